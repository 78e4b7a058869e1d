//! Issue 35: St Pere logs with impossible values or an empty DVL log are
//! errors naming the file, the line and the column, not missions that
//! convert silently.

use echofield_datasets::stpere::read_stpere_dir;
use std::path::Path;

const DVL_HEADER: &str = "% time, [idSensor], year, ...\r\n\r\n";
const DVL_LINES: &str = "\
1093455407.147 2007 3 16 13 0 56 38.20 -47.00 1.80 1 6.10 -4.90 2.80 1 1.84 1.88 1.86 143.00 142.00 149.00 100 207.70 -0.50 1.60 14.27 1488.00 12.80 0.50 1.50 0.08 -0.25\r\n\
1093455407.822 2007 3 16 13 0 57 4.80 51.40 18.30 1 -1.90 8.90 -4.70 1 1.83 1.87 1.85 152.00 144.00 144.00 100 207.40 -0.50 1.60 14.27 1488.00 12.80 0.50 1.50 0.07 -0.20\r\n";
const MTI: &str = "% time, [idSensor], positionX\r\n\r\n\
1093455407.042 0.506328 -2.5422 -126.276 0.0115654 -0.00641596 0.00508943 -0.427074 -0.0795686 -9.77331 \r\n\
1093455407.149 0.537181 -2.56871 -126.325 -0.00123256 -0.00291132 0.000567025 -0.421376 -0.0790028 -9.77091 \r\n";
const DGPS: &str = "% trueCourse\r\n\r\n\
1093455407.9 4212.225 306.2832 1 -2.1 51.8 23.6 24 0.1 0.1\r\n\
1093455408.9 4212.2251 306.2833 1 -2.1 51.8 23.6 24 0.1 0.1\r\n";

fn write(dir: &Path, dvl: &str, mti: &str) {
    for (kind, text) in [("DVL", dvl), ("MTI", mti), ("DGPS", DGPS)] {
        std::fs::write(dir.join(format!("_040825_1735_{kind}.log")), text).unwrap();
    }
}

fn read_error(dvl: &str, mti: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), dvl, mti);
    read_stpere_dir(dir.path())
        .expect_err("must fail")
        .to_string()
}

#[test]
fn the_fixture_reads() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &format!("{DVL_HEADER}{DVL_LINES}"), MTI);
    let logs = read_stpere_dir(dir.path()).unwrap();
    assert_eq!(logs.mission.dvl.len(), 2);
}

#[test]
fn an_empty_dvl_log_is_an_error_naming_the_file() {
    let message = read_error(DVL_HEADER, MTI);
    assert!(
        message.contains("_040825_1735_DVL.log") && message.contains("DVL samples"),
        "{message}"
    );
}

#[test]
fn an_mti_yaw_of_1e308_degrees_names_file_line_and_column() {
    let mti = MTI.replacen("-126.276", "1e308", 1);
    let message = read_error(&format!("{DVL_HEADER}{DVL_LINES}"), &mti);
    assert!(
        message.contains("_040825_1735_MTI.log")
            && message.contains("line 3")
            && message.contains("column 4 (yaw)"),
        "{message}"
    );
    // Two turns either way are still headings.
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        &format!("{DVL_HEADER}{DVL_LINES}"),
        &MTI.replacen("-126.276", "-700.5", 1),
    );
    read_stpere_dir(dir.path()).unwrap();
}

#[test]
fn a_dvl_velocity_beyond_the_invalid_marker_names_file_line_and_column() {
    let dvl = format!("{DVL_HEADER}{DVL_LINES}").replacen(" -1.90 ", " 1e22 ", 1);
    let message = read_error(&dvl, MTI);
    assert!(
        message.contains("_040825_1735_DVL.log")
            && message.contains("line 4")
            && message.contains("column 12 (bottomVelX)"),
        "{message}"
    );
}
