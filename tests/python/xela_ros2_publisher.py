"""Publishes XELA's ROS 2 server messages with an independent DDS, Eclipse
Cyclone DDS (its Python binding), as `xela_server_ros2` does: type
`xela_server_ros2/msg/SensStream` (DDS `xela_server_ros2::msg::dds_::SensStream_`)
on topic `/xServTopic` (DDS `rt/xServTopic`), reliable, keep last 10 (rclpy's
default QoS for `create_publisher(..., 10)`). The types are written from the
.msg files of github.com/mcsix/xela_server_ros2 (commit 3a890cf).

    xela_ros2_publisher.py DOMAIN

Waits until a reader matches, then publishes a scan every 10 ms until stdin
closes: sensor_pos 1 and 2 (uSPa44, 16 taxels, with forces) and 3 (uSPa35,
24 taxels, no forces); taxel counts cover 0..65535 and the forces are
multiples of 1/64 N (exact in float32). Prints `ready` on stderr once its
writer exists, then one JSON line per published message on stdout at the
end. CYCLONEDDS_URI gives the network setup.
"""

import json
import sys
import threading
import time
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float32, float64, sequence, uint8, uint16, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Taxel(IdlStruct, typename="xela_server_ros2.msg.dds_.Taxel_"):
    x: uint16
    y: uint16
    z: uint16


@dataclass
class Forces(IdlStruct, typename="xela_server_ros2.msg.dds_.Forces_"):
    x: float32
    y: float32
    z: float32


@dataclass
class SensorFull(IdlStruct, typename="xela_server_ros2.msg.dds_.SensorFull_"):
    message: uint32
    time: float64
    model: str
    sensor_pos: uint8
    taxels: sequence[Taxel]
    forces: sequence[Forces]


@dataclass
class SensStream(IdlStruct, typename="xela_server_ros2.msg.dds_.SensStream_"):
    sensors: sequence[SensorFull]


SENSORS = [(1, "uSPa44", 16, True), (2, "uSPa44", 16, True), (3, "uSPa35", 24, False)]


def scan(n, state):
    sensors = []
    for pos, model, taxels, with_forces in SENSORS:
        values = []
        for _ in range(3 * taxels):
            state[0] = (state[0] * 1103515245 + 12345) % (1 << 31)
            values.append(state[0] >> 15 & 0xFFFF)
        if pos == 1:
            values[:3] = [0, 65535, 32768]
        forces = [(((v >> 4) % 512) - 256) / 64.0 for v in values] if with_forces else []
        sensors.append(
            SensorFull(
                message=n,
                time=1_700_000_000.0 + n / 100.0,
                model=model,
                sensor_pos=pos,
                taxels=[Taxel(*values[i : i + 3]) for i in range(0, len(values), 3)],
                forces=[Forces(*forces[i : i + 3]) for i in range(0, len(forces), 3)],
            )
        )
    return SensStream(sensors=sensors)


def as_json(msg):
    return {
        "sensors": [
            {
                "message": s.message,
                "time": s.time,
                "sensor_pos": s.sensor_pos,
                "taxels": [[t.x, t.y, t.z] for t in s.taxels],
                "forces": [[f.x, f.y, f.z] for f in s.forces],
            }
            for s in msg.sensors
        ]
    }


def main():
    domain = int(sys.argv[1])
    qos = Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.History.KeepLast(10),
        Policy.Durability.Volatile,
    )
    participant = DomainParticipant(domain)
    topic = Topic(participant, "rt/xServTopic", SensStream, qos=qos)
    writer = DataWriter(participant, topic, qos=qos)
    print("ready", file=sys.stderr, flush=True)
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    while not writer.get_matched_subscriptions():
        if done.wait(0.01):
            return
    published, state, n = [], [12345], 0
    while not done.is_set():
        msg = scan(n, state)
        writer.write(msg)
        published.append(as_json(msg))
        n += 1
        time.sleep(0.01)
    for m in published:
        print(json.dumps(m))


if __name__ == "__main__":
    main()
