#!/usr/bin/env python3
"""A failing check against a passing one: what searching the causes costs.

The demo scene at --size (default 1920x1080) is run with `run --plan full --dump-stages`; the
passing set is its input, bright and ten blur passes as dumped, the failing set the same with
every blur pass k scaled by 1.07^k (a blur whose weights sum to 1.07, the bug of
community-shaders/skyrim-community-shaders#1595: every pass fails on its own and names
`weight-sum`). `bloomref check` of each, as whole commands (start to exit), alternated --repeat
times (default 7): medians, their ratio, and whether it is within the goal (a FAIL within 2x of
a PASS). The failing run must name weight-sum at blur.1 and the passing one PASS (exit 1
otherwise). Writes --json FILE when asked.

    python3 benchmarks/check_fail_vs_pass.py --bloomref build/cli/bloomref [--size WxH]
        [--repeat N] [--out DIR] [--json FILE]
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import OpenImageIO as oiio


def run(args, ok=(0,)):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode not in ok:
        sys.exit("check_fail_vs_pass: %s: exit %d\n%s" % (" ".join(args), r.returncode, r.stderr))


def scaled(src, dst, gain):
    img = oiio.ImageBuf(src)
    a = img.get_pixels(oiio.FLOAT)
    a[..., :3] *= np.float32(gain)
    spec = oiio.ImageSpec(a.shape[1], a.shape[0], a.shape[2], oiio.FLOAT)
    spec.channelnames = img.spec().channelnames
    # Compressed as the dump it scales is (--dump-stages' default, uncompressed): the two sets
    # then differ only in what check finds in them.
    spec.attribute("compression", img.spec().get_string_attribute("compression", "none"))
    out = oiio.ImageBuf(spec)
    out.set_pixels(oiio.ROI(), a)
    if not out.write(dst):
        sys.exit("check_fail_vs_pass: cannot write %s: %s" % (dst, out.geterror()))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bloomref", required=True)
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--out")
    ap.add_argument("--json")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="bloomref-fail-vs-pass.", dir=a.out)
    try:
        scene = os.path.join(tmp, "scene.exr")
        dump, good, bad = (os.path.join(tmp, d) for d in ("dump", "pass", "fail"))
        run([a.bloomref, "scenes", "demo", "--size", a.size, "-o", scene])
        run([a.bloomref, "run", scene, "--plan", "full", "--dump-stages", dump, "-o",
             os.path.join(tmp, "out.exr"), "-q"])
        os.makedirs(good)
        os.makedirs(bad)
        for name in ["input", "bright"] + ["blur.%d" % k for k in range(1, 11)]:
            f = name + ".exr"
            shutil.copy(os.path.join(dump, f), os.path.join(good, f))
            if name.startswith("blur."):
                scaled(os.path.join(dump, f), os.path.join(bad, f), 1.07 ** int(name[5:]))
            else:
                shutil.copy(os.path.join(dump, f), os.path.join(bad, f))
        times = {"pass": [], "fail": []}
        for _ in range(a.repeat):
            for kind, folder, ok in (("pass", good, (0,)), ("fail", bad, (1,))):
                js = os.path.join(tmp, kind + ".json")
                t0 = time.perf_counter()
                run([a.bloomref, "check", scene, "--stages", folder, "--json", js, "-q"], ok)
                times[kind].append((time.perf_counter() - t0) * 1e3)
                item = json.load(open(js))["items"][0]
                if kind == "fail":
                    cause = item.get("first_divergent_cause") or {}
                    if item["first_divergent_stage"] != "blur.1" or cause.get("id") != "weight-sum":
                        sys.exit("check_fail_vs_pass: the failing set named %r at %r, not weight-sum at blur.1"
                                 % (cause.get("id"), item["first_divergent_stage"]))
        p, f = statistics.median(times["pass"]), statistics.median(times["fail"])
        result = {"size": a.size, "repeat": a.repeat, "pass_ms": p, "fail_ms": f, "ratio": f / p,
                  "goal": 2.0, "met": f / p <= 2.0}
        print("check at %s, medians of %d alternated runs: PASS %.0f ms, FAIL (every pass 1.07x, "
              "weight-sum named) %.0f ms: %.2fx (goal <= 2x)%s"
              % (a.size, a.repeat, p, f, f / p, "" if result["met"] else "  WARN: goal not met"))
        if a.json:
            with open(a.json, "w") as fh:
                json.dump(result, fh, indent=1)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
