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
