"""ROS 2 message types for Eclipse Cyclone DDS's Python binding, written
from their .msg definitions: the DDS type names are ROS 2's
(`pkg::msg::dds_::Type_`, as rmw_cyclonedds_cpp names them), the fields in
the .msg order. slidetrack_msgs: session/ros2/slidetrack_msgs/msg/*.msg.
builtin_interfaces/Time, std_msgs/Header: ROS 2's rcl_interfaces and
common_interfaces repositories.
"""

from dataclasses import dataclass

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float64, int32, sequence, uint8, uint16, uint32, uint64


@dataclass
class Time(IdlStruct, typename="builtin_interfaces.msg.dds_.Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs.msg.dds_.Header_"):
    stamp: Time
    frame_id: str


@dataclass
class TactileSensorRaw(IdlStruct, typename="slidetrack_msgs.msg.dds_.TactileSensorRaw_"):
    name: str
    x: sequence[uint16]
    y: sequence[uint16]
    z: sequence[uint16]


@dataclass
class TactileRaw(IdlStruct, typename="slidetrack_msgs.msg.dds_.TactileRaw_"):
    header: Header
    sequence: uint64
    sensors: sequence[TactileSensorRaw]


@dataclass
class GripperState(IdlStruct, typename="slidetrack_msgs.msg.dds_.GripperState_"):
    activated: bool
    object: uint8
    fault: uint8
    requested: uint16
    position: uint16
    current_ma: uint32


@dataclass
class HandState(IdlStruct, typename="slidetrack_msgs.msg.dds_.HandState_"):
    header: Header
    finger_travel: sequence[float64]
    has_opening: bool
    opening: float64
    has_gripper: bool
    gripper: GripperState


@dataclass
class SlidingEstimate(IdlStruct, typename="slidetrack_msgs.msg.dds_.SlidingEstimate_"):
    header: Header
    position: float64
    velocity: float64
    covariance: array[float64, 4]


# sensor_msgs, geometry_msgs and tf2_msgs: ros2/common_interfaces and
# ros2/geometry2, their .msg files.


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs.msg.dds_.CompressedImage_"):
    header: Header
    format: str
    data: sequence[uint8]


@dataclass
class RegionOfInterest(IdlStruct, typename="sensor_msgs.msg.dds_.RegionOfInterest_"):
    x_offset: uint32
    y_offset: uint32
    height: uint32
    width: uint32
    do_rectify: bool


@dataclass
class CameraInfo(IdlStruct, typename="sensor_msgs.msg.dds_.CameraInfo_"):
    header: Header
    height: uint32
    width: uint32
    distortion_model: str
    d: sequence[float64]
    k: array[float64, 9]
    r: array[float64, 9]
    p: array[float64, 12]
    binning_x: uint32
    binning_y: uint32
    roi: RegionOfInterest


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs.msg.dds_.Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs.msg.dds_.Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Transform(IdlStruct, typename="geometry_msgs.msg.dds_.Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs.msg.dds_.TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs.msg.dds_.TFMessage_"):
    transforms: sequence[TransformStamped]


@dataclass
class Point(IdlStruct, typename="geometry_msgs.msg.dds_.Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs.msg.dds_.Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs.msg.dds_.PoseStamped_"):
    header: Header
    pose: Pose


@dataclass
class Twist(IdlStruct, typename="geometry_msgs.msg.dds_.Twist_"):
    linear: Vector3
    angular: Vector3


@dataclass
class TwistStamped(IdlStruct, typename="geometry_msgs.msg.dds_.TwistStamped_"):
    header: Header
    twist: Twist


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs.msg.dds_.PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs.msg.dds_.TwistWithCovariance_"):
    twist: Twist
    covariance: array[float64, 36]


# nav_msgs: ros2/common_interfaces, nav_msgs/msg/Odometry.msg.


@dataclass
class Odometry(IdlStruct, typename="nav_msgs.msg.dds_.Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance
