#!/usr/bin/env python3
"""Each lossless EXR compression `run --dump-stages` offers, on the demo frame's 15 stages:
the dumps' size, `run --plan full --dump-stages` (writing them) and `check` of them with one
thread and with two, whole commands, alternated `--repeat` times; medians. Beside them
`run --plan full` of the frame, as the check speed goal (check <= 3x run) measures it.
docs/design.md, "EXR compression", quotes a run of it.

    benchmarks/dump_compression.py --bloomref build/cli/bloomref --out DIR [--size WxH] [--repeat N]
"""
import argparse
import os
import shutil
import statistics
import subprocess
import time

KINDS = ("none", "rle", "zips", "zip", "piz")


def timed(cmd):
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return (time.perf_counter() - t0) * 1e3


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bloomref", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    d = os.path.join(a.out, f"dump-compression-{a.size}")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    exe = a.bloomref
    scene = os.path.join(d, "scene.exr")
    subprocess.run([exe, "scenes", "demo", "--size", a.size, "-o", scene], check=True,
                   stdout=subprocess.DEVNULL)
    run_ms, write_ms = [], {k: [] for k in KINDS}
    check_ms = {(k, t): [] for k in KINDS for t in (1, 2)}
    sizes = {}
    for _ in range(a.repeat):
        run_ms.append(timed([exe, "run", scene, "--plan", "full", "-o", os.path.join(d, "out.exr"), "-q"]))
        for k in KINDS:
            stages = os.path.join(d, k)
            shutil.rmtree(stages, ignore_errors=True)
            write_ms[k].append(timed([exe, "run", scene, "--plan", "full", "--dump-stages", stages,
                                      "--dump-compression", k, "-o", os.path.join(d, "out.exr"), "-q"]))
            sizes[k] = sum(os.path.getsize(os.path.join(stages, f)) for f in os.listdir(stages))
            for t in (1, 2):
                check_ms[(k, t)].append(timed([exe, "check", scene, "--stages", stages, "--threads",
                                               str(t), "--json", os.path.join(d, "check.json"), "-q"]))
    med = statistics.median
    run = med(run_ms)
    print(f"{a.size} demo frame, 15 stages, medians of {a.repeat} alternated runs; "
          f"run --plan full: {run:.0f} ms")
    print("| compression | 15 dumps | run --dump-stages | check, 1 thread | check, 2 threads | check / run (2 threads) |")
    print("|---|---|---|---|---|---|")
    for k in KINDS:
        c2 = med(check_ms[(k, 2)])
        print(f"| {k} | {sizes[k] / 1e6:.0f} MB | {med(write_ms[k]):.0f} ms | "
              f"{med(check_ms[(k, 1)]):.0f} ms | {c2:.0f} ms | {c2 / run:.2f}x |")


if __name__ == "__main__":
    main()
