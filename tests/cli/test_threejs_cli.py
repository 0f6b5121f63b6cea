"""Preset threejs (three.js's bloom, data/presets/threejs.json) through the bloomref command.

- `--preset threejs` sets BloomNode's values (mrdoob/three.js at fef3c54); options given beside
  it override them.
- `compare --preset threejs`: bloomref's GLSL of BloomNode's passes (gpu/shaders/threejs_*.frag)
  in updateBefore's order, from the preset's description, judged stage by stage against the CPU
  reference; the same description on Vulkan.
- `check --preset threejs --stages`: clean dumps pass, also with only some stages; dumps made
  with one of three.js's choices changed fail at the stage where the change enters, and never
  with a wrong cause.
The GL and Vulkan cases skip without a device (exit 3) unless BLOOMREF_REQUIRE_GL=1 /
BLOOMREF_REQUIRE_VULKAN=1. The CPU reference itself is checked against numpy in
tests/cli/test_threejs_numpy.py.
"""
import json
import os

import pytest

import cli_support
from cli_support import assert_fails_where_planted, first_cause, gl_or_skip, run

CORPUS = os.environ.get("BLOOMREF_CORPUS", "")
SIZE = "203x131"  # odd: the high pass is 102x66, the mips 102x66 .. 7x5


def test_preset_sets_threejs_values_and_options_override_them(tmp_path):
    code, _, err = run(["run", "--size", SIZE, "-q", "-o", "o.exr", "--json", "r.json",
                        "--preset", "threejs"], tmp_path)
    assert code == 0, err
    r = json.loads((tmp_path / "r.json").read_text())
    p = r["params"]
    assert p["method"] == "mip" and p["level_count"] == "threejs" and p["levels"] == 5
    assert p["first_downsample"] == "bilinear" and p["prefilter"] == "smoothstep"
    assert p["threshold"] == 0 and p["smooth_width"] == 0.01 and p["luma"] == "rec709"
    assert p["downsample"] == "separable" and p["level_kernels"] == [6, 10, 14, 18, 22]
    assert p["level_combine"] == "sum" and p["level_factors"] == [1, 0.8, 0.6, 0.4, 0.2]
    assert p["level_radius"] == 0 and p["level_strength"] == 1 and p["strength"] == 1
    assert p["bloom_upscale"] == "bilinear" and p["storage"] == "f16"
    assert p["chain_storage"] == "f16"
    assert r["mip_levels_used"] == 6  # the high pass and five mips
    code, _, err = run(["run", "--size", SIZE, "-q", "-o", "o.exr", "--json", "r.json",
                        "--preset", "threejs", "--level-radius", "0.4", "--levels", "3",
                        "--level-kernels", "3,5,7"], tmp_path)
    assert code == 0, err
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["params"]["level_radius"] == 0.4 and r["mip_levels_used"] == 4
    assert r["params"]["level_kernels"] == [3, 5, 7]


def test_bad_values_of_threejs_options_are_refused(tmp_path):
    for args, words in ((["--level-radius", "1.5"], "--level-radius must be in [0, 1]"),
                        (["--smooth-width", "0"], "--smooth-width"),
                        (["--threshold", "1e6"], "smoothstep's edges would meet"),
                        (["--level-sigmas", "0.01"], "--level-sigmas: each sigma"),
                        (["--level-kernels", "6,10"], "--level-kernels needs a radius for each"),
                        (["--level-kernels", "6,0,14,18,22"], "radius must be in [1, 64]"),
                        (["--level-factors", "1,1"], "--level-factors needs a factor"),
                        (["--level-count", "fixed"], "--level-combine sum"),
                        (["--first-downsample", "13-tap"], "--first-downsample bilinear")):
        code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", "threejs",
                            *args], tmp_path)
        assert code == 2 and words in err, (args, err)
    assert not (tmp_path / "o.exr").exists()


def test_compare_runs_bloomrefs_threejs_shaders_and_every_stage_passes(tmp_path):
    code, out, err = run(["compare", "--scene", "demo", "--size", SIZE, "--preset", "threejs",
                          "--json", "c.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    assert "three.js's layout" in out
    stages = {s["stage"]: s for s in json.loads((tmp_path / "c.json").read_text())["stages"]}
    assert set(stages) == {"input", "up.1", "composite", "output"} | {
        f"down.{k}" for k in range(1, 7)}
    assert all(s["isolated"]["verdict"] == "PASS" for s in stages.values())
    assert all(s["end_to_end"]["verdict"] == "PASS" for s in stages.values())
    # The device's own images: somewhere off the oracle's by its rounding.
    assert max(s["isolated"]["max_abs"] for s in stages.values()) > 0


def test_compare_on_vulkan_passes(tmp_path):
    code, out, err = run(["compare", "--backend", "vulkan", "--scene", "demo", "--size", SIZE,
                          "--preset", "threejs"], tmp_path, timeout=600)
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())
    assert code == 0 and "verdict PASS" in out, out + err


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
@pytest.mark.parametrize("image", ["GoldenGate.exr", "StarField.exr"])
def test_compare_threejs_on_the_corpus(tmp_path, image):
    code, out, err = run(["compare", os.path.join(CORPUS, image), "--preset", "threejs"],
                         tmp_path, timeout=600)
    gl_or_skip(code, err)
    assert code == 0 and "verdict PASS" in out, out + err


def dump(tmp_path, name, *options):
    return cli_support.dump(tmp_path, name, "threejs", SIZE, *options)


def judged(tmp_path, folder, keep, name):
    return cli_support.judged(tmp_path, folder, keep, name, "threejs", SIZE)


def test_clean_dumps_pass_whole_and_in_part(tmp_path):
    clean = dump(tmp_path, "clean")
    assert judged(tmp_path, clean, None, "all")["verdict"] == "PASS"
    for keep in (["composite"], ["up.1", "composite"], ["down.3", "up.1", "output"]):
        item = judged(tmp_path, clean, keep, "part-" + "-".join(keep))
        assert all(s["isolated"]["verdict"] == "PASS" for s in item["stages"]), keep
        assert item["verdict"] == "PASS" or item["sensitivity"]["weak"], keep


# One of three.js's choices changed in the dump (the planted error), the stage where it enters,
# and the causes allowed to be named there (none is always allowed: unexplained is not wrong).
PLANTED = [
    # a threshold of 0.5 where the default is 0: the high pass drops the dim texels.
    (("--threshold", "0.5"), "down.1", {"none", "threshold-other"}),
    # the first mip's kernel radius 5 for 6 (a narrower blur, and a different coefficient sum).
    (("--level-kernels", "5,10,14,18,22"), "down.2", {"none"}),
    # the old UnrealBloomPass's radii, 3 .. 11 (before three.js PR 31528).
    (("--level-kernels", "3,5,7,9,11"), "down.2", {"none"}),
    # radius 0.5 mirrors the factors: the composite of the mips is off.
    (("--level-radius", "0.5"), "up.1", {"none"}),
    # the fourth factor 0.2 for 0.4: only the sum sees it.
    (("--level-factors", "1,0.8,0.6,0.2,0.2"), "up.1", {"none"}),
    # the bloom added at half strength where the example adds it whole.
    (("--strength", "0.5"), "composite", {"none", "bloom-scaled"}),
]


@pytest.mark.parametrize("planted,stage,causes", PLANTED, ids=[" ".join(p[0]) for p in PLANTED])
def test_a_changed_choice_fails_where_it_enters(tmp_path, planted, stage, causes):
    item = judged(tmp_path, dump(tmp_path, "planted", *planted), None, "all")
    value = planted[1]
    numeric = value.replace(".", "", 1).isdigit()
    assert_fails_where_planted(item, stage, causes, float(value) if numeric else None)


def test_a_wrong_mip_fails_with_only_the_sum_and_output_captured(tmp_path):
    for planted in (("--level-kernels", "3,5,7,9,11"), ("--level-radius", "0.5")):
        item = judged(tmp_path, dump(tmp_path, "p" + planted[1], *planted), ["up.1", "output"],
                      "part" + planted[1])
        assert item["verdict"] == "FAIL", (planted, json.dumps(item["stages"])[:1500])


def test_the_planted_threshold_and_strength_are_named(tmp_path):
    """A threshold set where three.js's default is 0 is fitted at the high pass (its interval
    holding the planted 0.5); a bloom added at half strength is named at the composite, also
    with only the composite captured."""
    item = judged(tmp_path, dump(tmp_path, "thr", "--threshold", "0.5"), None, "thr-all")
    stage, cause, c = first_cause(item)
    assert (stage, cause) == ("down.1", "threshold-other"), json.dumps(c)
    assert c["fitted"]["low"] <= 0.5 <= c["fitted"]["high"], json.dumps(c)
    weak = dump(tmp_path, "weak", "--strength", "0.5")
    for keep in (None, ["composite"], ["up.1", "composite"]):
        item = judged(tmp_path, weak, keep, "weak-" + "-".join(keep or ["all"]))
        assert first_cause(item)[:2] == ("composite", "bloom-scaled"), keep
