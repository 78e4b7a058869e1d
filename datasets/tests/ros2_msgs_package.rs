//! The ROS 2 message package `tools/ros/echofield_msgs` defines exactly the
//! `SonarBeam` the reader decodes, and is a package colcon can build.

use echofield_datasets::mcap::ros2::SONAR_BEAM_MSG;
use std::path::PathBuf;

fn package() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tools/ros/echofield_msgs")
}

#[test]
fn the_msg_file_is_the_definition_the_reader_decodes() {
    let file = std::fs::read_to_string(package().join("msg/SonarBeam.msg")).unwrap();
    assert_eq!(file, SONAR_BEAM_MSG);
}

#[test]
fn the_package_declares_its_interfaces_for_rosidl() {
    let xml = std::fs::read_to_string(package().join("package.xml")).unwrap();
    for needed in [
        "<package format=\"3\">",
        "<name>echofield_msgs</name>",
        "<buildtool_depend>rosidl_default_generators</buildtool_depend>",
        "<depend>std_msgs</depend>",
        "<exec_depend>rosidl_default_runtime</exec_depend>",
        "<member_of_group>rosidl_interface_packages</member_of_group>",
        "<build_type>ament_cmake</build_type>",
    ] {
        assert!(xml.contains(needed), "package.xml lacks {needed}");
    }
    let cmake = std::fs::read_to_string(package().join("CMakeLists.txt")).unwrap();
    assert!(cmake.contains("project(echofield_msgs)"));
    assert!(cmake.contains("rosidl_generate_interfaces(${PROJECT_NAME}"));
    assert!(cmake.contains("\"msg/SonarBeam.msg\""));
    assert!(cmake.contains("DEPENDENCIES std_msgs"));
    // Every message type the .msg uses comes from a declared dependency.
    for line in SONAR_BEAM_MSG.lines().filter(|l| !l.starts_with('#')) {
        if let Some((package, _)) = line
            .split_whitespace()
            .next()
            .and_then(|t| t.split_once('/'))
        {
            assert!(
                xml.contains(&format!("<depend>{package}</depend>")),
                "{line}"
            );
        }
    }
}
