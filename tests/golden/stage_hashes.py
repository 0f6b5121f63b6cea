#!/usr/bin/env python3
"""The SHA-256 of every stage's pixels (float32 RGBA, row-major) for a fixed set of scenes and
bloomref runs: `record` writes them, `check` compares (exit 1 naming each difference).
Usage: stage_hashes.py BLOOMREF CORPUS_DIR {record|check} FILE (CORPUS_DIR "-": $BLOOMREF_CORPUS;
exit 77, skipped, where it is not set).

The recorded file keeps the two built-in methods' bits: a change of any stage's bits is a change
of the specification and must say so (record again, with the reason in the commit).
"""
import hashlib
import os
import subprocess
import sys
import tempfile

import OpenImageIO as oiio
import numpy as np

SCENES = ["uffizi_probe-128.exr", "WideFloatRange.exr", "reference-crop.exr", "<demo>"]
RUNS = {
    "gaussian": [],
    "gaussian-f16": ["--storage", "f16"],
    "gaussian-linear5-full": ["--kernel", "linear5", "--plan", "full", "--passes", "4"],
    "gaussian-f64": ["--precision", "f64", "--passes", "3"],
    "mip": ["--method", "mip"],
    "mip-karis-f16": ["--method", "mip", "--karis", "--storage", "f16"],
    "mip-after-8bit": ["--method", "mip", "--composite", "after-tonemap", "--exposure", "0.5",
                       "--strength", "0.02", "--subtexel-bits", "8"],
}


def pixels_hash(path):
    # ImageInput, not ImageBuf: the image cache behind ImageBuf would return a replaced file's
    # old pixels under the same name.
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise SystemExit(f"cannot read {path}: {oiio.geterror()}")
    px = inp.read_image(0, 0, 0, 4, oiio.FLOAT)
    inp.close()
    if px is None or px.size == 0:
        raise SystemExit(f"cannot read {path}")
    return hashlib.sha256(np.ascontiguousarray(px, dtype=np.float32).tobytes()).hexdigest()


def hashes(exe, corpus):
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in SCENES:
            src = [] if scene == "<demo>" else [os.path.join(corpus, scene)]
            for name, args in RUNS.items():
                key = f"{scene} {name}"
                # The output alone (the fused paths), then every stage (nothing fused).
                o = os.path.join(tmp, "out.exr")
                subprocess.run([exe, "run", *src, *args, "-q", "-o", o], check=True)
                out[f"{key} output-only"] = pixels_hash(o)
                d = os.path.join(tmp, "stages")
                subprocess.run([exe, "run", *src, *args, "-q", "--dump-stages", d], check=True)
                for f in sorted(os.listdir(d)):
                    out[f"{key} {f[:-4]}"] = pixels_hash(os.path.join(d, f))
                    os.remove(os.path.join(d, f))
    return out


def main():
    exe, corpus, mode, file = sys.argv[1:5]
    if corpus == "-":
        corpus = os.environ.get("BLOOMREF_CORPUS", "")
    if not os.path.isdir(corpus):
        print("BLOOMREF_CORPUS is not set: skipped")
        return 77
    got = hashes(exe, corpus)
    if mode == "record":
        with open(file, "w") as f:
            for k, v in got.items():
                f.write(f"{v}  {k}\n")
        return 0
    want = {}
    with open(file) as f:
        for line in f:
            v, k = line.rstrip("\n").split("  ", 1)
            want[k] = v
    bad = [k for k in want if got.get(k) != want[k]]
    extra = [k for k in got if k not in want]
    for k in bad:
        print(f"changed: {k}: {want[k]} -> {got.get(k, 'missing')}")
    for k in extra:
        print(f"not recorded: {k}")
    print(f"{len(want) - len(bad)} of {len(want)} stage images keep their bits")
    return 1 if bad or extra else 0


if __name__ == "__main__":
    sys.exit(main())
