"""Rewrites the EXR images of a folder as RenderDoc saves a render target of 32-bit float
components: uncompressed scanline EXR, float channels A, B, G, R (baldurk/renderdoc,
renderdoc/replay/replay_controller.cpp, SaveTexture: tinyexr's InitEXRHeader leaves the
compression at 0, none; recent versions keep float for 4-byte components). For the check
benchmark (scripts/perf-report), which times check of the same stages in this form beside
bloomref's own PIZ dumps.

  PYTHONPATH=build/python python3 benchmarks/renderdoc_format.py FROM_DIR TO_DIR
"""
import os
import struct
import sys

import numpy as np

import bloomref


def attribute(name, kind, value):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def write_exr(path, image):
    """`image` (H x W x 4 float32, RGBA) as an uncompressed scanline EXR, channels A, B, G, R."""
    h, w = image.shape[:2]
    names = ["A", "B", "G", "R"]  # OpenEXR's channel list is sorted by name
    index = {"R": 0, "G": 1, "B": 2, "A": 3}
    channels = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for n in names)
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<i", 2) +
              attribute("channels", "chlist", channels + b"\0") +
              attribute("compression", "compression", b"\0") +
              attribute("dataWindow", "box2i", box) +
              attribute("displayWindow", "box2i", box) +
              attribute("lineOrder", "lineOrder", b"\0") +
              attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)) +
              attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)) +
              attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    # Each line: its y, its byte count, then each channel's w floats in the list's order.
    planar = np.ascontiguousarray(
        np.stack([image[:, :, index[n]] for n in names], axis=1).astype("<f4"))  # h x 4 x w
    line_bytes = 4 * w * 4
    first = len(header) + 8 * h
    offsets = struct.pack(f"<{h}Q", *(first + y * (8 + line_bytes) for y in range(h)))
    tmp = path + ".part"
    with open(tmp, "wb") as f:
        f.write(header)
        f.write(offsets)
        for y in range(h):
            f.write(struct.pack("<ii", y, line_bytes))
            f.write(planar[y].tobytes())
    os.replace(tmp, path)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[-1].strip())
    src, dst = sys.argv[1], sys.argv[2]
    os.makedirs(dst, exist_ok=True)
    for name in sorted(os.listdir(src)):
        if name.endswith(".exr"):
            write_exr(os.path.join(dst, name), bloomref.load(os.path.join(src, name)))


if __name__ == "__main__":
    main()
