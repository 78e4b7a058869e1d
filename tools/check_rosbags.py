"""Writes a ROS 2 recording (rosbag2, MCAP storage) with the independent
`rosbags` package, for tools/check_rosbags.sh.

Usage: check_rosbags.py MSG_FILE OUTPUT_FOLDER

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
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TANK = (0.0, 20.0, 0.0, 14.0)  # x min, x max, y min, y max (m)
BEAM_PERIOD_S = 0.07
STEPS = 200  # beams per rotation
BINS, BIN_M = 300, 0.05
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


def main(msg_file, output):
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(Path(msg_file).read_text(), "echofield_msgs/msg/SonarBeam"))
    T = store.types
    Header, Vector3, Quaternion = T["std_msgs/msg/Header"], T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    rng = random.Random(1)
    duration = 2 * 14.0 / 0.3 + 2 * math.pi / 0.3
    with Writer(Path(output), version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        topics = {
            "/sonar/beam": "echofield_msgs/msg/SonarBeam",
            "/dvl/twist": "geometry_msgs/msg/TwistWithCovarianceStamped",
            "/imu/data": "sensor_msgs/msg/Imu",
            "/ground_truth/odom": "nav_msgs/msg/Odometry",
        }
        conn = {t: writer.add_connection(t, m, typestore=store) for t, m in topics.items()}
        events = []
        k = 0
        while k * BEAM_PERIOD_S < duration:
            events.append((k * BEAM_PERIOD_S, "beam", k))
            k += 1
        events += [(i * 0.2, "dvl", i) for i in range(int(duration / 0.2))]
        events += [(i * 0.05, "imu", i) for i in range(int(duration / 0.05))]
        events += [(i * 0.1, "gt", i) for i in range(int(duration / 0.1))]
        events.sort(key=lambda e: (e[0], e[1]))
        for t, kind, i in events:
            x, y, yaw = pose_at(t)
            header = Header(stamp=stamp(T, START_S + t), frame_id={"beam": "sonar", "dvl": "dvl", "imu": "imu", "gt": "world"}[kind])
            if kind == "beam":
                angle = 2 * math.pi * (i % STEPS) / STEPS
                r = wall_range(x, y, yaw + angle)
                bins = bytearray(rng.randrange(0, 20) for _ in range(BINS))
                centre = int(r / BIN_M)
                for b in range(centre - 2, centre + 3):
                    if 0 <= b < BINS:
                        bins[b] = 200 + rng.randrange(0, 40)
                msg = T["echofield_msgs/msg/SonarBeam"](header=header, angle_rad=angle, bin_size_m=BIN_M, first_bin_range_m=0.0, intensities=np.frombuffer(bytes(bins), dtype=np.uint8))
            elif kind == "dvl":
                x2, y2, _ = pose_at(t + 0.01)
                vx_w, vy_w = (x2 - x) / 0.01, (y2 - y) / 0.01
                c, s = math.cos(yaw), math.sin(yaw)
                body = (c * vx_w + s * vy_w + rng.gauss(0, 0.005), -s * vx_w + c * vy_w + rng.gauss(0, 0.005), 0.0)
                cov = [0.0] * 36
                for d in range(3):
                    cov[7 * d] = 0.005**2
                twist = T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=Vector3(x=body[0], y=body[1], z=body[2]), angular=Vector3(x=0.0, y=0.0, z=0.0)),
                    covariance=np.array(cov),
                )
                msg = T["geometry_msgs/msg/TwistWithCovarianceStamped"](header=header, twist=twist)
            elif kind == "imu":
                _, _, yaw2 = pose_at(t + 0.01)
                q = Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
                cov = np.zeros(9)
                cov[8] = 1e-4
                msg = T["sensor_msgs/msg/Imu"](
                    header=header, orientation=q, orientation_covariance=cov,
                    angular_velocity=Vector3(x=0.0, y=0.0, z=(yaw2 - yaw) / 0.01), angular_velocity_covariance=cov,
                    linear_acceleration=Vector3(x=0.0, y=0.0, z=9.81), linear_acceleration_covariance=cov,
                )
            else:
                pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
                msg = T["nav_msgs/msg/Odometry"](
                    header=header, child_frame_id="vehicle",
                    pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                    twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=T["geometry_msgs/msg/Twist"](linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)), covariance=np.zeros(36)),
                )
            topic = {"beam": "/sonar/beam", "dvl": "/dvl/twist", "imu": "/imu/data", "gt": "/ground_truth/odom"}[kind]
            writer.write(conn[topic], int(round((START_S + t) * 1e9)), store.serialize_cdr(msg, topics[topic]))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
