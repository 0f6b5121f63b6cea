"""The adaptive plan against the full plan as a user runs bloomref: one process per image.

Each case is run as `bloomref run IN --plan full|adaptive -o OUT.exr --json J -q`, a fresh
process every time, the two plans alternating (the order flipping every round, so that a change
in the machine's load falls on both); the figure is the JSON's `timings_ms.total` (the plan's
scan and every stage, reading and writing files excluded). Medians of --runs rounds, their ratio
(full / adaptive), and the outputs compared byte for byte (the plans must give the same bits).

Cases and goals (docs/performance.md, "one process per run"):
  StarField.exr (from --corpus)      a few stars on black, 1000x1000    >= 3x
  demo 3840x2160 (built-in scene)    four light cubes                   >= 3x
  noise 383x257 (built-in scene)     dense: gamma noise, 40 sources     >= 0.95x
  impulse, hot-edge, 150x150-640x480 one or two bright texels on black     >= 0.95x
  with --all-corpus, every *.exr and *.hdr of the corpus                >= 0.95x

A case whose full plan takes under 1 ms is shown but not judged on time. A case that misses its
goal is measured again (twice --runs more rounds, pooled with the first)
before it counts as missed. Prints a markdown table; writes --out/oneshot.json; exits 1 when a
goal does not hold or the plans' outputs differ, 2 when a case cannot run.

  python3 benchmarks/oneshot.py BLOOMREF [--corpus DIR] [--runs N] [--threads N] [--out DIR]
      [--all-corpus] [--only NAME,...]

--corpus defaults to BLOOMREF_CORPUS, else ../shared/data/hdr beside the repository.
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
kShortestJudgedMs = 1.0  # a case whose full plan takes less is not judged on time


def cpu_model():
    """The first processor's model name in /proc/cpuinfo (with family and model numbers)."""
    info = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if not line.strip():
                    break
                key, _, value = line.partition(":")
                info[key.strip()] = value.strip()
    except OSError:
        pass
    model = info.get("model name", "unknown CPU")
    if "cpu family" in info:
        model += f" (family {info['cpu family']}, model {info.get('model', '?')})"
    return model


def cases(corpus, all_corpus):
    """(name, run arguments, goal) for every case."""
    out = []
    star = corpus / "StarField.exr" if corpus else None
    if star and star.exists():
        out.append(("StarField.exr", [str(star)], 3.0))
    else:
        out.append(("StarField.exr", None, 3.0))  # reported as not found
    out.append(("demo 3840x2160", ["--scene", "demo", "--size", "3840x2160"], 3.0))
    out.append(("noise 383x257 (dense)", ["--scene", "noise", "--size", "383x257"], 0.95))
    for scene, size in (("impulse", "150x150"), ("hot-edge", "180x120"), ("impulse", "300x300"),
                        ("impulse", "640x480")):
        out.append((f"{scene} {size} (sparse)", ["--scene", scene, "--size", size], 0.95))
    if all_corpus and corpus:
        for f in sorted(list(corpus.glob("*.exr")) + list(corpus.glob("*.hdr"))):
            if f.name != "StarField.exr":
                out.append((f.name, [str(f)], 0.95))
    return out


def one_run(exe, args, plan, threads, work, tag):
    j, o = work / f"{tag}.{plan}.json", work / f"{tag}.{plan}.exr"
    cmd = [exe, "run", *args, "--plan", plan, "-o", str(o), "--json", str(j), "-q"]
    if threads:
        cmd += ["--threads", str(threads)]
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit(f"oneshot: {' '.join(cmd)}: exit {r.returncode}\n{r.stderr}")
    return json.loads(j.read_text())["timings_ms"]["total"], o.read_bytes(), cmd


def bench_case(exe, name, args, runs, threads, work, goal):
    """Alternated rounds of both plans; a case that misses its goal is measured again, twice as
    many rounds more, pooled with the first: two processes doing the same work (a dense scene,
    where both plans blur every pixel) differ by more than 5% under a little load."""
    tag = "".join(c if c.isalnum() else "_" for c in name)
    times = {"full": [], "adaptive": []}
    out = {}

    def rounds(n):
        for i in range(n):
            for plan in (("full", "adaptive") if i % 2 == 0 else ("adaptive", "full")):
                ms, bits, cmd = one_run(exe, args, plan, threads, work, tag)
                times[plan].append(ms)
                if plan in out and out[plan][0] != bits:
                    sys.exit(f"oneshot: {name}: two runs of the {plan} plan gave other bits")
                out[plan] = (bits, cmd)
        return statistics.median(times["full"]), statistics.median(times["adaptive"])

    full, adaptive = rounds(runs)
    remeasured = full / adaptive < goal and full >= kShortestJudgedMs
    if remeasured:
        full, adaptive = rounds(2 * runs)
    return {"name": name, "full_ms": times["full"], "adaptive_ms": times["adaptive"],
            "full_median_ms": full, "adaptive_median_ms": adaptive, "speedup": full / adaptive,
            "remeasured": remeasured, "same_bits": out["full"][0] == out["adaptive"][0],
            "command": out["adaptive"][1]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bloomref")
    ap.add_argument("--corpus", default=os.environ.get("BLOOMREF_CORPUS") or
                    str(ROOT.parent / "shared" / "data" / "hdr"))
    ap.add_argument("--runs", type=int, default=5, help="rounds (each runs both plans once)")
    ap.add_argument("--threads", type=int, default=0, help="0: the command's default (all)")
    ap.add_argument("--out", default="", help="folder for oneshot.json (default: none)")
    ap.add_argument("--all-corpus", action="store_true")
    ap.add_argument("--only", default="", help="comma-separated case names (prefixes)")
    a = ap.parse_args()
    corpus = pathlib.Path(a.corpus) if a.corpus else None
    only = [s for s in a.only.split(",") if s]
    rows, ok = [], True
    with tempfile.TemporaryDirectory() as tmp:
        for name, args, goal in cases(corpus, a.all_corpus):
            if only and not any(name.startswith(o) for o in only):
                continue
            if args is None:
                print(f"oneshot: {name} not found (set BLOOMREF_CORPUS or --corpus)",
                      file=sys.stderr)
                rows.append({"name": name, "goal": goal, "missing": True})
                ok = False
                continue
            r = bench_case(a.bloomref, name, args, a.runs, a.threads, pathlib.Path(tmp), goal)
            r["goal"] = goal
            # Under 1 ms (HDR-A-1x1.exr: 0.1 ms) tens of microseconds of scheduling are more than
            # 5%: shown, not judged on time.
            r["judged"] = r["full_median_ms"] >= kShortestJudgedMs
            r["met"] = (r["speedup"] >= goal or not r["judged"]) and r["same_bits"]
            ok = ok and r["met"]
            rows.append(r)
            print(f"oneshot: {name}: full {r['full_median_ms']:.1f} ms, adaptive "
                  f"{r['adaptive_median_ms']:.1f} ms, {r['speedup']:.2f}x", file=sys.stderr,
                  flush=True)
    print(f"One process per run, medians of {a.runs} alternated runs per plan "
          f"(`timings_ms.total`, I/O excluded; * a case that missed its goal measured again, "
          f"{3 * a.runs} runs); {cpu_model()}, {os.cpu_count()} CPUs\n")
    print("| scene | full ms | adaptive ms | speed-up | goal | same bits | met |")
    print("|---|---:|---:|---:|---:|---|---|")
    for r in rows:
        if r.get("missing"):
            print(f"| {r['name']} | - | - | - | >= {r['goal']:g}x | - | not found |")
            continue
        print(f"| {r['name']}{' *' if r['remeasured'] else ''} | {r['full_median_ms']:.1f} | "
              f"{r['adaptive_median_ms']:.1f} | {r['speedup']:.2f}x | "
              f"{'>= ' + format(r['goal'], 'g') + 'x' if r['judged'] else 'not judged (< 1 ms)'} | {'yes' if r['same_bits'] else 'NO'} | "
              f"{'yes' if r['met'] else 'NO'} |")
    if a.out:
        os.makedirs(a.out, exist_ok=True)
        with open(os.path.join(a.out, "oneshot.json"), "w") as f:
            json.dump({"runs": a.runs, "threads": a.threads, "cpu": cpu_model(), "cases": rows},
                      f, indent=2)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
