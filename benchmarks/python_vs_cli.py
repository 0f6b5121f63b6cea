"""bloomref.run from Python against the command's own in-process time.

For each built-in scene at --size (default 3840x2160: `demo`, sparse, the adaptive plan's case;
`constant`, every pixel bright), rounds alternate between
  * the command as its own process, `bloomref run SCENE.exr --repeat N+1` (--cli, default the
    build's next to the module, else the one on PATH): its JSON's per-run totals of the N warm
    runs (the first of each call is left out), and
  * N+1 calls of bloomref.run(array) on the loaded scene, in this process, each timed around the
    call (parsing the options, the run reading the array in place, wrapping the output as an
    array), the first left out as the command's is: each side's timed runs follow one run of
    its own, not the other side's, and
  * N+1 calls of bloomref.run(a, out=a), in place as the command runs, on an array the module
    made (bloomref.load), the scene copied into it before each call outside the timer, as the
    command copies its input before each of its runs;
the medians of each, their ratios to the command's and the medians of the rounds' own ratios
(each round's sides ran under the same load) are printed and written to
--out/python_vs_cli.json. Every timed Python output must have the bits of the command's output
file (exit 1 otherwise). The command runs as its own process, not through
bloomref.run_command_line, because the module changes how this process allocates large buffers
(huge pages, machinery/src/pixel_memory.cpp).

  PYTHONPATH=build/python python3 benchmarks/python_vs_cli.py [--size WxH] [--rounds R]
      [--repeat N] [--cli PATH] [--out DIR]
"""
import argparse
import json
import os
import pathlib
import shutil
import subprocess
import statistics
import sys
import tempfile
import time

import numpy as np

import bloomref


def command(cli, *args):
    r = subprocess.run([cli] + [str(a) for a in args], stdout=subprocess.DEVNULL)
    if r.returncode != 0:
        sys.exit(f"bloomref {' '.join(map(str, args))}: exit {r.returncode}")


def default_cli():
    built = pathlib.Path(bloomref.__file__).resolve().parent.parent / "cli" / "bloomref"
    return str(built) if built.is_file() else shutil.which("bloomref")


def timed_runs(n, call, expected, what, before=lambda: None):
    """n calls of call() (before() first, outside the timer), each output checked against
    `expected`'s bits; the times of all but the first, and the last output (kept alive by the
    caller until its next round, as a user's loop keeps it)."""
    ms = []
    for _ in range(n):
        before()
        t0 = time.perf_counter()
        out = call()
        ms.append((time.perf_counter() - t0) * 1e3)
        if not np.array_equal(out.view(np.uint32), expected):
            sys.exit(f"{what} gave other bits than the command's output")
    return ms[1:], out


def bench_scene(cli, name, size, rounds, repeat, work):
    scene = work / f"{name}.exr"
    command(cli, "scenes", name, "--size", size, "-o", scene)
    command(cli, "run", scene, "-o", work / f"{name}.out.exr", "-q")
    expected = bloomref.load(work / f"{name}.out.exr").view(np.uint32)
    image = bloomref.load(scene)
    work_array = bloomref.load(scene)  # the in-place runs' array, its buffer the module's
    cli_ms, py_ms, paired, inplace_ms, inplace_paired = [], [], [], [], []
    last = bloomref.run(image)  # warm-up, outside the figures

    def in_place():
        out = bloomref.run(work_array, out=work_array)
        if out is not work_array:
            sys.exit(f"{name}: bloomref.run(a, out=a) did not return a")
        return out

    for _ in range(rounds):
        command(cli, "run", scene, "--repeat", repeat + 1, "--json", work / "t.json", "-q")
        cmd = json.loads((work / "t.json").read_text())["repeat"]["total_ms"][1:]
        py, last = timed_runs(repeat + 1, lambda: bloomref.run(image), expected,
                              f"{name}: bloomref.run")
        ip, _ = timed_runs(repeat + 1, in_place, expected, f"{name}: bloomref.run(a, out=a)",
                           before=lambda: np.copyto(work_array, image))
        cli_ms += cmd
        py_ms += py
        inplace_ms += ip
        paired.append(statistics.median(py) / statistics.median(cmd))
        inplace_paired.append(statistics.median(ip) / statistics.median(cmd))
    cmd, py, ip = (statistics.median(v) for v in (cli_ms, py_ms, inplace_ms))
    return {"scene": name, "size": size, "cli_in_process_ms": cli_ms, "python_ms": py_ms,
            "python_in_place_ms": inplace_ms,
            "cli_median_ms": cmd, "python_median_ms": py, "ratio": py / cmd,
            "python_in_place_median_ms": ip, "in_place_ratio": ip / cmd,
            "cli_min_ms": min(cli_ms), "python_min_ms": min(py_ms),
            "paired_ratio_median": statistics.median(paired),
            "in_place_paired_ratio_median": statistics.median(inplace_paired),
            "same_bits": True}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="3840x2160")
    ap.add_argument("--scenes", default="demo,constant")
    ap.add_argument("--rounds", type=int, default=12)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--cli", default=None, help="the bloomref command to time against")
    ap.add_argument("--out", default=None, help="folder for python_vs_cli.json")
    a = ap.parse_args()
    cli = a.cli or default_cli()
    if not cli:
        sys.exit("no bloomref command: give --cli PATH")
    results = []
    with tempfile.TemporaryDirectory(prefix="bloomref-pybench-") as tmp:
        for name in a.scenes.split(","):
            r = bench_scene(cli, name, a.size, a.rounds, a.repeat, pathlib.Path(tmp))
            results.append(r)
            print(f"{name} {a.size}: command in-process median {r['cli_median_ms']:.1f} ms "
                  f"(min {r['cli_min_ms']:.1f}), bloomref.run median {r['python_median_ms']:.1f} "
                  f"ms (min {r['python_min_ms']:.1f}), ratio {r['ratio']:.3f}, per round "
                  f"{r['paired_ratio_median']:.3f}; in place (out=) median "
                  f"{r['python_in_place_median_ms']:.1f} ms, ratio {r['in_place_ratio']:.3f}, per "
                  f"round {r['in_place_paired_ratio_median']:.3f} ({len(r['python_ms'])} runs "
                  "each, same bits)")
    doc = {"threads": os.cpu_count(), "loadavg": os.getloadavg(), "cli": cli, "results": results}
    if a.out:
        pathlib.Path(a.out).mkdir(parents=True, exist_ok=True)
        (pathlib.Path(a.out) / "python_vs_cli.json").write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
