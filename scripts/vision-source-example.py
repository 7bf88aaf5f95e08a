#!/usr/bin/env python3
"""A reference client of slidetrack's external vision source (protocol v1,
docs/protocols.md "External vision source"), standard library only.

slidetrack listens (`vision track --measurements external --listen ADDR`);
this client connects, says hello, and answers every announced frame with a
pose and/or a mask. Replace `answer()` with your network.

  scripts/vision-source-example.py --connect 127.0.0.1:7450 \
      --fixed-pose 0,0,0.75,0,0,0,1 [--mask-rect 250,180,390,300]
  scripts/vision-source-example.py --poses poses.csv [--masks-dir masks/]

poses.csv: a header, then `frame_t_ns,tx_m,ty_m,tz_m,qx,qy,qz,qw` rows
(camera_from_object, camera frame). masks-dir: `<frame_t_ns>.png` files
(any PNG; non-zero first channel = object), sent as they are.
"""

import argparse
import base64
import csv
import json
import os
import socket
import sys
import time

PROTOCOL = "slidetrack-vision-source"
VERSION = 1


def rle_rectangle(width, height, rect):
    """Row-major run lengths (outside first) of the rectangle u0,v0,u1,v1 (end exclusive)."""
    u0, v0, u1, v1 = rect
    counts, inside, run = [], False, 0
    for v in range(height):
        for u in range(width):
            here = u0 <= u < u1 and v0 <= v < v1
            if here != inside:
                counts.append(run)
                inside, run = here, 0
            run += 1
    counts.append(run)
    return {"encoding": "rle", "width": width, "height": height, "counts": counts}


def pose_message(values):
    tx, ty, tz, qx, qy, qz, qw = values
    return {"translation_m": [tx, ty, tz], "rotation_xyzw": [qx, qy, qz, qw]}


def connect(address, retry_s):
    host, port = address.rsplit(":", 1)
    deadline = time.monotonic() + retry_s
    while True:
        try:
            return socket.create_connection((host, int(port)))
        except OSError as e:
            if time.monotonic() > deadline:
                sys.exit(f"cannot connect to {address}: {e}")
            time.sleep(0.2)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--connect", default="127.0.0.1:7450", help="slidetrack's --listen address")
    p.add_argument("--fixed-pose", help="tx,ty,tz,qx,qy,qz,qw sent for every frame")
    p.add_argument("--poses", help="CSV of poses by frame_t_ns")
    p.add_argument("--masks-dir", help="directory of <frame_t_ns>.png masks")
    p.add_argument("--mask-rect", help="u0,v0,u1,v1: a rectangular mask for every frame")
    p.add_argument("--retry", type=float, default=10.0, help="seconds to keep trying to connect")
    args = p.parse_args()

    fixed = [float(v) for v in args.fixed_pose.split(",")] if args.fixed_pose else None
    poses = {}
    if args.poses:
        with open(args.poses, newline="") as f:
            for row in csv.DictReader(f):
                poses[int(row["frame_t_ns"])] = [float(row[k]) for k in ("tx_m", "ty_m", "tz_m", "qx", "qy", "qz", "qw")]
    rect = [int(v) for v in args.mask_rect.split(",")] if args.mask_rect else None

    sock = connect(args.connect, args.retry)
    reader = sock.makefile("r", encoding="utf-8", newline="\n")
    writer = sock.makefile("w", encoding="utf-8", newline="\n")

    def send(message):
        writer.write(json.dumps(message, separators=(",", ":")) + "\n")
        writer.flush()

    hello = json.loads(reader.readline())
    if hello.get("type") != "hello" or hello.get("version") != VERSION:
        sys.exit(f"unexpected server hello: {hello}")
    width, height = hello["width"], hello["height"]
    send({"type": "hello", "protocol": PROTOCOL, "version": VERSION, "name": "vision-source-example"})
    print(f"connected: {width}x{height} px, intrinsics {hello['intrinsics']}", file=sys.stderr)

    answered = 0
    for line in reader:
        message = json.loads(line)
        if message["type"] == "error":
            print(f"slidetrack refused a message: {message['kind']}: {message['detail']}", file=sys.stderr)
            continue
        if message["type"] != "frame":
            continue
        t = message["frame_t_ns"]
        result = {"type": "result", "frame_t_ns": t}
        pose = poses.get(t, fixed)
        if pose is not None:
            result["pose"] = pose_message(pose)
        if rect:
            result["mask"] = rle_rectangle(width, height, rect)
        if args.masks_dir:
            path = os.path.join(args.masks_dir, f"{t}.png")
            if os.path.exists(path):
                with open(path, "rb") as f:
                    result["mask"] = {"encoding": "png", "data": base64.b64encode(f.read()).decode("ascii")}
        # A result without pose and mask says "nothing on this frame": in
        # lockstep the tracker then goes on at once instead of waiting.
        send(result)
        answered += 1
    print(f"slidetrack closed the connection; {answered} frames answered", file=sys.stderr)


if __name__ == "__main__":
    main()
