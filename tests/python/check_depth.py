"""Decodes every /rgbd/depth frame of a session with the official MCAP reader
and a PNG decoder of its own (zlib, the five PNG row filters, NumPy): no
code shared with slidetrack's Rust decoder.

Usage: check_depth.py SESSION OUT

Reads both forms of /rgbd/depth: `foxglove.CompressedImage` holding a 16-bit
greyscale PNG (format `png`) and the older `foxglove.RawImage` `16UC1`.
Writes every frame's values to OUT, in log-time order, as little-endian
uint16 (row-major, frames one after another), and prints a JSON summary:
frames, the form of each, sizes, and the message bytes of each frame.
"""
import base64
import json
import struct
import sys
import zlib

import numpy as np
from mcap.reader import make_reader

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def paeth(a, b, c):
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    return b if pb <= pc else c


def unfilter(kind, line, prev, bpp):
    """One row of bytes (int32) back from PNG filter `kind` (RFC 2083, 6.)."""
    if kind == 0:
        return line
    if kind == 2:
        return (line + prev) & 0xFF
    out = line.copy()
    if kind == 1:
        for lane in range(bpp):
            out[lane::bpp] = np.cumsum(line[lane::bpp]) & 0xFF
        return out
    for i in range(len(line)):
        left = out[i - bpp] if i >= bpp else 0
        if kind == 3:
            out[i] = (line[i] + (left + prev[i]) // 2) & 0xFF
        elif kind == 4:
            up_left = prev[i - bpp] if i >= bpp else 0
            out[i] = (line[i] + paeth(int(left), int(prev[i]), int(up_left))) & 0xFF
        else:
            raise AssertionError(f"unknown PNG filter {kind}")
    return out


def decode_png16(data):
    """A 16-bit greyscale, non-interlaced PNG as a (height, width) uint16 array."""
    assert data[:8] == PNG_SIGNATURE, "not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert zlib.crc32(kind + body) & 0xFFFFFFFF == crc, f"bad CRC in {kind}"
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
        pos += 12 + length
    width, height, bit_depth, color, _, _, interlace = header
    assert (bit_depth, color, interlace) == (16, 0, 0), f"not 16-bit grey: {header}"
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).astype(np.int32)
    stride = 2 * width
    assert raw.size == height * (stride + 1), "wrong amount of image data"
    rows, prev = [], np.zeros(stride, dtype=np.int32)
    for y in range(height):
        start = y * (stride + 1)
        prev = unfilter(int(raw[start]), raw[start + 1 : start + 1 + stride], prev, 2)
        rows.append(prev)
    return np.array(rows, dtype=np.uint8).reshape(height, stride).view(">u2").astype(np.uint16)


def decode(payload):
    if "format" in payload:
        assert payload["format"] == "png", payload["format"]
        return "png", decode_png16(base64.b64decode(payload["data"]))
    assert payload["encoding"] == "16UC1", payload["encoding"]
    w, h = payload["width"], payload["height"]
    assert payload["step"] == 2 * w
    values = np.frombuffer(base64.b64decode(payload["data"]), dtype="<u2")
    return "16UC1", values.reshape(h, w)


def main():
    path, out_path = sys.argv[1], sys.argv[2]
    forms, sizes, message_bytes = [], set(), []
    with open(path, "rb") as f, open(out_path, "wb") as out:
        reader = make_reader(f)
        for _, _, message in reader.iter_messages(topics=["/rgbd/depth"], log_time_order=True):
            form, values = decode(json.loads(message.data))
            forms.append(form)
            sizes.add(values.shape)
            message_bytes.append(len(message.data))
            out.write(values.astype("<u2").tobytes())
    print(json.dumps({
        "frames": len(forms),
        "forms": sorted(set(forms)),
        "sizes": sorted(sizes),
        "message_bytes": message_bytes,
    }))


if __name__ == "__main__":
    main()
