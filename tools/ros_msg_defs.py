"""Definitions of the third-party ROS messages echofield reads, for the
`rosbags` type system (tools/check_rosbags.py, datasets/ros-fixtures/).

Retyped (fields only) from the packages' repositories:
- ping360_sonar_msgs/msg/SonarEcho: CentraleNantesRobotics/ping360_sonar,
  ping360_sonar_msgs/msg/SonarEcho.msg at fa53b8f.
- marine_acoustic_msgs/msg/{RawSonarImage,PingInfo,SonarImageData,Dvl}:
  apl-ocean-engineering/marine_msgs, marine_acoustic_msgs/msg/.
- dvl_msgs/msg/{DVL,DVLBeam}: the Water Linked A50 ROS 2 driver's messages
  (paagutie/dvl_msgs).
- waterlinked_a50_ros_driver/msg/{DVL,DVLBeam}: waterlinked/dvl-a50-ros-driver,
  msg/ at 15ad219 (ROS 1).
- ping360_sonar/msg/SonarEcho: CentraleNantesRobotics/ping360_sonar (the ROS 1
  driver), msg/SonarEcho.msg at 4ecc256.
- cirs_girona_cala_viuda/msg/{RangeImageBeam,LinkquestDvl,Imu,Depth}: the
  Girona underwater caves data set's package as ported to ROS 2,
  PickNikRobotics/cirs_girona_cala_viuda, msg/ at 18ec011 (field names
  lower-cased from the ROS 1 originals; the wire layout is the same).
"""

from rosbags.typesys import get_types_from_msg

# ping360_sonar_msgs/SonarEcho (ROS 2) and ping360_sonar/SonarEcho (ROS 1).
PING360_SONAR_ECHO = """
std_msgs/Header header
float32 angle
uint8 gain
uint16 number_of_samples
uint16 transmit_frequency
uint16 speed_of_sound
uint8 range
uint8[] intensities
"""

DEFS = {
    "ping360_sonar_msgs/msg/SonarEcho": PING360_SONAR_ECHO,
    "marine_acoustic_msgs/msg/PingInfo": """
float32 frequency
float32 sound_speed
float32[] tx_beamwidths
float32[] rx_beamwidths
""",
    "marine_acoustic_msgs/msg/SonarImageData": """
bool is_bigendian
uint32 DTYPE_UINT8=0
uint32 DTYPE_UINT16=2
uint32 dtype
uint32 beam_count
uint8[] data
""",
    "marine_acoustic_msgs/msg/RawSonarImage": """
std_msgs/Header header
marine_acoustic_msgs/PingInfo ping_info
float32 sample_rate
uint32 samples_per_beam
uint32 sample0
float32[] tx_delays
float32[] tx_angles
float32[] rx_angles
marine_acoustic_msgs/SonarImageData image
""",
    "marine_acoustic_msgs/msg/Dvl": """
uint8 DVL_MODE_BOTTOM=1
uint8 DVL_MODE_WATER=2
uint8 DVL_TYPE_PISTON=0
uint8 DVL_TYPE_PHASED_ARRAY=1
std_msgs/Header header
uint8 velocity_mode
uint8 dvl_type
geometry_msgs/Vector3 velocity
float64[9] velocity_covar
float64 altitude
float64 course_gnd
float64 speed_gnd
uint8 num_good_beams
float32 sound_speed
bool beam_ranges_valid
bool beam_velocities_valid
geometry_msgs/Vector3[4] beam_unit_vec
float64[4] range
float32[4] range_covar
float32[4] beam_quality
float32[4] beam_velocity
float32[4] beam_velocity_covar
""",
    "dvl_msgs/msg/DVLBeam": """
int64 id
float64 velocity
float64 distance
float64 rssi
float64 nsd
bool valid
""",
    "dvl_msgs/msg/DVL": """
std_msgs/Header header
float64 time
geometry_msgs/Vector3 velocity
float64 fom
float64[] covariance
float64 altitude
dvl_msgs/DVLBeam[] beams
bool velocity_valid
int64 status
int64 time_of_validity
int64 time_of_transmission
string form
""",
    "waterlinked_a50_ros_driver/msg/DVLBeam": """
int64 id
float64 velocity
float64 distance
float64 rssi
float64 nsd
bool valid
""",
    "waterlinked_a50_ros_driver/msg/DVL": """
std_msgs/Header header
float64 time
geometry_msgs/Vector3 velocity
float64 fom
float64 altitude
waterlinked_a50_ros_driver/DVLBeam[] beams
bool velocity_valid
int64 status
string form
""",
    # The ROS 1 driver's message has the same fields (it writes `angle` in
    # gradians, not the radians of its comment: datasets/README.md).
    "ping360_sonar/msg/SonarEcho": PING360_SONAR_ECHO,
    "cirs_girona_cala_viuda/msg/RangeImageBeam": """
std_msgs/Header header
float64 angle_grad
float64 angle_rad
int32 nbins
int32 max_range
int32[] beam_data
""",
    "cirs_girona_cala_viuda/msg/LinkquestDvl": """
std_msgs/Header header
string errcode
int32[4] datagood
float64[4] altitudebeam
float64[4] bottomvelocitybeam
float64[4] watervelocitybeam
float64[4] watervelocitycredit
float64[3] velocityinst
int32 velocityinstflag
float64[3] velocityearth
int32 velocityearthflag
float64[3] watervelocityinst
int32 watervelocityinstflag
float64[3] watervelocityearth
int32 watervelocityearthflag
float64 roll
float64 pitch
float64 heading
float64 altitude
float64 temperature
float64 pressure
float64 salinity
float64 soundspeed
string rawdata
""",
    "cirs_girona_cala_viuda/msg/Imu": """
std_msgs/Header header
float64 roll
float64 pitch
float64 yaw
float64 qx
float64 qy
float64 qz
float64 qw
float64 temp
float64 mx
float64 my
float64 mz
float64 ax
float64 ay
float64 az
float64 gx
float64 gy
float64 gz
float64 bx
float64 by
float64 bz
""",
    "cirs_girona_cala_viuda/msg/Depth": """
std_msgs/Header header
float64 depth
""",
}


def register(store, echofield_msg=None):
    """Registers every definition (and echofield_msgs/msg/SonarBeam from
    the package's .msg file when given) in a rosbags type store."""
    types = {}
    for name, text in DEFS.items():
        types.update(get_types_from_msg(text, name))
    if echofield_msg is not None:
        types.update(get_types_from_msg(open(echofield_msg).read(), "echofield_msgs/msg/SonarBeam"))
    store.register(types)
