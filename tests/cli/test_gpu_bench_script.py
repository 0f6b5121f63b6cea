"""scripts/gpu-bench: its own parts (ldd's output, which libraries travel, the markdown report)
and both verbs end to end on this machine's GL (llvmpipe in CI): pack a built-in scene, run from
a copy of the packed folder, and run with no EGL vendor at all.
"""
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import shutil
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "..", "scripts", "gpu-bench")
EXE = os.environ.get("BLOOMREF_EXE", os.path.join(HERE, "..", "..", "build", "cli", "bloomref"))
OUTPUTS = {"gpu-bench.json", "gpu-bench.md", "gpu-bench.log", "compare-full.json",
           "bench-full.json"}


def load_script():
    loader = importlib.machinery.SourceFileLoader("gpu_bench", SCRIPT)
    spec = importlib.util.spec_from_loader("gpu_bench", loader)
    mod = importlib.util.module_from_spec(spec)
    loader.exec_module(mod)
    return mod


gb = load_script()


def test_parse_ldd_reads_found_missing_and_bare_lines():
    text = ("\tlinux-vdso.so.1 (0x00007ffd1e5f0000)\n"
            "\tlibpng16.so.16 => /lib/x86_64-linux-gnu/libpng16.so.16 (0x00007f03f5732000)\n"
            "\tlibfoo.so.3 => not found\n"
            "\t/lib64/ld-linux-x86-64.so.2 (0x00007f03f5785000)\n")
    assert gb.parse_ldd(text) == [
        ("linux-vdso.so.1", "linux-vdso.so.1"),
        ("libpng16.so.16", "/lib/x86_64-linux-gnu/libpng16.so.16"),
        ("libfoo.so.3", None),
        ("ld-linux-x86-64.so.2", "/lib64/ld-linux-x86-64.so.2"),
    ]


@pytest.mark.parametrize("soname,kind", [
    ("libc.so.6", "skip"), ("libm.so.6", "skip"), ("libdl.so.2", "skip"),
    ("libpthread.so.0", "skip"), ("librt.so.1", "skip"), ("ld-linux-x86-64.so.2", "skip"),
    ("linux-vdso.so.1", "skip"), ("libEGL.so.1", "skip"), ("libGL.so.1", "skip"),
    ("libGLX.so.0", "skip"), ("libGLdispatch.so.0", "skip"), ("libOpenGL.so.0", "skip"),
    ("libgbm.so.1", "skip"), ("libdrm.so.2", "skip"), ("libglapi.so.0", "skip"),
    ("libstdc++.so.6", "fallback"), ("libgcc_s.so.1", "fallback"),
    ("libtbb.so.12", "pack"), ("libepoxy.so.0", "pack"), ("libOpenEXR-3_1.so.30", "pack"),
    ("libz.so.1", "pack"), ("libcrypt.so.1", "pack"), ("libmd.so.0", "pack"),
])
def test_classify(soname, kind):
    assert gb.classify(soname) == kind


def synthetic_result():
    gl_row = {"size": "64x64", "pixels": 4096, "backend": "gl-fragment", "plan": "full",
              "threads": 0, "total_ms": 12.25, "blur_ms": 4.0,
              "stages_ms": {"input": 0.5, "blur.1": 2.5}, "check": "max |gl - cpu| output 1e-07",
              "check_ok": True}
    cpu_row = {"size": "64x64", "pixels": 4096, "backend": "cpu", "plan": "adaptive",
               "threads": 4, "total_ms": 3.0, "blur_ms": 1.0,
               "stages_ms": {"input": 0.25, "composite+tonemap+output": 1.5},
               "check": "DIFFERS from 1-thread full", "check_ok": False}
    stages = [{"stage": "input", "verdict": "PASS", "max_abs": 0, "max_f16_ulps": 0,
               "max_error_over_bound": 0.0, "end_to_end_verdict": "PASS",
               "end_to_end_max_error_over_bound": 0.0},
              {"stage": "blur.1", "verdict": "FAIL", "max_abs": 0.1, "max_f16_ulps": 40,
               "max_error_over_bound": 6.5, "end_to_end_verdict": "FAIL",
               "end_to_end_max_error_over_bound": 6.5}]
    return {
        "machine": {"os": "TestOS", "cpu_model": "TestCPU", "cpus": 4, "memory_gib": 8},
        "gl": {"renderer": "llvmpipe (LLVM 15)", "version": "4.5", "gpu": False,
               "note": "renderer is llvmpipe: not a GPU"},
        "environment": {"loaders": "the machine's own"},
        "pack": {"commit": "0123456789abcdef", "build_type": "Release"},
        "elapsed_s": 9.0, "budget_s": 300,
        "steps": [
            {"name": "bench f32 64x64", "kind": "bench", "status": "failed", "rc": 1,
             "storage": "f32", "repeat": 5, "threads_available": 4, "rows": [gl_row, cpu_row]},
            {"name": "compare demo@64x64", "kind": "compare", "status": "failed", "rc": 1,
             "image": "demo@64x64", "width": 64, "height": 64, "method": "gaussian",
             "storage": "f32", "shaders": "fragment", "profile_asked": "auto",
             "profile_used": "llvmpipe", "verdict": "FAIL", "first_divergent_stage": "blur.1",
             "timings_ms": {"total": 20.0}, "stages": stages},
        ],
    }


def test_markdown_tables_escape_pipes_and_list_failures():
    md = gb.markdown(synthetic_result())
    assert "- **renderer is llvmpipe: not a GPU**" in md
    assert "\n  - `bench f32 64x64`: failed, exit 1" in md
    assert "\n  - `compare demo@64x64`: failed, exit 1 (FAIL)" in md
    # The check text's '|' is escaped, so the row keeps its 8 cells.
    assert ("| 64x64 | f32 | gl-fragment | full |  | 12.2 | 4.00 | "
            "max \\|gl - cpu\\| output 1e-07 |") in md
    assert "| 64x64 | f32 | cpu | adaptive | 4 | 3.00 | 1.00 | **FAIL** DIFFERS" in md
    # Per stage: GL's time beside the compare's err/bound for the same frame, CPU's beside.
    assert "| blur.1 | 2.50 | 6.5 |  |" in md
    assert "| input | 0.500 | 0 | 0.250 |" in md
    assert "| composite+tonemap+output |  |  | 1.50 |" in md
    assert ("| demo@64x64 | 64x64 | gaussian | f32 | fragment | auto=llvmpipe | FAIL | blur.1 "
            "| blur.1 6.5 | 20.0 | 1 |") in md
    assert "blur.1 6.5 **FAIL**" in md
    brief = gb.markdown(synthetic_result(), brief=True)
    assert "0 of 1 compares PASS; the others:" in brief
    assert "### 64x64 f32: per stage" not in brief


def test_markdown_checks_show_expectations_and_check_against_run():
    res = synthetic_result()
    stages = [{"stage": "input", "max_error_over_bound": "inf"},
              {"stage": "blur.1", "max_error_over_bound": 2.5}]
    res["steps"] += [
        {"name": "c1", "kind": "check", "status": "ok", "rc": 1, "image": "a.exr",
         "storage": "f32", "source": "own GL stages read bottom-up", "expect": "FAIL",
         "expect_stage": "input", "as_expected": True, "verdict": "FAIL",
         "first_divergent_stage": "input", "cause": "images flipped vertically",
         "cause_within": 1.0, "stages": stages},
        {"name": "c2", "kind": "check", "status": "failed", "rc": 0, "image": "a.exr",
         "storage": "f16", "source": "LearnOpenGL, gamma 2.0", "expect": "FAIL",
         "expect_stage": "output", "as_expected": False, "verdict": "PASS", "stages": stages[1:]}]
    res["check_vs_run"] = [{"size": "64x32", "runs": 3, "run_ms": 10.0, "check_ms": 25.0,
                            "ratio": 2.5, "check_peak_rss_bytes": 50e6, "verdict": "PASS"}]
    md = gb.markdown(res)
    assert ("| a.exr | f32 | own GL stages read bottom-up | FAIL | FAIL at input | input | "
            "images flipped vertically (1 within) | input inf | 1 |") in md
    assert ("| a.exr | f16 | LearnOpenGL, gamma 2.0 | PASS | **FAIL at output: no** |  |  | "
            "blur.1 2.5 | 0 |") in md
    assert "25.0 ms against run --plan full 10.0 ms = **2.50x**" in md
    assert "peak RSS 50 MB" in md
    brief = gb.markdown(res, brief=True)
    assert "1 of 2 checks as expected; the others:" in brief
    assert "own GL stages read bottom-up" not in brief and "gamma 2.0" in brief


needs_exe = pytest.mark.skipif(not os.path.isfile(EXE), reason=f"{EXE} not built")


def run_script(args, env=None, timeout=300):
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True,
                          env=env, timeout=timeout)


@needs_exe
def test_pack_then_run_from_a_copy(tmp_path):
    # The demo scene: not the same flipped, nor with R and B swapped.
    scene = tmp_path / "demo.exr"
    subprocess.run([EXE, "scenes", "demo", "--size", "64x48", "-o", str(scene)], check=True)
    build = tmp_path / "build" / "cli"
    build.mkdir(parents=True)
    os.symlink(os.path.abspath(EXE), build / "bloomref")
    packed = tmp_path / "packed"
    lo = os.environ.get("BLOOMREF_LEARNOPENGL_DIR")
    lo = lo if lo and all(os.path.isfile(os.path.join(lo, f)) for f in gb.LO_FILES) else None
    r = run_script(["pack", str(packed), "--build", str(tmp_path / "build"), "--images",
                    str(scene), "--no-debs"] + (["--learnopengl", lo] if lo else []))
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(packed / "learnopengl")) == sorted(gb.LO_FILES) if lo else \
        not (packed / "learnopengl").exists()
    assert '"carry": [' in r.stdout
    manifest = json.loads((packed / "manifest.json").read_text())
    assert [i["name"] for i in manifest["images"]] == ["demo.exr"]
    assert manifest["images"][0]["sha256"] == hashlib.sha256(scene.read_bytes()).hexdigest()
    for f in os.listdir(packed / "lib"):
        if f != "fallback":
            assert gb.classify(f) == "pack", f
    assert not any(n.startswith(("libc.so", "libEGL", "libGL", "ld-linux"))
                   for n in os.listdir(packed / "lib"))

    copy = tmp_path / "copy"
    shutil.copytree(packed, copy)
    env = {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"}
    out = tmp_path / "out"
    r = run_script(["run", str(copy), "--out", str(out), "--sizes", "32x32", "--repeat", "1",
                    "--check-size", "48x32", "--probe-size", "64x48", "--budget", "300"], env=env)
    assert set(os.listdir(out)) == OUTPUTS
    res = json.loads((out / "gpu-bench.json").read_text())
    assert res["environment"]["LD_LIBRARY_PATH"].split(":")[0] == str(copy / "lib")
    assert res["environment"]["packed_libs_resolved_elsewhere"] == []
    names = [s["name"] for s in res["steps"]]
    assert names[0] == "gl-info"
    assert "bench f32 32x32" in names and "bench f16 32x32" in names
    assert all("rc" in s and s["status"] in ("ok", "failed", "timeout", "skipped")
               for s in res["steps"])
    if res["steps"][0]["rc"] != 0:
        pytest.skip("no GL here: " + res["gl"]["note"])
    compares = [s for s in res["steps"] if s["kind"] == "compare" and s["shaders"] != "vulkan"]
    # One image and the scene at one size: f32 and f16, fragment and compute (8), mip on the
    # image (2), and the nvidia profile on the fragment ones wherever auto chose another.
    others = sum(1 for s in compares if s["profile_asked"] == "auto" and s["shaders"] ==
                 "fragment" and s["method"] == "gaussian" and s["profile_used"] != "nvidia")
    assert len(compares) == 10 + others
    # check: the own GL stages pass in f32 and f16; read bottom-up or as BGRA they fail at
    # input, and the cause is named; the tutorial's broken copies fail at their stage.
    checks = {s["source"] + " " + s["storage"]: s for s in res["steps"] if s["kind"] == "check"}
    for storage in ("f32", "f16"):
        assert checks[f"own GL stages {storage}"]["verdict"] == "PASS"
    assert checks["own GL stages read bottom-up f32"]["cause_id"] == "flipped-vertically"
    assert checks["own GL stages read as BGRA f32"]["cause_id"] == "rb-swapped"
    for what, (_, _, _, stage) in gb.LO_BROKEN.items() if lo else ():
        c = checks[f"LearnOpenGL, {what} f32"]
        assert (c["verdict"], c["first_divergent_stage"], c["status"]) == ("FAIL", stage, "ok")
    assert len(checks) == 4 + (2 + len(gb.LO_BROKEN) if lo else 0)
    # Vulkan: the device, the pass probe (one pass per API, each checked against the CPU's),
    # and compares of the image (f32 and f16 gaussian and mip) and three presets' chains.
    vk = [s for s in res["steps"] if s["kind"] == "compare" and s["shaders"] == "vulkan"]
    if res["vulkan"].get("device"):
        assert "vulkan-info" in names
        probe = [s for s in res["steps"] if s["kind"] == "probe"][0]
        rows = {r["api"]: r for r in probe["probes"][0]["rows"]}
        assert set(rows) == {"gl-fragment", "gl-compute", "vulkan"}
        assert all(r["checked"] for r in rows.values())
        assert probe["probes"][0]["bytes_per_pass"] == 2 * 16 * 64 * 48  # RGBA32F read + write
        assert len(vk) == 7 and all(c["verdict"] == "PASS" for c in vk), [
            (c["name"], c.get("verdict")) for c in vk]
        assert sorted(c["method"] for c in vk if "--preset" in c["method"]) == [
            "mip --preset bevy", "mip --preset learnopengl-pbb", "mip --preset unity-urp"]
        md = (out / "gpu-bench.md").read_text()
        assert "## Where the time goes" in md and "| 64x48 | f32 | vulkan |" in md
    cvr = res["check_vs_run"][0]
    assert (cvr["size"], cvr["verdict"], cvr["runs"]) == ("48x32", "PASS", 1)
    assert cvr["ratio"] == pytest.approx(cvr["check_ms"] / cvr["run_ms"], rel=0.01)
    assert r.returncode == (0 if all(s["status"] == "ok" for s in res["steps"]) else 1)
    if "llvmpipe" in res["gl"]["renderer"]:
        assert res["gl"]["note"] == "renderer is llvmpipe: not a GPU"
        assert "**renderer is llvmpipe: not a GPU**" in (out / "gpu-bench.md").read_text()


@needs_exe
def test_run_without_egl_records_it_and_still_benches_the_cpu(tmp_path):
    build = tmp_path / "build" / "cli"
    build.mkdir(parents=True)
    os.symlink(os.path.abspath(EXE), build / "bloomref")
    scene = tmp_path / "impulse.exr"
    subprocess.run([EXE, "scenes", "impulse", "-o", str(scene)], check=True)
    packed = tmp_path / "packed"
    assert run_script(["pack", str(packed), "--build", str(tmp_path / "build"), "--images",
                       str(scene), "--no-debs"]).returncode == 0
    env = dict(os.environ, __EGL_VENDOR_LIBRARY_FILENAMES=str(tmp_path / "none.json"))
    env.pop("LD_LIBRARY_PATH", None)
    out = tmp_path / "out"
    r = run_script(["run", str(packed), "--out", str(out), "--sizes", "32x32", "--repeat", "1",
                    "--check-size", "48x32", "--probe-size", "64x48", "--expect-gpu"], env=env)
    assert r.returncode == 3
    res = json.loads((out / "gpu-bench.json").read_text())
    assert res["steps"][0]["name"] == "gl-info" and res["steps"][0]["rc"] == 3
    assert res["gl"]["note"].startswith("GL unavailable (gl-info exit 3)")
    # check against run needs no GL: the CPU's run and check of one frame, timed. Vulkan needs
    # no EGL: its device, the probe (the Vulkan pass alone) and its compares run.
    vulkan = ["vulkan-info", "probe"] + ["compare"] * 7 if res["vulkan"].get("device") else \
        ["vulkan-info"]
    assert [s["kind"] for s in res["steps"]] == ["gl-info", "bench", *vulkan, "prep", "timed",
                                                 "timed", "bench"]
    assert res["check_vs_run"][0]["verdict"] == "PASS"
    assert all(s["rc"] == 0 for s in res["steps"][1:])
    assert "GL unavailable (gl-info exit 3)" in (out / "gpu-bench.md").read_text()


def test_perf_report_summarises_a_gpu_bench_report(tmp_path):
    """scripts/perf-report's "On a GPU" section reads the report gpu-bench writes."""
    loader = importlib.machinery.SourceFileLoader(
        "perf_report", os.path.join(HERE, "..", "..", "scripts", "perf-report"))
    spec = importlib.util.spec_from_loader("perf_report", loader)
    pr = importlib.util.module_from_spec(spec)
    loader.exec_module(pr)
    res = synthetic_result()
    check = {"kind": "check", "rc": 0, "image": "a.exr", "storage": "f32", "stages": [],
             "first_divergent_stage": None}
    res["steps"] += [
        dict(check, name="c1", status="ok", source="own GL stages", expect="PASS",
             as_expected=True, verdict="PASS"),
        dict(check, name="c2", status="failed", source="LearnOpenGL, gamma 2.0", expect="FAIL",
             expect_stage="output", as_expected=False, verdict="PASS"),
        dict(check, name="c3", status="failed", rc=1, source="LearnOpenGL shaders",
             verdict="FAIL", first_divergent_stage="output")]
    res["check_vs_run"] = [{"size": "64x32", "runs": 3, "run_ms": 10.0, "check_ms": 25.0,
                            "ratio": 2.5, "check_peak_rss_bytes": 50e6, "verdict": "PASS"}]
    (tmp_path / "docs" / "gpu").mkdir(parents=True)
    (tmp_path / "docs" / "gpu" / "x.md").write_text(gb.markdown(res))
    pr.ROOT = str(tmp_path)
    text = "\n".join(pr.gpu_section())
    assert "- machine: TestOS, TestCPU, 4 CPUs, 8 GiB" in text
    assert "- GL: llvmpipe (LLVM 15) 4.5" in text
    assert ("- checks with an expected verdict: 1 of 2 as expected; not: a.exr f32 "
            "LearnOpenGL, gamma 2.0 (PASS, first divergent )") in text
    assert "values): 1 FAIL\n" in text
    assert "- compares: 1 FAIL\n" in text
    assert "= **2.50x**" in text
