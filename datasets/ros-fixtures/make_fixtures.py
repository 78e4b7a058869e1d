"""Writes the ROS recordings in this folder with the independent `rosbags`
package (https://pypi.org/project/rosbags/), for the readers' tests
(datasets/tests/ros_messages.rs).

Usage (from the repository root, with `rosbags` and `numpy` installed):
    python datasets/ros-fixtures/make_fixtures.py datasets/ros-fixtures

Every value the tests check is written here by hand; see the comments.
"""

import math
import shutil
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import ros_msg_defs  # noqa: E402

T0 = 1_700_000_000  # s


def quat_z(yaw):
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


class Msgs:
    """Builds the fixture's messages for one type store (ROS 1 or ROS 2)."""

    def __init__(self, store, ros1):
        self.T = store.types
        self.ros1 = ros1

    def header(self, t, frame):
        sec = int(t)
        stamp = self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)))
        if self.ros1:
            return self.T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def v3(self, x, y, z):
        return self.T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    def quat(self, yaw):
        x, y, z, w = quat_z(yaw)
        return self.T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def ping360(self, t, k, angle=None):
        # angle 0.1·k rad, range 10 m over 5 samples (2 m bins), bins [k, 1, 2, 3, 4].
        return self.T["ping360_sonar_msgs/msg/SonarEcho"](
            header=self.header(t, "sonar_link"),
            angle=0.1 * k if angle is None else angle,
            gain=1, number_of_samples=5, transmit_frequency=750, speed_of_sound=1500, range=10,
            intensities=np.array([k, 1, 2, 3, 4], dtype=np.uint8),
        )

    def raw_image(self, t, k):
        # 1 beam at 0.5 + k rad; 1500 m/s at 7500 Hz: 0.1 m bins; sample0 2: first bin 0.2 m;
        # tx delay 0.01 s; 4 uint8 samples [10, 20, 30, 40 + k].
        T = self.T
        return T["marine_acoustic_msgs/msg/RawSonarImage"](
            header=self.header(t, "sonar_link"),
            ping_info=T["marine_acoustic_msgs/msg/PingInfo"](
                frequency=700e3, sound_speed=1500.0,
                tx_beamwidths=np.array([0.03], dtype=np.float32), rx_beamwidths=np.array([0.5], dtype=np.float32)),
            sample_rate=7500.0, samples_per_beam=4, sample0=2,
            tx_delays=np.array([0.01], dtype=np.float32), tx_angles=np.array([0.0], dtype=np.float32),
            rx_angles=np.array([0.5 + k], dtype=np.float32),
            image=T["marine_acoustic_msgs/msg/SonarImageData"](
                is_bigendian=False, dtype=0, beam_count=1, data=np.array([10, 20, 30, 40 + k], dtype=np.uint8)),
        )

    def scan(self, t):
        # A sweep of 3 rays from -0.5 rad by 0.25 rad, 0.01 s apart; ranges 4 m, none (inf), 8 m;
        # range_max 10 m (0.02 m bins: bins 200 and 400).
        return self.T["sensor_msgs/msg/LaserScan"](
            header=self.header(t, "sonar_link"),
            angle_min=-0.5, angle_max=0.0, angle_increment=0.25, time_increment=0.01, scan_time=0.03,
            range_min=0.5, range_max=10.0,
            ranges=np.array([4.0, np.inf, 8.0], dtype=np.float32),
            intensities=np.array([], dtype=np.float32),
        )

    def one_beam_scan(self, t, k):
        # The Girona caves layout: one beam per message, angle in angle_min (0.2·k rad),
        # angle_increment 0, intensities = 4 bins over [0, 20 m] (5 m bins): [0, 50, 191, 7].
        return self.T["sensor_msgs/msg/LaserScan"](
            header=self.header(t, "micron"),
            angle_min=0.2 * k, angle_max=0.2 * k, angle_increment=0.0, time_increment=0.0, scan_time=0.0,
            range_min=0.0, range_max=20.0,
            ranges=np.array([1.0, 2.0, 3.0, 4.0], dtype=np.float32),
            intensities=np.array([0.0, 50.0, 191.0, 7.0], dtype=np.float32),
        )

    def range_image_beam(self, t, k):
        # The Girona caves data set's own sonar message: the beam of one_beam_scan(t, k)
        # (angle 0.2·k rad, 4 bins over [0, 20 m]) with beam_data [0, 50, 191, 7 + k].
        return self.T["cirs_girona_cala_viuda/msg/RangeImageBeam"](
            header=self.header(t, "micron"), angle_grad=math.degrees(0.2 * k), angle_rad=0.2 * k,
            nbins=4, max_range=20, beam_data=np.array([0, 50, 191, 7 + k], dtype=np.int32),
        )

    def linkquest(self, t, good):
        # velocityInst (0.3, 0.05, 0.01) m/s, z down; velocityInstFlag 1 (good) or 0.
        return self.T["cirs_girona_cala_viuda/msg/LinkquestDvl"](
            header=self.header(t, "dvl"), errcode="", datagood=np.ones(4, dtype=np.int32),
            altitudebeam=np.full(4, 2.5), bottomvelocitybeam=np.zeros(4), watervelocitybeam=np.zeros(4),
            watervelocitycredit=np.zeros(4), velocityinst=np.array([0.3, 0.05, 0.01]),
            velocityinstflag=1 if good else 0, velocityearth=np.zeros(3), velocityearthflag=0,
            watervelocityinst=np.zeros(3), watervelocityinstflag=0, watervelocityearth=np.zeros(3),
            watervelocityearthflag=0, roll=0.0, pitch=0.0, heading=0.0, altitude=2.5, temperature=14.0,
            pressure=0.0, salinity=35.0, soundspeed=1500.0, rawdata="",
        )

    def caves_imu(self, t):
        # The data set's custom IMU message (not read: its *_ros twin is a sensor_msgs/Imu).
        fields = {f: 0.0 for f in "roll pitch yaw qx qy qz temp mx my mz ax ay az gx gy gz bx by bz".split()}
        return self.T["cirs_girona_cala_viuda/msg/Imu"](header=self.header(t, "imu"), qw=1.0, **fields)

    def ping360_ros1(self, t, k):
        # The ROS 1 driver: angle 100·k gradians (k·π/2 rad), range 10 m over 5 samples, bins [k, 1, 2, 3, 4].
        return self.T["ping360_sonar/msg/SonarEcho"](
            header=self.header(t, "sonar_frame"), angle=100.0 * k, gain=0, number_of_samples=5,
            transmit_frequency=740, speed_of_sound=1500, range=10,
            intensities=np.array([k, 1, 2, 3, 4], dtype=np.uint8),
        )

    def marine_dvl(self, t):
        # Bottom track, velocity (0.5, 0.1, 0.05) m/s with z down; covariance diag 0.01.
        T = self.T
        cov = np.zeros(9)
        cov[[0, 4, 8]] = 0.01
        return T["marine_acoustic_msgs/msg/Dvl"](
            header=self.header(t, "dvl_link"), velocity_mode=1, dvl_type=0,
            velocity=self.v3(0.5, 0.1, 0.05), velocity_covar=cov, altitude=3.0, course_gnd=0.2, speed_gnd=0.51,
            num_good_beams=4, sound_speed=1500.0, beam_ranges_valid=True, beam_velocities_valid=True,
            beam_unit_vec=[self.v3(0.0, 0.0, 1.0)] * 4, range=np.full(4, 3.5),
            range_covar=np.zeros(4, dtype=np.float32), beam_quality=np.zeros(4, dtype=np.float32),
            beam_velocity=np.zeros(4, dtype=np.float32), beam_velocity_covar=np.zeros(4, dtype=np.float32),
        )

    def water_linked(self, t, valid):
        # Velocity (0.3, -0.2, 0.1) m/s (x forward, y starboard, z down); ROS 2: covariance diag 0.0004.
        T = self.T
        pkg = "waterlinked_a50_ros_driver" if self.ros1 else "dvl_msgs"
        beams = [T[f"{pkg}/msg/DVLBeam"](id=i, velocity=0.1, distance=2.0, rssi=-40.0, nsd=-90.0, valid=True) for i in range(4)]
        fields = dict(header=self.header(t, "dvl_link"), time=12.5, velocity=self.v3(0.3, -0.2, 0.1), fom=0.002,
                      altitude=2.0, beams=beams, velocity_valid=valid, status=0, form="json_v3")
        if not self.ros1:
            cov = np.zeros(9)
            cov[[0, 4, 8]] = 0.0004
            fields.update(covariance=cov, time_of_validity=0, time_of_transmission=0)
        return T[f"{pkg}/msg/DVL"](**fields)

    def twist(self, t):
        # (0.25, 0.0, 0.0) m/s, unknown covariance (all zero).
        T = self.T
        return T["geometry_msgs/msg/TwistWithCovarianceStamped"](
            header=self.header(t, "base_link"),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=self.v3(0.25, 0.0, 0.0), angular=self.v3(0.0, 0.0, 0.0)),
                covariance=np.zeros(36)),
        )

    def odometry(self, t):
        # Pose (1, 2) m, yaw 0.3 rad; twist (0.4, 0, 0) m/s in base_link.
        T = self.T
        return T["nav_msgs/msg/Odometry"](
            header=self.header(t, "odom"), child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=-5.0), orientation=self.quat(0.3)),
                covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=self.v3(0.4, 0.0, 0.0), angular=self.v3(0.0, 0.0, 0.0)),
                covariance=np.zeros(36)),
        )

    def imu(self, t):
        # Yaw 0.2 rad, yaw rate 0.05 rad/s.
        return self.T["sensor_msgs/msg/Imu"](
            header=self.header(t, "imu_link"), orientation=self.quat(0.2), orientation_covariance=np.zeros(9),
            angular_velocity=self.v3(0.0, 0.0, 0.05), angular_velocity_covariance=np.zeros(9),
            linear_acceleration=self.v3(0.0, 0.0, 9.8), linear_acceleration_covariance=np.zeros(9),
        )

    def heading(self, t):
        # Yaw -0.4 rad.
        return self.T["geometry_msgs/msg/QuaternionStamped"](header=self.header(t, "compass"), quaternion=self.quat(-0.4))

    def tf(self, t, parent, child, xyz, yaw, roll=0.0):
        T = self.T
        # Rz(yaw)·Rx(roll) as a quaternion.
        cy, sy, cr, sr = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(roll / 2), math.sin(roll / 2)
        q = T["geometry_msgs/msg/Quaternion"](x=cy * sr, y=sy * sr, z=sy * cr, w=cy * cr)
        ts = T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t, parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](translation=self.v3(*xyz), rotation=q))
        return T["tf2_msgs/msg/TFMessage"](transforms=[ts])


def messages(m, ros1):
    """(topic, type, time, message) of the fixture, in time order."""
    out = [
        # base_link -> mast -> sonar_link: sonar at (0.5 + 0.2·cos 0.1, -0.1 + 0.2·sin 0.1) m, yaw 0.1 rad.
        ("/tf_static", "tf2_msgs/msg/TFMessage", 0.0, m.tf(0.0, "base_link", "mast", (0.5, -0.1, 0.3), 0.1)),
        ("/tf_static", "tf2_msgs/msg/TFMessage", 0.0, m.tf(0.0, "mast", "sonar_link", (0.2, 0.0, 0.0), 0.0)),
        ("/tf", "tf2_msgs/msg/TFMessage", 0.05, m.tf(0.05, "odom", "base_link", (1.0, 2.0, 0.0), 0.3)),
    ]
    for k in range(3):
        t = 0.1 * (k + 1)
        out.append(("/ping360/echo", "ping360_sonar_msgs/msg/SonarEcho", t, m.ping360(T0 + t, k)))
    for k in range(2):
        t = 0.15 + 0.1 * k
        out.append(("/sonar/raw", "marine_acoustic_msgs/msg/RawSonarImage", t, m.raw_image(T0 + t, k)))
    out.append(("/sonar/scan", "sensor_msgs/msg/LaserScan", 0.2, m.scan(T0 + 0.2)))
    for k in range(2):
        t = 0.1 + 0.2 * k
        out.append(("/dvl/marine", "marine_acoustic_msgs/msg/Dvl", t, m.marine_dvl(T0 + t)))
        dvl_type = "waterlinked_a50_ros_driver/msg/DVL" if ros1 else "dvl_msgs/msg/DVL"
        out.append(("/dvl/data", dvl_type, t, m.water_linked(T0 + t, valid=k == 0)))
        out.append(("/dvl/twist", "geometry_msgs/msg/TwistWithCovarianceStamped", t, m.twist(T0 + t)))
        out.append(("/odometry", "nav_msgs/msg/Odometry", t, m.odometry(T0 + t)))
        out.append(("/odometry/filtered", "nav_msgs/msg/Odometry", t, m.odometry(T0 + t)))
        out.append(("/imu/data", "sensor_msgs/msg/Imu", t, m.imu(T0 + t)))
        out.append(("/heading", "geometry_msgs/msg/QuaternionStamped", t, m.heading(T0 + t)))
    if ros1:
        for k in range(2):
            t = 0.12 + 0.1 * k
            out.append(("/sonar_micron_ros", "sensor_msgs/msg/LaserScan", t, m.one_beam_scan(T0 + t, k)))
    out.sort(key=lambda e: e[2])
    return out


def ros1_store():
    store = get_typestore(Stores.ROS1_NOETIC)
    ros_msg_defs.register(store)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        # tf2_msgs/TFMessage (ROS 1 noetic), missing from rosbags' ROS 1 store.
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    return store


def write_bag(path, store, entries, compression=Writer1.CompressionFormat.LZ4):
    """A ROS 1 bag of (topic, type, time, message) entries, in time order."""
    path.unlink(missing_ok=True)
    writer = Writer1(path)
    writer.set_compression(compression)
    with writer as w:
        conns = {}
        for topic, ty, t, msg in sorted(entries, key=lambda e: e[2]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, ty, typestore=store)
            w.write(conns[topic], int((T0 + t) * 1e9), store.serialize_ros1(msg, ty))


def write_caves(path):
    """The topics of the Girona underwater caves data set (Mallios et al., IJRR 2017),
    with its own message types (cirs_girona_cala_viuda) and their standard twins."""
    store = ros1_store()
    m = Msgs(store, ros1=True)
    pkg = "cirs_girona_cala_viuda/msg/"
    entries = []
    for k in range(2):
        t = 0.12 + 0.1 * k
        entries.append(("/sonar_micron", pkg + "RangeImageBeam", t, m.range_image_beam(T0 + t, k)))
        scan = m.one_beam_scan(T0 + t, k)
        scan.intensities = np.array([0.0, 50.0, 191.0, 7.0 + k], dtype=np.float32)
        entries.append(("/sonar_micron_ros", "sensor_msgs/msg/LaserScan", t, scan))
        entries.append(("/dvl_linkquest", pkg + "LinkquestDvl", t, m.linkquest(T0 + t, good=k == 0)))
        entries.append(("/imu_adis", pkg + "Imu", t, m.caves_imu(T0 + t)))
        entries.append(("/imu_adis_ros", "sensor_msgs/msg/Imu", t, m.imu(T0 + t)))
        entries.append(("/depth_sensor", pkg + "Depth", t, store.types[pkg + "Depth"](header=m.header(T0 + t, "depth"), depth=13.9)))
        entries.append(("/odometry", "nav_msgs/msg/Odometry", t, m.odometry(T0 + t)))
    # The data set publishes its mountings on /tf (no /tf_static), beside the moving vehicle:
    # world -> sparus moves; sparus -> micron (0.55, 0, -0.1) m, yaw 3.0 rad and
    # sparus -> dvl (-0.4, 0.05, 0.2) m, yaw pi/4 are repeated unchanged.
    for k in range(3):
        t = 0.05 + 0.1 * k
        entries.append(("/tf", "tf2_msgs/msg/TFMessage", t, m.tf(T0 + t, "world", "sparus", (1.0 * k, 0.0, 13.9), 0.1 * k)))
        entries.append(("/tf", "tf2_msgs/msg/TFMessage", t, m.tf(T0 + t, "sparus", "micron", (0.55, 0.0, -0.1), 3.0)))
        entries.append(("/tf", "tf2_msgs/msg/TFMessage", t, m.tf(T0 + t, "sparus", "dvl", (-0.4, 0.05, 0.2), math.pi / 4)))
    write_bag(path, store, entries)


def write_ping360_ros1(path):
    """Three echoes of the Ping360's ROS 1 driver (ping360_sonar/SonarEcho)."""
    store = ros1_store()
    m = Msgs(store, ros1=True)
    entries = [("/ping360_node/sonar/data", "ping360_sonar/msg/SonarEcho", 0.1 * (k + 1), m.ping360_ros1(T0 + 0.1 * (k + 1), k))
               for k in range(3)]
    write_bag(path, store, entries)


# The vehicle of dvl_lever_arm/: from the origin, heading 0, it turns at OMEGA rad/s with its
# origin moving forward at SPEED m/s, for DURATION s. Its DVL sits at DVL_XY m, yawed DVL_YAW rad
# (base_link -> dvl_link on /tf_static), and measures the velocity of that point, in its own axes.
OMEGA, SPEED, DURATION = 0.2, 0.5, 30.0
DVL_XY, DVL_YAW = (1.0, -0.5), 0.3


def circle_pose(t):
    yaw = OMEGA * t
    return SPEED / OMEGA * math.sin(yaw), SPEED / OMEGA * (1.0 - math.cos(yaw)), yaw


def write_lever_arm(folder):
    """A rosbag2 (MCAP): a turning vehicle whose DVL sits off its origin."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    ros_msg_defs.register(store)
    m = Msgs(store, ros1=False)
    T = store.types
    # v_dvl = v + w x r in the vehicle frame, then in the DVL's axes (rotated by -DVL_YAW).
    vx, vy = SPEED - OMEGA * DVL_XY[1], OMEGA * DVL_XY[0]
    c, s = math.cos(DVL_YAW), math.sin(DVL_YAW)
    dvl = (c * vx + s * vy, -s * vx + c * vy)
    entries = [("/tf_static", "tf2_msgs/msg/TFMessage", 0.0, m.tf(0.0, "base_link", "dvl_link", (*DVL_XY, 0.4), DVL_YAW))]
    for i in range(int(DURATION * 5) + 1):
        t = 0.2 * i
        _, _, yaw = circle_pose(t)
        entries.append(("/imu/data", "sensor_msgs/msg/Imu", t, T["sensor_msgs/msg/Imu"](
            header=m.header(T0 + t, "imu_link"), orientation=m.quat(yaw), orientation_covariance=np.zeros(9),
            angular_velocity=m.v3(0.0, 0.0, OMEGA), angular_velocity_covariance=np.zeros(9),
            linear_acceleration=m.v3(0.0, 0.0, 9.8), linear_acceleration_covariance=np.zeros(9))))
        twist = T["geometry_msgs/msg/TwistWithCovarianceStamped"](
            header=m.header(T0 + t + 0.1, "dvl_link"),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=m.v3(dvl[0], dvl[1], 0.0), angular=m.v3(0.0, 0.0, 0.0)),
                covariance=np.zeros(36)))
        entries.append(("/dvl/twist", "geometry_msgs/msg/TwistWithCovarianceStamped", t + 0.1, twist))
    for i in range(int(DURATION) + 1):
        x, y, yaw = circle_pose(float(i))
        pose = T["geometry_msgs/msg/PoseStamped"](
            header=m.header(T0 + i, "odom"),
            pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=m.quat(yaw)))
        entries.append(("/ground_truth", "geometry_msgs/msg/PoseStamped", float(i), pose))
    shutil.rmtree(folder, ignore_errors=True)
    with Writer2(folder, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for topic, ty, t, msg in sorted(entries, key=lambda e: e[2]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, ty, typestore=store)
            w.write(conns[topic], int((T0 + t) * 1e9), store.serialize_cdr(msg, ty))


def write_ros2(folder, storage):
    store = get_typestore(Stores.ROS2_HUMBLE)
    ros_msg_defs.register(store)
    m = Msgs(store, ros1=False)
    shutil.rmtree(folder, ignore_errors=True)
    with Writer2(folder, version=8, storage_plugin=storage) as w:
        conns = {}
        for topic, ty, t, msg in messages(m, ros1=False):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, ty, typestore=store)
            w.write(conns[topic], int((T0 + t) * 1e9), store.serialize_cdr(msg, ty))


def write_ros1(path, compression):
    store = ros1_store()
    write_bag(path, store, messages(Msgs(store, ros1=True), ros1=True), compression)


def write_bad(folder):
    """A rosbag2 (MCAP) whose second SonarEcho has a NaN angle."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    ros_msg_defs.register(store)
    m = Msgs(store, ros1=False)
    shutil.rmtree(folder, ignore_errors=True)
    ty = "ping360_sonar_msgs/msg/SonarEcho"
    with Writer2(folder, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/ping360/echo", ty, typestore=store)
        for k in range(3):
            msg = m.ping360(T0 + k, k, angle=float("nan") if k == 1 else None)
            w.write(c, int((T0 + k) * 1e9), store.serialize_cdr(msg, ty))


def main(out):
    out = Path(out)
    write_ros2(out / "ros2_mcap", StoragePlugin.MCAP)
    write_ros2(out / "ros2_sqlite3", StoragePlugin.SQLITE3)
    write_ros1(out / "ros1_lz4.bag", Writer1.CompressionFormat.LZ4)
    write_ros1(out / "ros1_bz2.bag", Writer1.CompressionFormat.BZ2)
    write_bad(out / "bad_ping360")
    write_caves(out / "girona_caves.bag")
    write_ping360_ros1(out / "ping360_ros1.bag")
    write_lever_arm(out / "dvl_lever_arm")


if __name__ == "__main__":
    main(sys.argv[1])
