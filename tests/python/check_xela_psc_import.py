"""Checks that a session imported by `slidetrack import xela-psc` holds every
value of the trial folder it was made from, read with the official MCAP
reader (and NumPy for the rotation).

Usage: check_xela_psc_import.py SESSION TRIAL_DIR

Every row of every CSV file is compared with the message of the same index
(the MCAP `sequence` field is the row index), logged at the row's `time`
(robot_state.csv, in ns): tactile counts on /tactile/raw, raw minus the tare
on /tactile/zeroed exactly on rows whose counts changed, the marker on
/aruco/detections (a missed detection where the CSV has the 10.0 sentinel)
and on /markers/marker1/pose and /markers/tf (present exactly where the CSV
has a pose), all 33 robot columns on /robot/state (its quaternion the
rotation of the transform's 3x3 block) and /robot/ee_pose, both labels on
/slip/label; every meta_data.csv column in the `xela_psc` metadata record.
No /hand/state. Prints a JSON summary; exits non-zero on the first mismatch.
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


def rotation(q):
    x, y, z, w = (q[a] for a in "xyzw")
    return numpy.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def main(session, folder):
    with open(session, "rb") as f:
        reader = make_reader(f)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        messages = [(c, m) for _, c, m in reader.iter_messages()]
        summary = reader.get_summary()
    topics = {c.topic for c in summary.channels.values()}
    assert "/hand/state" not in topics, topics
    layout = json.loads(next(c for c in summary.channels.values() if c.topic == "/tactile/raw").metadata["taxel_layout"])
    assert [s["name"] for s in layout["sensors"]] == ["sensor1", "sensor2"], layout
    assert all((s["model"], s["rows"], s["cols"]) == ("uSPa44", 4, 4) for s in layout["sensors"]), layout
    assert metadata["slidetrack"]["rig"] == "xela-psc", metadata["slidetrack"]
    compared = 0

    header, robot_rows = rows(os.path.join(folder, "robot_state.csv"))
    assert header[-1] == "time"
    times_ns = [round(float(r[-1]) * 1e9) for r in robot_rows]
    assert all(b >= a for a, b in zip(times_ns, times_ns[1:])), "time decreases"

    def at_row(topic, got, i):
        assert got[i][0] == times_ns[i], f"{topic} row {i}: logged at {got[i][0]} ns, time is {times_ns[i]} ns"

    raw = by_sequence(messages, "/tactile/raw")
    zeroed = by_sequence(messages, "/tactile/zeroed")
    tare = by_sequence(messages, "/tactile/tare")[0][1]
    counts = []
    for s in (0, 1):
        header, data = rows(os.path.join(folder, f"xela_sensor{s + 1}.csv"))
        assert len(data) == len(raw), f"sensor {s + 1}: {len(data)} rows, {len(raw)} scans"
        counts.append([[float(x) for x in r] for r in data])
        for i, r in enumerate(data):
            at_row("/tactile/raw", raw, i)
            taxels = raw[i][1]["sensors"][s]["taxels"]
            assert len(taxels) == 16
            for col, text in enumerate(r):
                got = taxels[col // 3]["xyz"[col % 3]]
                assert got == float(text), f"sensor {s + 1} row {i} {header[col]}: {got} != {text}"
                compared += 1
    for i in range(len(raw)):
        fresh = i == 0 or counts[0][i] != counts[0][i - 1] or counts[1][i] != counts[1][i - 1]
        assert (i in zeroed) == fresh, f"row {i}: zeroed {'missing' if fresh else 'written for a repeated row'}"
        if fresh:
            at_row("/tactile/zeroed", zeroed, i)
            for s in (0, 1):
                z = zeroed[i][1]["sensors"][s]["taxels"]
                b = tare["baseline"][s]["taxels"]
                for col in range(48):
                    a = "xyz"[col % 3]
                    want = counts[s][i][col] - b[col // 3][a]
                    assert abs(z[col // 3][a] - want) < 1e-9, f"zeroed row {i} sensor {s + 1} col {col}"

    header, data = rows(os.path.join(folder, "marker.csv"))
    aruco = by_sequence(messages, "/aruco/detections")
    poses = by_sequence(messages, "/markers/marker1/pose")
    tfs = by_sequence(messages, "/markers/tf")
    assert len(aruco) == len(data), f"{len(aruco)} detections for {len(data)} marker rows"
    for i, r in enumerate(data):
        v = [float(x) for x in r]
        at_row("/aruco/detections", aruco, i)
        d = aruco[i][1]
        if all(x == SENTINEL for x in v):
            assert i not in poses and i not in tfs, f"marker row {i}: not seen, but a pose was written"
            assert not d["detected"] and d["position_in_camera_m"] is None, f"row {i}: {d}"
        else:
            at_row("/markers/marker1/pose", poses, i)
            p = poses[i][1]["pose"]
            got = [p["position"][a] for a in "xyz"] + [p["orientation"][a] for a in "xyzw"]
            assert got == v, f"marker row {i}: {got} != {v}"
            assert poses[i][1]["frame_id"] == "camera"
            tf = tfs[i][1]
            assert (tf["parent_frame_id"], tf["child_frame_id"]) == ("camera", "marker1"), tf
            assert [tf["translation"][a] for a in "xyz"] + [tf["rotation"][a] for a in "xyzw"] == v
            q = d["orientation_in_camera"]
            assert d["detected"] and d["position_in_camera_m"] + [q[a] for a in "xyzw"] == v, f"row {i}: {d}"
        compared += 7

    robot = by_sequence(messages, "/robot/state")
    ee_pose = by_sequence(messages, "/robot/ee_pose")
    assert len(robot) == len(robot_rows) == len(ee_pose)
    for i, r in enumerate(robot_rows):
        v = [float(x) for x in r]
        at_row("/robot/state", robot, i)
        m = robot[i][1]
        got = (m["joint_position_rad"] + m["joint_velocity_rad_s"] + m["ee_transform_column_major"]
               + [m["v_x_m_s"], m["v_y_m_s"], m["time_s"]])
        assert got == v, f"robot row {i}: {got} != {v}"
        compared += 33
        t = numpy.array(v[14:30]).reshape(4, 4).T  # column-major: t[row][col] = ee_T_<row><col>
        assert m["ee_position_in_base_m"] == list(t[:3, 3]), f"robot row {i}: position"
        q = m["ee_orientation_in_base"]
        assert q["w"] >= 0 and abs(sum(q[a] ** 2 for a in "xyzw") - 1) < 1e-9, q
        assert numpy.abs(rotation(q) - t[:3, :3]).max() < 1e-4, f"robot row {i}: quaternion"
        e = ee_pose[i][1]
        assert e["frame_id"] == "base"
        assert [e["pose"]["position"][a] for a in "xyz"] == m["ee_position_in_base_m"]
        assert e["pose"]["orientation"] == q

    header, data = rows(os.path.join(folder, "slip_label.csv"))
    assert header == ["slip", "fail"], header
    labels = by_sequence(messages, "/slip/label")
    assert len(labels) == len(data)
    for i, r in enumerate(data):
        at_row("/slip/label", labels, i)
        assert [labels[i][1]["slip"], labels[i][1]["fail"]] == [float(x) for x in r], f"label row {i}"
        compared += 2

    source = metadata["xela_psc"]
    header, data = rows(os.path.join(folder, "meta_data.csv"))
    for name, value in zip(header, data[0]):
        assert source[f"meta.{name}"] == value, f"meta_data.csv {name}: {source.get('meta.' + name)!r} != {value!r}"
        compared += 1
    assert source["dropped"] == ("true" if float(data[0][header.index("dropped")]) else "false")
    assert int(source["rows"]) == len(robot_rows)

    print(json.dumps({
        "values_compared": compared,
        "rows": len(raw),
        "zeroed_rows": len(zeroed),
        "marker_seen": len(poses),
        "slip_rows": sum(1 for _, m in labels.values() if m["slip"]),
        "fail_rows": sum(1 for _, m in labels.values() if m["fail"]),
        "metadata": sorted(metadata),
    }))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
