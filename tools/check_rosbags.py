"""Writes a ROS 2 recording (rosbag2, MCAP storage) with the independent
`rosbags` package, for tools/check_rosbags.sh.

Usage: check_rosbags.py MSG_FILE OUTPUT VARIANT

VARIANT (see VARIANTS) chooses the container (rosbag2 MCAP or sqlite3
storage, or a ROS 1 bag with lz4 chunks) and the message types: the sonar as
echofield_msgs/SonarBeam, ping360_sonar_msgs/SonarEcho,
marine_acoustic_msgs/RawSonarImage or sensor_msgs/LaserScan (one sweep per
message, ranges only), the DVL as TwistWithCovarianceStamped,
marine_acoustic_msgs/Dvl or the Water Linked DVL message, the heading as
Imu or QuaternionStamped. The standard variants put the sonar head 0.4 m
forward with its angle zero to port and publish that on /tf_static.

A vehicle crosses a 20 m x 14 m rectangular tank and back at 0.3 m/s; the
recording holds its sonar beams as `echofield_msgs/msg/SonarBeam` (the type
registered from MSG_FILE, the package's own .msg file), DVL velocities as
`geometry_msgs/msg/TwistWithCovarianceStamped`, attitude as
`sensor_msgs/msg/Imu` and ground truth as `nav_msgs/msg/Odometry`. The beams
are drawn from the tank's walls: a band of echo 2 bins either side of the
range where the beam meets a wall, and a little seeded noise.
"""

import math
import random
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TANK = (0.0, 20.0, 0.0, 14.0)  # x min, x max, y min, y max (m)
BEAM_PERIOD_S = 0.07
STEPS = 200  # beams per rotation
BINS, BIN_M = 500, 0.05
START_S = 1_700_000_000.0


def pose_at(t):
    """Vehicle pose (x, y, yaw) at t seconds: east along y = 5, a half turn, west along y = 9."""
    speed, leg = 0.3, 14.0
    d = speed * t
    if d < leg:
        return 3.0 + d, 5.0, 0.0
    turn = math.pi * 2.0  # the half turn's length (radius 2 m)
    if d < leg + turn:
        a = (d - leg) / 2.0
        return 17.0 + 2.0 * math.sin(a), 7.0 - 2.0 * math.cos(a), a
    return 17.0 - (d - leg - turn), 9.0, math.pi


def wall_range(x, y, heading):
    c, s = math.cos(heading), math.sin(heading)
    best = math.inf
    for bound, along_x in ((TANK[0], True), (TANK[1], True), (TANK[2], False), (TANK[3], False)):
        k = c if along_x else s
        if abs(k) < 1e-9:
            continue
        r = (bound - (x if along_x else y)) / k
        if r > 0:
            best = min(best, r)
    return best


def stamp(types, t):
    sec = int(t)
    return types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)


# What each variant records: container, sonar type, DVL type, heading type.
VARIANTS = {
    "echofield-mcap": ("mcap", "echofield", "twist", "imu"),
    "ping360-sqlite3": ("sqlite3", "ping360", "marine", "quaternion"),
    "rawimage-mcap": ("mcap", "raw", "waterlinked", "imu"),
    "laserscan-mcap": ("mcap", "laserscan", "twist", "quaternion"),
    "ros1-ping360-lz4": ("ros1", "ping360", "waterlinked", "imu"),
}
# The sonar head on the vehicle (published on /tf_static for the standard
# variants): 0.4 m forward, its angle zero pointing to port.
SONAR_X, SONAR_YAW = 0.4, math.pi / 2
RANGE_M = 25  # Ping360 `range` (uint8 m): 500 bins of 0.05 m


def wall_bins(rng, x, y, heading):
    r = wall_range(x, y, heading)
    bins = bytearray(rng.randrange(0, 20) for _ in range(BINS))
    centre = int(r / BIN_M)
    for b in range(centre - 2, centre + 3):
        if 0 <= b < len(bins):
            bins[b] = 200 + rng.randrange(0, 40)
    return bins, r


def main(msg_file, output, variant="echofield-mcap"):
    container, sonar, dvl, heading = VARIANTS[variant]
    ros1 = container == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import ros_msg_defs
    ros_msg_defs.register(store, msg_file)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    T = store.types
    Vector3, Quaternion = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    rng = random.Random(1)
    duration = 2 * 14.0 / 0.3 + 2 * math.pi / 0.3
    standard = sonar != "echofield"
    # Beams from the head: echofield's own message puts the head at the
    # vehicle origin (no mounting in a ROS file), the others at SONAR_X, SONAR_YAW.
    head_x, head_yaw = (SONAR_X, SONAR_YAW) if standard else (0.0, 0.0)

    def header(t, frame):
        sec = int(t)
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)
        if ros1:
            return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def head_pose(t):
        x, y, yaw = pose_at(t)
        return x + head_x * math.cos(yaw), y + head_x * math.sin(yaw), yaw + head_yaw

    sonar_type = {
        "echofield": "echofield_msgs/msg/SonarBeam",
        "ping360": "ping360_sonar_msgs/msg/SonarEcho",
        "raw": "marine_acoustic_msgs/msg/RawSonarImage",
        "laserscan": "sensor_msgs/msg/LaserScan",
    }[sonar]
    dvl_type = {
        "twist": "geometry_msgs/msg/TwistWithCovarianceStamped",
        "marine": "marine_acoustic_msgs/msg/Dvl",
        "waterlinked": "waterlinked_a50_ros_driver/msg/DVL" if ros1 else "dvl_msgs/msg/DVL",
    }[dvl]
    heading_type = {"imu": "sensor_msgs/msg/Imu", "quaternion": "geometry_msgs/msg/QuaternionStamped"}[heading]
    topics = {
        "/sonar/beam": sonar_type,
        "/dvl/data": dvl_type,
        "/heading": heading_type,
        "/ground_truth/odom": "nav_msgs/msg/Odometry",
    }
    if standard:
        topics["/tf_static"] = "tf2_msgs/msg/TFMessage"

    events = []
    if standard:
        events.append((0.0, "tf", 0))
    if sonar == "laserscan":
        # One sweep (a whole rotation) per message, stamped at its first ray.
        k = 0
        while (k + 1) * STEPS * BEAM_PERIOD_S < duration:
            events.append((k * STEPS * BEAM_PERIOD_S, "beam", k))
            k += 1
    else:
        k = 0
        while k * BEAM_PERIOD_S < duration:
            events.append((k * BEAM_PERIOD_S, "beam", k))
            k += 1
    events += [(i * 0.2, "dvl", i) for i in range(int(duration / 0.2))]
    events += [(i * 0.05, "imu", i) for i in range(int(duration / 0.05))]
    events += [(i * 0.1, "gt", i) for i in range(int(duration / 0.1))]
    events.sort(key=lambda e: (e[0], e[1]))

    def beam_message(t, i):
        angle = 2 * math.pi * (i % STEPS) / STEPS
        hx, hy, hyaw = head_pose(t)
        bins, r = wall_bins(rng, hx, hy, hyaw + angle)
        h = header(START_S + t, "sonar")
        data = np.frombuffer(bytes(bins), dtype=np.uint8)
        if sonar == "echofield":
            return T[sonar_type](header=h, angle_rad=angle, bin_size_m=BIN_M, first_bin_range_m=0.0, intensities=data)
        if sonar == "ping360":
            return T[sonar_type](header=h, angle=angle, gain=1, number_of_samples=len(bins), transmit_frequency=750,
                                 speed_of_sound=1500, range=RANGE_M, intensities=data)
        return T[sonar_type](
            header=h,
            ping_info=T["marine_acoustic_msgs/msg/PingInfo"](frequency=700e3, sound_speed=1500.0,
                tx_beamwidths=np.array([0.03], dtype=np.float32), rx_beamwidths=np.array([0.5], dtype=np.float32)),
            sample_rate=1500.0 / (2 * BIN_M), samples_per_beam=len(bins), sample0=0,
            tx_delays=np.array([0.0], dtype=np.float32), tx_angles=np.array([0.0], dtype=np.float32),
            rx_angles=np.array([angle], dtype=np.float32),
            image=T["marine_acoustic_msgs/msg/SonarImageData"](is_bigendian=False, dtype=0, beam_count=1, data=data))

    def sweep_message(t, k):
        ranges = []
        for j in range(STEPS):
            hx, hy, hyaw = head_pose(t + j * BEAM_PERIOD_S)
            ranges.append(wall_range(hx, hy, hyaw + 2 * math.pi * j / STEPS) + rng.gauss(0, 0.02))
        return T[sonar_type](header=header(START_S + t, "sonar"), angle_min=0.0, angle_max=2 * math.pi * (STEPS - 1) / STEPS,
                             angle_increment=2 * math.pi / STEPS, time_increment=BEAM_PERIOD_S, scan_time=STEPS * BEAM_PERIOD_S,
                             range_min=0.3, range_max=float(RANGE_M), ranges=np.array(ranges, dtype=np.float32),
                             intensities=np.array([], dtype=np.float32))

    def dvl_message(t):
        x, y, yaw = pose_at(t)
        x2, y2, _ = pose_at(t + 0.01)
        vx_w, vy_w = (x2 - x) / 0.01, (y2 - y) / 0.01
        c, s = math.cos(yaw), math.sin(yaw)
        body = (c * vx_w + s * vy_w + rng.gauss(0, 0.005), -s * vx_w + c * vy_w + rng.gauss(0, 0.005), 0.0)
        h = header(START_S + t, "dvl")
        if dvl == "twist":
            cov = [0.0] * 36
            for d in range(3):
                cov[7 * d] = 0.005**2
            return T[dvl_type](header=h, twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=Vector3(x=body[0], y=body[1], z=body[2]), angular=Vector3(x=0.0, y=0.0, z=0.0)),
                covariance=np.array(cov)))
        # Both DVL messages state a z-down frame (y starboard).
        down = Vector3(x=body[0], y=-body[1], z=-body[2])
        cov9 = np.zeros(9)
        cov9[[0, 4, 8]] = 0.005**2
        if dvl == "marine":
            return T[dvl_type](header=h, velocity_mode=1, dvl_type=0, velocity=down, velocity_covar=cov9, altitude=3.0,
                               course_gnd=0.0, speed_gnd=0.0, num_good_beams=4, sound_speed=1500.0, beam_ranges_valid=False,
                               beam_velocities_valid=False, beam_unit_vec=[Vector3(x=0.0, y=0.0, z=1.0)] * 4, range=np.zeros(4),
                               range_covar=np.zeros(4, dtype=np.float32), beam_quality=np.zeros(4, dtype=np.float32),
                               beam_velocity=np.zeros(4, dtype=np.float32), beam_velocity_covar=np.zeros(4, dtype=np.float32))
        fields = dict(header=h, time=0.0, velocity=down, fom=0.005, altitude=3.0, beams=[], velocity_valid=True, status=0, form="json_v3")
        if not ros1:
            fields.update(covariance=cov9, time_of_validity=0, time_of_transmission=0)
        return T[dvl_type](**fields)

    def heading_message(t):
        _, _, yaw = pose_at(t)
        _, _, yaw2 = pose_at(t + 0.01)
        q = Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
        h = header(START_S + t, "imu")
        if heading == "quaternion":
            return T[heading_type](header=h, quaternion=q)
        cov = np.zeros(9)
        cov[8] = 1e-4
        return T[heading_type](header=h, orientation=q, orientation_covariance=cov,
                               angular_velocity=Vector3(x=0.0, y=0.0, z=(yaw2 - yaw) / 0.01), angular_velocity_covariance=cov,
                               linear_acceleration=Vector3(x=0.0, y=0.0, z=9.81), linear_acceleration_covariance=cov)

    def gt_message(t):
        x, y, yaw = pose_at(t)
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                           orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
        zero = T["geometry_msgs/msg/Twist"](linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))
        return T["nav_msgs/msg/Odometry"](header=header(START_S + t, "world"), child_frame_id="base_link",
                                          pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                                          twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=zero, covariance=np.zeros(36)))

    def tf_message():
        ts = T["geometry_msgs/msg/TransformStamped"](
            header=header(START_S, "base_link"), child_frame_id="sonar",
            transform=T["geometry_msgs/msg/Transform"](translation=Vector3(x=SONAR_X, y=0.0, z=0.2),
                                                       rotation=Quaternion(x=0.0, y=0.0, z=math.sin(SONAR_YAW / 2), w=math.cos(SONAR_YAW / 2))))
        return T["tf2_msgs/msg/TFMessage"](transforms=[ts])

    def serialize(msg, ty):
        return store.serialize_ros1(msg, ty) if ros1 else store.serialize_cdr(msg, ty)

    if ros1:
        writer = Writer1(Path(output))
        writer.set_compression(Writer1.CompressionFormat.LZ4)
    else:
        plugin = StoragePlugin.SQLITE3 if container == "sqlite3" else StoragePlugin.MCAP
        writer = Writer(Path(output), version=8, storage_plugin=plugin)
    with writer:
        conn = {t: writer.add_connection(t, m, typestore=store) for t, m in topics.items()}
        for t, kind, i in events:
            if kind == "tf":
                topic, msg = "/tf_static", tf_message()
            elif kind == "beam":
                topic, msg = "/sonar/beam", sweep_message(t, i) if sonar == "laserscan" else beam_message(t, i)
            elif kind == "dvl":
                topic, msg = "/dvl/data", dvl_message(t)
            elif kind == "imu":
                topic, msg = "/heading", heading_message(t)
            else:
                topic, msg = "/ground_truth/odom", gt_message(t)
            writer.write(conn[topic], int(round((START_S + t) * 1e9)), serialize(msg, topics[topic]))


if __name__ == "__main__":
    main(*sys.argv[1:4])
