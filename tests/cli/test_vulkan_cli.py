"""bloomref vulkan-info: the Vulkan device, its reported limits, and the facts a compute probe
measures on it (vulkan/src/device_facts.cpp).

Skips without a Vulkan device (exit 3) unless BLOOMREF_REQUIRE_VULKAN=1 (CI: lavapipe is always
installable). On Mesa's software devices the facts are checked against an independent
measurement: gl-info's GL probe on llvmpipe, which shares the Vulkan driver's sampler and
store code (gallivm), must find the same store rounding and filter precision.
"""
import json
import os
import shutil
from pathlib import Path
import subprocess

import pytest

from cli_support import EXE, first_cause, run

ROOT = Path(__file__).resolve().parents[2]
PIPELINES = ROOT / "data" / "pipelines"


def vulkan_or_skip(code, err):
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())


@pytest.fixture(scope="module")
def info(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("vulkan")
    code, out, err = run(["vulkan-info", "--json", "v.json"], tmp)
    vulkan_or_skip(code, err)
    assert code == 0, err
    j = json.loads((tmp / "v.json").read_text())
    assert json.loads(out) == j  # the console and the file say the same
    return j


def test_reports_the_limits_the_precision_model_needs(info):
    r = info["reported"]
    assert info["api"] == "vulkan" and info["device"] and info["api_version"].count(".") == 2
    # Vulkan 1.x requires at least 4 sub-texel bits and 4 mipmap bits (the spec's limit table).
    assert r["sub_texel_precision_bits"] >= 4 and r["mipmap_precision_bits"] >= 4
    assert r["max_workgroup_invocations"] >= 128 and min(r["max_workgroup_size"]) >= 64
    assert r["timestamp_period_ns"] > 0
    assert set(r["float_controls"]) >= {"denorm_behavior_independence", "rounding_rte_f32"}


def test_measured_facts_are_consistent(info):
    m = info["measured"]
    assert m["half_rounding"] in ("nearest-even", "toward-zero", "other")
    distinct, bits = m["bilinear_distinct_of_1024"], m["subtexel_bits"]
    assert 2 <= distinct <= 1024
    if bits:  # b-bit fixed-point weights give 2^b or 2^b + 1 values across one span
        assert distinct in (1 << bits, (1 << bits) + 1)
    else:
        assert distinct >= 1000
    # A toward-zero store saturates 65520 to the largest half; a nearest one does not go below it.
    if m["half_rounding"] == "toward-zero":
        assert m["half_of_65520"] == 65504.0


def test_a_device_that_is_not_there_exits_3(tmp_path):
    """BLOOMREF_VULKAN_DEVICE names a device no machine has: exit 3, the variable named."""
    p = subprocess.run([EXE, "vulkan-info"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, env={**os.environ, "BLOOMREF_VULKAN_DEVICE": "no-such-device-42"})
    assert p.returncode == 3, p.stderr
    assert "BLOOMREF_VULKAN_DEVICE" in p.stderr and "no-such-device-42" in p.stderr, p.stderr


def test_lavapipe_agrees_with_llvmpipe_gl(info, tmp_path):
    """Mesa's two software drivers share the sampler and store code: the Vulkan probe must find
    what the GL probe finds (store rounding, saturation, weight precision, FMA)."""
    if "llvmpipe" not in info["device"]:
        pytest.skip("not Mesa's software Vulkan device: " + info["device"])
    code, _, err = run(["gl-info", "--json", "g.json"], tmp_path)
    if code == 3:
        pytest.skip("no GL to compare with: " + err.strip())
    gl = json.loads((tmp_path / "g.json").read_text())
    if "llvmpipe" not in gl["renderer"]:
        pytest.skip("GL is not llvmpipe: " + gl["renderer"])
    m = info["measured"]
    for key in ("half_rounding", "half_of_65520", "half_of_70000", "half_denormals_kept",
                "f32_denormals_kept", "bilinear_distinct_of_1024", "subtexel_bits",
                "fma_contracted"):
        assert m[key] == gl[key], (key, m[key], gl[key])


CORPUS = os.environ.get("BLOOMREF_CORPUS", "")
SIZE = "203x131"


def compare(tmp_path, *args):
    code, out, err = run(["compare", "--backend", "vulkan", "--json", "c.json", *args], tmp_path,
                         timeout=600)
    vulkan_or_skip(code, err)
    j = json.loads((tmp_path / "c.json").read_text()) if (tmp_path / "c.json").exists() else None
    return code, out, err, j


@pytest.mark.parametrize("options", [["--method", "gaussian"],
                                     ["--method", "gaussian", "--storage", "f16", "--kernel", "linear5"],
                                     ["--method", "mip", "--karis", "--storage", "f16"],
                                     ["--method", "mip", "--composite", "after-tonemap"]],
                         ids=["gaussian-f32", "gaussian-f16-linear5", "mip-karis-f16", "mip-after"])
def test_compare_on_vulkan_passes_every_stage(tmp_path, options):
    code, out, err, j = compare(tmp_path, "--scene", "demo", "--size", SIZE, *options)
    assert code == 0 and "verdict PASS" in out, out + err
    assert j["renderer"].startswith("vulkan (compute")
    stages = {s["stage"]: s for s in j["stages"]}
    assert {"input", "composite", "tonemap", "output"} <= set(stages)
    assert all(s["isolated"]["verdict"] == "PASS" and s["end_to_end"]["verdict"] == "PASS"
               for s in stages.values())
    # The images are the device's own: somewhere they differ from the oracle's by its rounding.
    assert max(s["isolated"]["max_abs"] for s in stages.values()) > 0


# Each fault bloomref injects (by editing its shaders, or through the host), and the stage where
# it enters (gpu/src/faults.cpp). Exposure 0.5: at exposure 1 an ignored exposure changes nothing.
FAULTS = [
    ("weight-1pct", "gaussian", "blur.1"), ("weight-0.01pct", "gaussian", "blur.1"),
    ("half-texel-shift", "gaussian", "blur.1"), ("vertical-offsets-x", "gaussian", "blur.2"),
    ("threshold-ge", "gaussian", "bright"), ("gamma-twice", "gaussian", "output"),
    ("swap-rb", "gaussian", "composite"), ("exposure-ignored", "gaussian", "tonemap"),
    ("tap-offset", "mip", "down.1"), ("karis-unnormalised", "mip", "down.1"),
    # injected by the host, as the GL host injects them
    ("repeat-wrap", "gaussian", "blur.1"), ("skip-pass", "gaussian", "blur.3"),
    ("f16-storage", "gaussian", "input"), ("level-size", "mip", "down.2"),
    ("mip-level-offset", "mip", "up.2"),
]


@pytest.mark.parametrize("fault,method,stage", FAULTS, ids=[f[0] for f in FAULTS])
def test_an_injected_fault_fails_on_vulkan_where_it_enters(tmp_path, fault, method, stage):
    extra = ["--karis"] if method == "mip" else []
    code, out, err, j = compare(tmp_path, "--scene", "demo", "--size", SIZE, "--method", method,
                                "--exposure", "0.5", "--inject-fault", fault, *extra)
    assert code == 1, out + err
    assert j["verdict"] == "FAIL" and j["first_divergent_stage"] == stage, (
        j["first_divergent_stage"], stage)


# The stages each preset's host reads back at 203x131, counted from its layout (docs/presets.md):
# the article's 6 levels with its bright image; Bevy's 8 levels and the composite it blends into
# the view; URP's floor(log2(max(203 >> 1, 131 >> 1))) - 1 = floor(log2(101)) - 1 = 5 levels.
def chain(n, bright=False, composite=True):
    names = ["input"] + (["bright"] if bright else [])
    names += ["down.%d" % k for k in range(1, n + 1)] + ["up.%d" % k for k in range(n - 1, 0, -1)]
    return names + (["composite"] if composite else []) + ["output"]


PRESETS = [
    (["--preset", "learnopengl-pbb"], chain(6, bright=True, composite=False)),
    (["--preset", "learnopengl-pbb", "--chain-storage", "f16"], chain(6, bright=True, composite=False)),
    (["--preset", "bevy"], chain(8)),
    (["--preset", "bevy", "--storage", "f32", "--chain-storage", "f32"], chain(8)),
    (["--preset", "bevy-old-school"], chain(8)),
    (["--preset", "unity-urp"], chain(5)),
    (["--preset", "unity-urp", "--chain-storage", "f16", "--storage", "f16"], chain(5)),
]


@pytest.mark.parametrize("options,stages", PRESETS, ids=[" ".join(p[0][1:]) for p in PRESETS])
def test_every_preset_passes_compare_on_vulkan(tmp_path, options, stages):
    """The presets' chains run on Vulkan as their hosts' passes, each a compute shader; every
    stage the host reads back is judged and passes."""
    code, out, err, j = compare(tmp_path, "--scene", "demo", "--size", SIZE, *options)
    assert code == 0 and "verdict PASS" in out, out + err
    assert "preset's passes as compute shaders" in j["renderer"]
    assert [s["stage"] for s in j["stages"]] == stages
    assert all(s["isolated"]["verdict"] == "PASS" for s in j["stages"])
    # The device's own images: somewhere they differ from the oracle's by its rounding.
    assert max(s["isolated"]["max_abs"] for s in j["stages"]) > 0


def test_a_fault_in_a_presets_chain_is_refused(tmp_path):
    code, _, err = run(["compare", "--backend", "vulkan", "--size", "16x16", "--preset",
                        "unity-urp", "--inject-fault", "tap-offset"], tmp_path)
    vulkan_or_skip(code, err)
    assert code == 2 and "preset's passes" in err, err


def test_run_on_vulkan_with_a_preset_dumps_stages_that_check_passes(tmp_path):
    code, _, err = run(["run", "--backend", "vulkan", "--size", SIZE, "--preset", "bevy", "-q",
                        "-o", "v.exr", "--dump-stages", "v"], tmp_path)
    vulkan_or_skip(code, err)
    assert code == 0, err
    assert sorted(p.stem for p in (tmp_path / "v").iterdir()) == sorted(chain(8))
    code, _, err = run(["check", "--scene", "demo", "--size", SIZE, "--preset", "bevy",
                        "--stages", "v", "--json", "c.json", "-q"], tmp_path)
    assert code == 0, err
    assert json.loads((tmp_path / "c.json").read_text())["verdict"] == "PASS"


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
@pytest.mark.parametrize("image,options", [("GoldenGate.exr", []),
                                           ("WideFloatRange.exr", ["--method", "mip", "--storage", "f16"]),
                                           ("CandleGlass.exr", ["--preset", "learnopengl-pbb"]),
                                           ("StageEnvLatLong.exr", ["--preset", "bevy"]),
                                           ("WideColorGamut.exr", ["--preset", "unity-urp"]),
                                           # up.1 beyond R11G11B10's range: saturated
                                           ("AllHalfValues.exr", ["--preset", "bevy-old-school"])])
def test_compare_on_vulkan_on_the_corpus(tmp_path, image, options):
    code, out, err, _ = compare(tmp_path, os.path.join(CORPUS, image), *options)
    assert code == 0 and "verdict PASS" in out, out + err


def test_run_on_vulkan_dumps_stages_that_check_passes(tmp_path):
    """run --backend vulkan writes the device's stages; check judges them as any capture."""
    code, _, err = run(["run", "--backend", "vulkan", "--size", SIZE, "--method", "mip", "-q",
                        "-o", "v.exr", "--dump-stages", "v", "--json", "r.json"], tmp_path)
    vulkan_or_skip(code, err)
    assert code == 0, err
    assert json.loads((tmp_path / "r.json").read_text())["renderer"].startswith("vulkan")
    code, _, err = run(["check", "--scene", "demo", "--size", SIZE, "--method", "mip",
                        "--stages", "v", "--json", "c.json", "-q"], tmp_path)
    assert code == 0, err
    assert json.loads((tmp_path / "c.json").read_text())["verdict"] == "PASS"


def test_bench_times_vulkan_and_gl_on_the_device_and_checks_them(tmp_path):
    """bench's GPU rows: wall time and the device's time from timer queries apart, per stage and
    in total; the device's total is within the wall time of the same runs (it excludes the
    drains and readbacks), and every row's output is checked."""
    code, out, err = run(["bench", "--sizes", "96x64", "--repeat", "1", "--out", "b"], tmp_path,
                         timeout=600)
    assert code == 0, out + err
    j = json.loads((tmp_path / "b" / "bench.json").read_text())
    rows = {r["backend"]: r for r in j["rows"] if r["backend"] != "cpu"}
    if "vulkan" not in rows:
        vulkan_or_skip(3, j["vulkan_device"])
    for backend, r in rows.items():
        assert r["check_ok"], (backend, r["check"])
        if r["device_total_ms"] is None:  # a timer that did not time every stage times none
            assert backend == "gl-compute" and r["device_stages_ms"] == {}, (backend, r)
            continue
        assert 0 < r["device_total_ms"] <= r["total_ms"] * 1.05 + 0.5, (backend, r)
        # A time for every stage that ran (the GL trace also times the plan's scan, on the CPU,
        # and its bright stage is the input's draw).
        assert set(r["device_stages_ms"]) == set(r["stages_ms"]) - {"plan", "bright"}, backend
    # The Vulkan device's timestamps and GL's fragment-pass timer time every stage.
    assert rows["vulkan"]["device_total_ms"] is not None
    if "gl-fragment" in rows:
        assert rows["gl-fragment"]["device_total_ms"] is not None
    assert "device ms" in out


def test_compare_on_vulkan_writes_the_report_of_the_failing_stage(tmp_path):
    """--report on Vulkan: the page, and the failing stage's images as the device wrote them
    beside the oracle's (an injected 1% weight error at blur.1)."""
    import numpy as np
    import OpenImageIO as oiio

    code, out, err, j = compare(tmp_path, "--scene", "demo", "--size", SIZE, "--method", "gaussian",
                                "--inject-fault", "weight-1pct", "--report", "rep")
    assert code == 1 and j["first_divergent_stage"] == "blur.1", out + err
    rep = tmp_path / "rep"
    page = (rep / "index.html").read_text()
    assert "blur.1" in page and "<th>device</th>" in page
    device = oiio.ImageBuf(str(rep / "blur.1.device.exr")).get_pixels(oiio.FLOAT)
    oracle = oiio.ImageBuf(str(rep / "blur.1.oracle.exr")).get_pixels(oiio.FLOAT)
    assert device.shape == oracle.shape == (131, 203, 4)
    # Weights summing to 1.01 (one tap 1% heavier): the device's image is brighter than the oracle's.
    assert device[..., :3].sum() > oracle[..., :3].sum()
    assert (rep / "blur.1.device.png").exists() and (rep / "blur.1.mask.png").exists()


def test_compare_on_lavapipe_takes_the_profile_vulkan_info_measures(info, tmp_path):
    """--profile auto on Mesa's software device is `lavapipe`, and each of its fields is what the
    device's probe measured (or allows more: FMA is allowed though not observed)."""
    if info["type"] != "cpu":
        pytest.skip("not a software Vulkan device: " + info["device"])
    code, out, err, j = compare(tmp_path, "--scene", "demo", "--size", "64x64")
    assert code == 0, out + err
    p, m = j["profile"], info["measured"]
    assert p["name"] == "lavapipe"
    assert p["subtexel_bits"] == m["subtexel_bits"]
    assert p["half_toward_zero"] == (m["half_rounding"] == "toward-zero")
    assert p["half_nearest_even"] == (m["half_rounding"] == "nearest-even")
    assert p["half_overflow_saturate"] == (m["half_of_70000"] == 65504.0)
    assert p["flush_denormals"] == (not m["shader_denormals_kept"])
    assert p["fma"] or not m["fma_contracted"]


# check --shaders pipeline --backend vulkan: a description's fragment passes as compute shaders.
SEED002 = ["--preset", "cod-mip", "--composite", "after-tonemap", "--exposure", "0.5",
           "--strength", "0.02"]


def described(tmp_path, size, description, *options):
    code, out, err = run(["check", "--scene", "demo", "--size", size, *options, "--shaders",
                          "pipeline", "--pipeline", str(description), "--backend", "vulkan",
                          "--json", "c.json", "-q"], tmp_path, timeout=600)
    vulkan_or_skip(code, err)
    assert code in (0, 1), err
    return json.loads((tmp_path / "c.json").read_text())["items"][0]


def copied(tmp_path, name, edit=None, shader=None, find=None, replace=None):
    """A copy of data/pipelines/NAME.json (its shaders' paths made absolute), its JSON changed by
    `edit` and, with `shader`, that shader copied and one text replaced."""
    d = json.loads((PIPELINES / (name + ".json")).read_text())
    for prog in d["programs"].values():
        prog["fragment"] = str((PIPELINES / prog["fragment"]).resolve())
    if shader:
        src = Path(d["programs"][shader]["fragment"])
        text = src.read_text()
        assert find in text
        (tmp_path / src.name).write_text(text.replace(find, replace))
        d["programs"][shader]["fragment"] = str(tmp_path / src.name)
    if edit:
        edit(d)
    f = tmp_path / "described.json"
    f.write_text(json.dumps(d))
    return f


def test_descriptions_pass_on_vulkan(tmp_path):
    """Seed 002's one-program layout (its samplers left to the units GL would give them) and the
    article's and Bevy's hosts, as descriptions, pass on Vulkan."""
    item = described(tmp_path, "256x192", PIPELINES / "seed-002.json", *SEED002)
    assert item["verdict"] == "PASS", item
    for name, preset, n in [("learnopengl-pbb", "learnopengl-pbb", 12), ("bevy", "bevy", 17)]:
        item = described(tmp_path, SIZE, PIPELINES / (name + ".json"), "--preset", preset)
        assert item["verdict"] == "PASS" and len(item["stages"]) == n, (name, item["verdict"])


@pytest.mark.parametrize("name,preset,edit,shader,find,replace,stage,causes", [
    # Seed 002's tent weights summing to 2: the upsample's gain
    ("seed-002", SEED002, None, "bloom", "/ 16.0", "/ 8.0", "up.5", {"upsample-gain"}),
    # Seed 002 with no threshold on the first level
    ("seed-002", SEED002, None, "bloom", "< 1.0) c = vec3(0.0)", "< -1.0) c = vec3(0.0)",
     "down.1", {"none", "threshold-other"}),
    # Bevy's deepest upsample blended with 0.8 where compute_blend_factor gives 0.745
    ("bevy", ["--preset", "bevy"],
     lambda d: d["passes"][2]["blend"].update(constant=0.8),
     None, None, None, "up.7", {"level-blend-constant"}),
    # The article's upsample drawn over a cleared level: GL's (ONE, ONE) blend loses the level
    ("learnopengl-pbb", ["--preset", "learnopengl-pbb"],
     lambda d: d["passes"][2]["passes"][0].update(clear=True), None, None, None, "up.5", None),
    # The article's downsample reading each tap one texel to the right
    ("learnopengl-pbb", ["--preset", "learnopengl-pbb"], None, "down",
     "texCoord + steps / srcResolution", "texCoord + (steps + vec2(1.0, 0.0)) / srcResolution",
     "down.1", None),
], ids=["seed-tent-gain", "seed-no-threshold", "bevy-blend-constant", "pbb-cleared-level",
        "pbb-shifted-downsample"])
def test_broken_descriptions_fail_on_vulkan_where_broken(tmp_path, name, preset, edit, shader,
                                                         find, replace, stage, causes):
    size = "256x192" if name == "seed-002" else SIZE
    f = copied(tmp_path, name, edit, shader, find, replace)
    item = described(tmp_path, size, f, *preset)
    assert item["verdict"] == "FAIL"
    first, named, _ = first_cause(item)
    assert first == stage, (first, stage)
    if causes:
        assert named in causes, named


def test_what_vulkan_cannot_run_is_refused_naming_the_file(tmp_path):
    # A program with its own vertex shader: a compute pass has none.
    f = copied(tmp_path, "seed-002",
               lambda d: d["programs"]["bloom"].update(vertex=d["programs"]["bloom"]["fragment"]))
    code, _, err = run(["check", "--scene", "demo", "--size", "64x48", *SEED002, "--shaders",
                        "pipeline", "--pipeline", str(f), "--backend", "vulkan"], tmp_path)
    vulkan_or_skip(code, err)
    assert code == 2 and "vertex shader" in err and str(f) in err, err
    # A shader that does not compile: its file and the compiler's message.
    f = copied(tmp_path, "seed-002", None, "bloom", "/ 16.0", "/ sixteen")
    code, _, err = run(["check", "--scene", "demo", "--size", "64x48", *SEED002, "--shaders",
                        "pipeline", "--pipeline", str(f), "--backend", "vulkan"], tmp_path)
    assert code == 2 and "bloom.frag" in err and "sixteen" in err, err
    # --backend vulkan without a description
    code, _, err = run(["check", "--scene", "demo", "--size", "64x48", "--backend", "vulkan",
                        "--stages", "."], tmp_path)
    assert code == 2 and "--shaders pipeline" in err, err


def test_the_pass_probe_times_one_pass_per_api_and_checks_it(tmp_path):
    """bench --pass-probe: blur.1 of a one-pass plan as a GL fragment pass, a GL compute pass and
    a Vulkan dispatch; device times only where plausible (llvmpipe's GL timer does not time
    compute dispatches), every pass checked against the CPU's."""
    code, out, err = run(["bench", "--pass-probe", "--sizes", "96x64", "--repeat", "3", "--out",
                          "p"], tmp_path, timeout=600)
    assert code == 0, out + err
    j = json.loads((tmp_path / "p" / "pass-probe.json").read_text())
    if not j["probes"][0]["vulkan_device"]:
        vulkan_or_skip(3, j["vulkan_device"])
    p = j["probes"][0]
    assert p["size"] == "96x64" and p["bytes_per_pass"] == 2 * 16 * 96 * 64
    rows = {r["api"]: r for r in p["rows"]}
    assert "vulkan" in rows and all(r["checked"] for r in rows.values())
    for r in rows.values():
        if r["device_ms"] is not None:
            assert 0.01 * r["wall_ms"] <= r["device_ms"] <= 1.05 * r["wall_ms"]
            assert r["device_gb_per_s"] == pytest.approx(p["bytes_per_pass"] / r["device_ms"] / 1e6)
    assert rows["vulkan"]["device_ms"] is not None  # lavapipe's timestamps time the dispatch
    assert "pass probe: one 9-tap pass (blur.1) at 96x64" in out


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
def test_the_articles_floor_on_negative_colour(tmp_path):
    """WideColorGamut.exr has negative channels: the article's Karis weight takes pow of a
    negative (NaN) and its max(., 0.0001) gives 0.0001 on the devices (maxNum), which the oracle
    models. Its chain passes on GL and Vulkan; a copy without the floor, leaving the NaN, fails
    at down.1 on both."""
    scene = os.path.join(CORPUS, "WideColorGamut.exr")
    for backend in ("gl", "vulkan"):
        code, out, err = run(["compare", scene, "--preset", "learnopengl-pbb", "--backend",
                              backend, "-q"], tmp_path, timeout=600)
        vulkan_or_skip(code, err)
        assert code == 0, (backend, out + err)
    f = copied(tmp_path, "learnopengl-pbb", None, "down", "level = max(sum, vec3(0.0001));",
               "level = sum;")
    for backend in ("gl", "vulkan"):
        code, out, err = run(["check", scene, "--preset", "learnopengl-pbb", "--shaders",
                              "pipeline", "--pipeline", str(f), "--backend", backend, "--json",
                              "c.json", "-q"], tmp_path, timeout=600)
        vulkan_or_skip(code, err)
        item = json.loads((tmp_path / "c.json").read_text())["items"][0]
        assert code == 1 and item["first_divergent_stage"] == "down.1", (backend, err)
        down1 = [s for s in item["stages"] if s["stage"] == "down.1"][0]
        assert down1["isolated"]["nonfinite_mismatch"] > 0


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
def test_the_articles_floor_with_only_some_stages_captured(tmp_path):
    """The same on Vulkan with down.1 and output alone read back: the clean chain passes, the
    copy without the floor still fails at down.1."""
    scene = os.path.join(CORPUS, "WideColorGamut.exr")

    def partial(d):
        d["passes"][1]["passes"][0].pop("stage")
        d["passes"][2]["passes"][0].pop("stage")

    results = {}
    for name, shader in (("clean", None), ("no-floor", "down")):
        (tmp_path / name).mkdir()
        if shader:
            f = copied(tmp_path / name, "learnopengl-pbb", partial, shader,
                       "level = max(sum, vec3(0.0001));", "level = sum;")
        else:
            f = copied(tmp_path / name, "learnopengl-pbb", partial)
        code, out, err = run(["check", scene, "--preset", "learnopengl-pbb", "--shaders",
                              "pipeline", "--pipeline", str(f), "--backend", "vulkan", "--json",
                              name + ".json", "-q"], tmp_path, timeout=600)
        vulkan_or_skip(code, err)
        results[name] = (code, json.loads((tmp_path / (name + ".json")).read_text())["items"][0])
    code, item = results["clean"]
    assert code == 0 and item["verdict"] == "PASS"
    assert [s["stage"] for s in item["stages"]] == ["down.1", "output"]
    code, item = results["no-floor"]
    assert code == 1 and item["first_divergent_stage"] == "down.1"
