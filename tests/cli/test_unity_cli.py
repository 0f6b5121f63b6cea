"""Preset unity-urp (Unity URP's bloom, data/presets/unity-urp.json) through the bloomref command.

- `--preset unity-urp` sets URP's values (Unity-Technologies/Graphics at 032e79e, Bloom.shader and
  PostProcessPass.SetupBloom); options given beside it override them.
- `compare --preset unity-urp`: bloomref's GLSL of URP's passes (gpu/shaders/unity_*.frag) in
  SetupBloom's order (gpu/src/unity_host.cpp), judged stage by stage against the CPU reference.
- `check --preset unity-urp --stages`: clean dumps pass, also with only some stages; dumps made
  with one of URP's choices changed fail at the stage where the change enters, and never with a
  wrong cause.
The GL cases skip without GL (exit 3) unless BLOOMREF_REQUIRE_GL=1. The CPU reference itself is
checked against numpy in tests/cli/test_unity_numpy.py.
"""
import json
import os

import pytest

import cli_support
from cli_support import assert_fails_where_planted, first_cause, gl_or_skip, run

CORPUS = os.environ.get("BLOOMREF_CORPUS", "")
# Odd: mip 0 is 101x65, log2(101) = 6.66, so 5 mips (101x65 .. 6x4), every one of odd width.
SIZE = "203x131"
LEVELS = 5


def test_preset_sets_urps_values_and_options_override_them(tmp_path):
    code, _, err = run(["run", "--size", SIZE, "-q", "-o", "o.exr", "--json", "r.json",
                        "--preset", "unity-urp"], tmp_path)
    assert code == 0, err
    r = json.loads((tmp_path / "r.json").read_text())
    p = r["params"]
    assert p["method"] == "mip" and p["first_downsample"] == "bilinear"
    assert p["prefilter"] == "soft-knee" and p["knee_form"] == "unity" and p["knee"] == 0.5
    assert p["clamp_max"] == 65472 and p["downsample"] == "gaussian" and p["upsample"] == "bilinear"
    assert p["level_combine"] == "lerp" and p["level_weights"] == "constant"
    assert p["level_weight"] == 0.68 and p["level_count"] == "unity"
    assert p["bloom_upscale"] == "bilinear" and p["composite_mode"] == "add"
    assert p["storage"] == "f16" and p["chain_storage"] == "r11g11b10"
    assert abs(p["threshold"] - 0.7874123) < 1e-6  # GammaToLinearSpace(0.9)
    assert r["mip_levels_used"] == LEVELS
    code, _, err = run(["run", "--size", SIZE, "-q", "-o", "o.exr", "--json", "r.json",
                        "--preset", "unity-urp", "--level-weight", "0.3", "--levels", "3"],
                       tmp_path)
    assert code == 0, err
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["params"]["level_weight"] == 0.3 and r["mip_levels_used"] == 3


def test_bad_values_of_urps_options_are_refused(tmp_path):
    for args, words in ((["--level-weight", "1.5"], "--level-weight must be in [0, 1]"),
                        (["--clamp-max", "-1"], "--clamp-max"),
                        (["--prefilter", "per-lookup"], "--first-downsample bilinear"),
                        (["--downsample", "box"], "13-tap, gaussian"),
                        (["--level-count", "auto"], "fixed, unity"),
                        (["--karis"], "--first-downsample 13-tap")):
        code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", "unity-urp",
                            *args], tmp_path)
        assert code == 2 and words in err, (args, err)
    assert not (tmp_path / "o.exr").exists()


def test_compare_runs_bloomrefs_unity_shaders_and_every_stage_passes(tmp_path):
    code, out, err = run(["compare", "--scene", "demo", "--size", SIZE, "--preset", "unity-urp",
                          "--json", "c.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    assert "URP's SetupBloom" in out
    stages = {s["stage"]: s for s in json.loads((tmp_path / "c.json").read_text())["stages"]}
    assert set(stages) == {"input", "composite", "output"} | {
        f"down.{k}" for k in range(1, LEVELS + 1)} | {f"up.{k}" for k in range(1, LEVELS)}
    assert all(s["isolated"]["verdict"] == "PASS" for s in stages.values())
    assert all(s["end_to_end"]["verdict"] == "PASS" for s in stages.values())


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
@pytest.mark.parametrize("image", ["GoldenGate.exr", "WideColorGamut.exr", "StarField.exr"])
def test_compare_unity_on_the_corpus(tmp_path, image):
    """WideColorGamut's negative values reach the first level, which B10G11R11 stores as 0."""
    code, out, err = run(["compare", os.path.join(CORPUS, image), "--preset", "unity-urp"],
                         tmp_path, timeout=600)
    gl_or_skip(code, err)
    assert code == 0 and "verdict PASS" in out, out + err


def dump(tmp_path, name, *options):
    return cli_support.dump(tmp_path, name, "unity-urp", SIZE, *options)


def judged(tmp_path, folder, keep, name):
    return cli_support.judged(tmp_path, folder, keep, name, "unity-urp", SIZE)


def test_clean_dumps_pass_whole_and_in_part(tmp_path):
    clean = dump(tmp_path, "clean")
    assert judged(tmp_path, clean, None, "all")["verdict"] == "PASS"
    for keep in (["composite"], ["up.1", "composite"], ["down.2", "up.3", "output"]):
        item = judged(tmp_path, clean, keep, "part-" + "-".join(keep))
        assert all(s["isolated"]["verdict"] == "PASS" for s in item["stages"]), keep
        assert item["verdict"] == "PASS" or item["sensitivity"]["weak"], keep


# One of URP's choices changed in the dump (the planted error), the stage where it enters, and
# the causes allowed to be named there (none is always allowed: unexplained is not wrong).
PLANTED = [
    # scatter 0.5 for 0.68: the first upsample, up.4, is off; the constant fitted.
    (("--level-weight", "0.5"), "up.4", {"none", "level-blend-constant"}),
    # the Volume's threshold 0.9 used without GammaToLinearSpace: fitted at down.1.
    (("--threshold", "0.9"), "down.1", {"none", "threshold-other"}),
    # seed 003's 13 taps where URP blurs each level with its Gaussian.
    (("--downsample", "13-tap"), "down.2", {"none"}),
    # the 3x3 tent where URP reads the level below with one bilinear lookup.
    (("--upsample", "tent"), "up.4", {"none"}),
    # a clamp of 1 where URP's is 65472.
    (("--clamp-max", "1"), "down.1", {"none"}),
    # one level fewer (as URP's later skipIterations would draw): up.3 reads down.4, not up.4.
    (("--levels", "4"), "up.3", {"none"}),
]


@pytest.mark.parametrize("planted,stage,causes", PLANTED, ids=[" ".join(p[0]) for p in PLANTED])
def test_a_changed_choice_fails_where_it_enters(tmp_path, planted, stage, causes):
    item = judged(tmp_path, dump(tmp_path, "planted", *planted), None, "all")
    value = planted[1]
    numeric = value.replace(".", "", 1).isdigit()
    assert_fails_where_planted(item, stage, causes, float(value) if numeric else None)


def test_the_planted_constants_are_named(tmp_path):
    """The two fits this preset relies on name their cause, not only allow it."""
    for option, value, stage, cause_id in (("--level-weight", "0.5", "up.4", "level-blend-constant"),
                                           ("--threshold", "0.9", "down.1", "threshold-other")):
        item = judged(tmp_path, dump(tmp_path, "p" + option, option, value), None, "j" + option)
        assert first_cause(item)[:2] == (stage, cause_id), json.dumps(first_cause(item)[2])


def test_a_stronger_bloom_never_passes_with_only_the_composite(tmp_path):
    strong = dump(tmp_path, "strong", "--strength", "2")
    assert judged(tmp_path, strong, ["composite"], "c")["verdict"] == "FAIL"
    item = judged(tmp_path, strong, ["up.1", "composite"], "uc")
    assert item["verdict"] == "FAIL" and first_cause(item)[:2] == ("composite", "bloom-scaled")


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
def test_a_sign_kept_where_r11g11b10_has_none_fails(tmp_path):
    """WideColorGamut's first level has negative values, which R11G11B10 (no sign) stores as 0:
    the bound allows a device anything between 2v and 0 there. A device that stored |v| (the
    sign dropped by abs, not clamped) must fail at down.1; the clean capture passes."""
    import numpy as np
    import OpenImageIO as oiio

    scene = os.path.join(CORPUS, "WideColorGamut.exr")

    def dumped(name, *options):
        d = tmp_path / name
        code, _, err = run(["run", scene, "--preset", "unity-urp", "-q", "-o",
                            str(tmp_path / (name + ".exr")), "--dump-stages", str(d), *options],
                           tmp_path, timeout=600)
        assert code == 0, err
        return d

    def read(path):
        return oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT)

    def judge(name, down1):
        sub = tmp_path / name
        sub.mkdir()
        (sub / "input.exr").write_bytes((stored / "input.exr").read_bytes())
        spec = oiio.ImageSpec(down1.shape[1], down1.shape[0], 4, oiio.FLOAT)
        spec.channelnames = ("R", "G", "B", "A")
        out = oiio.ImageBuf(spec)
        out.set_pixels(oiio.ROI(), np.ascontiguousarray(down1, dtype=np.float32))
        assert out.write(str(sub / "down.1.exr"))
        code, _, err = run(["check", scene, "--preset", "unity-urp", "--stages", str(sub),
                            "--json", str(sub / "r.json"), "-q"], tmp_path, timeout=600)
        assert code in (0, 1), err
        return json.loads((sub / "r.json").read_text())["items"][0]

    stored = dumped("stored")
    signed = read(dumped("signed", "--chain-storage", "f32") / "down.1.exr")
    clean = read(stored / "down.1.exr")
    negative = signed[..., :3] < 0
    assert negative.sum() > 100  # the case exists: enough negative values to see
    assert (clean[..., :3][negative] == 0).all()  # the CPU stores them as the format does
    assert judge("clean", clean)["verdict"] == "PASS"
    planted = clean.copy()
    planted[..., :3][negative] = np.abs(signed[..., :3][negative])
    item = judge("abs", planted)
    assert item["verdict"] == "FAIL" and item["first_divergent_stage"] == "down.1"
