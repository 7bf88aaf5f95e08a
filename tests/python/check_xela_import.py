"""Checks that a session imported by `slidetrack import xela-csv` holds every
value of the sequence folder it was made from, read with the official MCAP
reader (and NumPy for `meta_data.csv.npy`).

Usage: check_xela_import.py SESSION SEQUENCE_DIR

Every row of every CSV file is compared with the message of the same index
(the MCAP `sequence` field is the row index): tactile counts on /tactile/raw,
marker 1 on /aruco/detections (a missed detection where the CSV has the 10.0
sentinel), both markers on /markers/markerN/pose (present exactly where the
CSV has a pose), the robot state on /robot/state and /hand/state; every
meta_data.csv column in the `xela_imanlab` metadata record. Prints a JSON
summary; exits non-zero on the first mismatch.
"""
import csv
import json
import os
import sys

import numpy
from mcap.reader import make_reader

SENTINEL = 10.0


def rows(path):
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        return header, [r for r in reader]


def by_sequence(messages, topic):
    out = {}
    for channel, message in messages:
        if channel.topic == topic:
            assert message.sequence not in out, f"{topic}: two messages for row {message.sequence}"
            out[message.sequence] = (message.log_time, json.loads(message.data))
    return out


def main(session, folder):
    with open(session, "rb") as f:
        reader = make_reader(f)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        messages = [(c, m) for _, c, m in reader.iter_messages()]
        summary = reader.get_summary()
    layout = json.loads(next(c for c in summary.channels.values() if c.topic == "/tactile/raw").metadata["taxel_layout"])
    assert [s["name"] for s in layout["sensors"]] == ["sensor1", "sensor2"], layout
    assert all((s["model"], s["rows"], s["cols"]) == ("uSPa44", 4, 4) for s in layout["sensors"]), layout
    compared = 0

    raw = by_sequence(messages, "/tactile/raw")
    for s in (0, 1):
        header, data = rows(os.path.join(folder, f"xela_sensor{s + 1}.csv"))
        assert len(data) == len(raw), f"sensor {s + 1}: {len(data)} rows, {len(raw)} scans"
        for i, r in enumerate(data):
            taxels = raw[i][1]["sensors"][s]["taxels"]
            assert len(taxels) == 16
            for col, text in enumerate(r):
                got = taxels[col // 3]["xyz"[col % 3]]
                assert got == float(text), f"sensor {s + 1} row {i} {header[col]}: {got} != {text}"
                compared += 1

    header, data = rows(os.path.join(folder, "marker.csv"))
    aruco = by_sequence(messages, "/aruco/detections")
    poses = [by_sequence(messages, f"/markers/marker{k + 1}/pose") for k in (0, 1)]
    assert len(aruco) == len(data), f"{len(aruco)} detections for {len(data)} marker rows"
    for i, r in enumerate(data):
        v = [float(x) for x in r]
        for k in (0, 1):
            pose = v[7 * k:7 * k + 7]
            msg = poses[k].get(i)
            if all(x == SENTINEL for x in pose):
                assert msg is None, f"marker {k + 1} row {i}: not seen, but a pose was written"
            else:
                p = msg[1]["pose"]
                got = [p["position"][a] for a in "xyz"] + [p["orientation"][a] for a in "xyzw"]
                assert got == pose, f"marker {k + 1} row {i}: {got} != {pose}"
                assert msg[1]["frame_id"] == "camera"
            compared += 7
        d = aruco[i][1]
        if all(x == SENTINEL for x in v[:7]):
            assert not d["detected"] and d["position_in_camera_m"] is None, f"row {i}: {d}"
        else:
            q = d["orientation_in_camera"]
            assert d["detected"] and d["position_in_camera_m"] + [q[a] for a in "xyzw"] == v[:7], f"row {i}: {d}"

    header, data = rows(os.path.join(folder, "robot_state.csv"))
    robot = by_sequence(messages, "/robot/state")
    gripper = by_sequence(messages, "/hand/state")
    assert len(robot) == len(data) == len(gripper)
    for i, r in enumerate(data):
        v = [float(x) for x in r]
        m = robot[i][1]
        q = m["ee_orientation_in_base"]
        got = (m["joint_position_rad"] + [gripper[i][1]["opening"]] + m["joint_velocity_rad_s"]
               + m["ee_position_in_base_m"] + [q[a] for a in "xyzw"])
        assert got == v, f"robot row {i}: {got} != {v}"
        compared += 22

    source = metadata["xela_imanlab"]
    header, data = rows(os.path.join(folder, "meta_data.csv"))
    for name, value in zip(header, data[0]):
        assert source[f"meta.{name}"] == value, f"meta_data.csv {name}: {source.get('meta.' + name)!r} != {value!r}"
        compared += 1
    npy = os.path.join(folder, "meta_data.csv.npy")
    if os.path.exists(npy):
        assert source["meta_data_npy_path"] == str(numpy.load(npy)), source["meta_data_npy_path"]
        compared += 1
    else:
        assert source["meta_data_npy_present"] == "false"
    dropped = data[0][header.index("dropped")]
    assert source["dropped"] == ("true" if float(dropped) else "false")

    times = {t for t, _ in raw.values()}
    print(json.dumps({
        "values_compared": compared,
        "tactile_rows": len(raw),
        "marker_rows": len(aruco),
        "robot_rows": len(robot),
        "distinct_scan_times": len(times),
        "marker1_seen": len(poses[0]),
        "marker2_seen": len(poses[1]),
        "metadata": sorted(metadata),
    }))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
