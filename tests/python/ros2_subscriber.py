"""Subscribes to slidetrack's ROS 2 topics with an independent DDS
implementation, Eclipse Cyclone DDS (its Python binding), by their ROS 2
DDS names (`rt/tactile/raw`) and types (`slidetrack_msgs::msg::dds_::...`).

    ros2_subscriber.py DOMAIN [--never-read]

Prints `ready` on stderr once its readers exist, then takes every sample
until stdin closes (and 1 s more); then prints one JSON line per received
message on stdout: {"topic", "stamp_ns", ...the message's fields}. With
--never-read it only holds its readers (a subscriber that never reads) and
prints nothing. The network setup (loopback, unicast) comes from
CYCLONEDDS_URI.
"""

import base64
import json
import sys
import threading
import time
from pathlib import Path

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

sys.path.insert(0, str(Path(__file__).parent))
from ros2_types import (  # noqa: E402
    CameraInfo,
    CompressedImage,
    HandState,
    Odometry,
    PoseStamped,
    SlidingEstimate,
    TactileRaw,
    TFMessage,
    TwistStamped,
)

# The reliability of ROS 2's QoS profiles: sensor data best effort, the
# default reliable (a reliable reader does not match a best-effort writer).
# The readers keep every sample until taken (history is not matched between
# writer and reader): a slow Python on a loaded machine loses nothing to a
# keep-last depth of 5.
SENSOR = Qos(Policy.Reliability.BestEffort, Policy.History.KeepAll, Policy.Durability.Volatile)
DEFAULT = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.History.KeepAll,
    Policy.Durability.Volatile,
)
TOPICS = [
    ("/tactile/raw", TactileRaw, SENSOR),
    ("/hand/state", HandState, SENSOR),
    ("/estimate/dekf", SlidingEstimate, DEFAULT),
    ("/estimate/aruco", SlidingEstimate, DEFAULT),
    ("/camera/image", CompressedImage, SENSOR),
    ("/camera/calibration", CameraInfo, SENSOR),
    ("/tf", TFMessage, DEFAULT),
    ("/estimate/pose/maskukf", PoseStamped, DEFAULT),
    ("/estimate/velocity/maskukf", TwistStamped, DEFAULT),
    ("/estimate/odometry/maskukf", Odometry, DEFAULT),
]


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def xyz(v):
    return [v.x, v.y, v.z]


def fields(msg):
    if isinstance(msg, CompressedImage):
        data = base64.b64encode(bytes(msg.data)).decode()
        return {"frame_id": msg.header.frame_id, "format": msg.format, "data": data}
    if isinstance(msg, CameraInfo):
        return {"frame_id": msg.header.frame_id, "width": msg.width, "height": msg.height, "k": list(msg.k)}
    if isinstance(msg, TFMessage):
        t = msg.transforms[0]
        r = t.transform.rotation
        return {"parent": t.header.frame_id, "child": t.child_frame_id,
                "translation": xyz(t.transform.translation), "rotation": [r.x, r.y, r.z, r.w]}
    if isinstance(msg, PoseStamped):
        q = msg.pose.orientation
        return {"frame_id": msg.header.frame_id, "position": xyz(msg.pose.position),
                "orientation": [q.x, q.y, q.z, q.w]}
    if isinstance(msg, TwistStamped):
        return {"frame_id": msg.header.frame_id, "linear": xyz(msg.twist.linear),
                "angular": xyz(msg.twist.angular)}
    if isinstance(msg, Odometry):
        pose, twist = msg.pose, msg.twist
        q = pose.pose.orientation
        return {"frame_id": msg.header.frame_id, "child": msg.child_frame_id,
                "position": xyz(pose.pose.position), "orientation": [q.x, q.y, q.z, q.w],
                "pose_covariance": list(pose.covariance), "linear": xyz(twist.twist.linear),
                "angular": xyz(twist.twist.angular), "twist_covariance": list(twist.covariance)}
    if isinstance(msg, TactileRaw):
        sensors = [{"name": s.name, "x": list(s.x), "y": list(s.y), "z": list(s.z)} for s in msg.sensors]
        return {"sequence": msg.sequence, "sensors": sensors}
    if isinstance(msg, HandState):
        g = msg.gripper
        gripper = [g.activated, g.object, g.fault, g.requested, g.position, g.current_ma]
        return {
            "finger_travel": list(msg.finger_travel),
            "opening": msg.opening if msg.has_opening else None,
            "gripper": gripper if msg.has_gripper else None,
        }
    return {"position": msg.position, "velocity": msg.velocity, "covariance": list(msg.covariance)}


def main():
    domain = int(sys.argv[1])
    never_read = "--never-read" in sys.argv[2:]
    participant = DomainParticipant(domain)
    readers = []
    for name, kind, qos in TOPICS:
        topic = Topic(participant, "rt" + name, kind, qos=qos)
        readers.append((name, DataReader(participant, topic, qos=qos)))
    closed = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), closed.set()), daemon=True).start()
    print("ready", file=sys.stderr, flush=True)
    received = []
    deadline = None
    while deadline is None or time.monotonic() < deadline:
        if closed.is_set() and deadline is None:
            deadline = time.monotonic() + 1.0
        if never_read:
            time.sleep(0.05)
            continue
        for name, reader in readers:
            for msg in reader.take(N=1000):
                if isinstance(msg, TFMessage) and msg.transforms:
                    header = msg.transforms[0].header
                elif hasattr(msg, "header"):
                    header = msg.header
                else:
                    continue  # an invalid sample (a writer gone), no data
                received.append({"topic": name, "stamp_ns": stamp_ns(header), **fields(msg)})
        time.sleep(0.005)
    for line in received:
        print(json.dumps(line))


if __name__ == "__main__":
    main()
