"""Presets and the mip-chain article's host code, through the bloomref command.

- `--preset`: a built-in name or a JSON file sets the options; those given beside it override;
  a bad preset is exit 2 naming it and the key.
- `compare --preset learnopengl-pbb`: bloomref's own shaders for the article (gpu/shaders/pbb_*)
  through the article's host code, judged stage by stage against the CPU reference.
- `check --shaders learnopengl-pbb`: refusals name the file or option; bloomref's shaders pass;
  with BLOOMREF_LEARNOPENGL_PBB_DIR (a folder holding the article's 6.new_downsample.fs,
  6.new_upsample.fs, 6.bloom_final.fs and their .vs files, JoeyDeVries/LearnOpenGL
  src/8.guest/2022/6.physically_based_bloom/), the article's own, unmodified shaders too: they
  pass on corpus images without negative values and fail the output, with the pow cause, on one
  with them. They are not in this repository (bloomref copies no code).
The GL cases skip without GL (exit 3) unless BLOOMREF_REQUIRE_GL=1.
"""
import json
import os
from pathlib import Path

import pytest

import cli_support
from cli_support import first_cause, gl_or_skip, run

ROOT = Path(__file__).resolve().parents[2]
OWN = ROOT / "gpu" / "shaders"
CORPUS = os.environ.get("BLOOMREF_CORPUS", "")
ARTICLE = os.environ.get("BLOOMREF_LEARNOPENGL_PBB_DIR", "")


def params(tmp_path, *args):
    code, out, err = run(["run", "--size", "40x30", "-q", "-o", "o.exr", "--json", "r.json", *args], tmp_path)
    assert code == 0, err
    return json.loads((tmp_path / "r.json").read_text())["params"]


def test_preset_sets_the_articles_values_and_options_override_them(tmp_path):
    p = params(tmp_path, "--preset", "learnopengl-pbb")
    # The article's host code and shaders (data/presets/learnopengl-pbb.json cites them).
    assert p["method"] == "mip" and p["prefilter"] == "bright" and p["karis"] is True
    assert p["karis_form"] == "group-srgb" and p["texel_step"] == "halved-float"
    assert p["upsample_radius"] == 0.005 and p["bloom_upscale"] == "bilinear"
    assert p["composite_mode"] == "mix" and p["strength"] == 0.04
    assert p["storage"] == "f16" and p["chain_storage"] == "r11g11b10"
    # Given beside it, an option wins, whichever comes first on the line.
    p = params(tmp_path, "--strength", "0.1", "--preset", "learnopengl-pbb", "--levels", "3")
    assert p["strength"] == 0.1 and p["levels"] == 3 and p["composite_mode"] == "mix"
    # cod-mip is --method mip as it was.
    assert params(tmp_path, "--preset", "cod-mip")["prefilter"] == "per-lookup"


@pytest.mark.parametrize("args, option", [
    (["--preset", "bevy", "--knee", "0.2"], "--knee"),             # bevy has no soft knee
    (["--method", "mip", "--passes", "4"], "--passes"),           # no blur passes in the chain
    (["--levels", "4"], "--levels"),                              # no levels in the Gaussian
    (["--preset", "threejs", "--level-weight", "0.5"], "--level-weight"),
    (["--preset", "unity-urp", "--level-kernels", "3,5"], "--level-kernels"),
    (["--method", "mip", "--passes", "10"], "--passes"),          # given, even at its default
    (["--preset", "bevy", "--luma", "rec601"], "--luma"),         # Bevy's chain compares none
    (["--preset", "threejs", "--upsample", "bilinear"], "--upsample"),  # the sum has none
    (["--preset", "threejs", "--first-level-height", "40"], "--first-level-height"),
])
def test_an_option_its_mode_ignores_is_refused(tmp_path, args, option):
    code, _, err = run(["run", "--size", "32x24", "-q", "-o", "x.exr", *args], tmp_path)
    assert code == 2 and option + " does nothing without" in err, err
    assert not (tmp_path / "x.exr").exists()


def test_a_manifests_params_are_given(tmp_path):
    """A manifest's params are the user's: one its mode ignores is refused, naming the file."""
    assert run(["scenes", "demo", "--size", "32x24", "-o", "scene.exr"], tmp_path)[0] == 0
    manifest = {"version": 1, "params": {"method": "mip", "passes": 4},
                "items": [{"id": "demo", "scene": "scene.exr", "stages": "d"}]}
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    code, out, err = run(["check", "--manifest", "m.json", "-q"], tmp_path)
    assert code == 2 and "m.json" in err and "--passes does nothing without" in err, out + err
    # The mode an option on the command line needs may come from the manifest.
    assert run(["run", "scene.exr", "--method", "mip", "--dump-stages", "d", "-q", "-o", "o.exr"],
               tmp_path)[0] == 0
    manifest["params"] = {"method": "mip"}
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    code, out, err = run(["check", "--manifest", "m.json", "--levels", "6", "-q"], tmp_path)
    assert code == 0, out + err
    manifest.pop("params")
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    code, out, err = run(["check", "--manifest", "m.json", "--levels", "6", "-q"], tmp_path)
    assert code == 2 and "--levels does nothing without --method mip" in err, out + err


def test_a_presets_values_under_an_overridden_mode_are_not_refused(tmp_path):
    """unity-urp sets --knee for its soft knee; with --prefilter none given the knee is
    unused, and not refused: the user gave the mode, not the knee."""
    p = params(tmp_path, "--preset", "unity-urp", "--prefilter", "none")
    assert p["prefilter"] == "none" and p["knee"] == 0.5
    # Every mode of threejs-unrealbloompass overridden: its level options (normalise, kernels,
    # sigmas, factors) are left unused, not refused.
    code, _, err = run(["run", "--size", "32x24", "-q", "-o", "y.exr", "--preset",
                        "threejs-unrealbloompass", "--downsample", "13-tap", "--level-count",
                        "fixed", "--level-combine", "add", "--first-downsample", "13-tap",
                        "--prefilter", "per-lookup", "--threshold", "1"], tmp_path)
    assert code == 0, err
    # A preset's mip chain under --method gaussian given: its chain options are unused, and
    # --no-level-normalise asks for nothing.
    for args in (["--preset", "learnopengl-pbb", "--method", "gaussian"],
                 ["--method", "mip", "--no-level-normalise"]):
        code, _, err = run(["run", "--size", "32x24", "-q", "-o", "z.exr", *args], tmp_path)
        assert code == 0, (args, err)


def test_cod_mip_preset_gives_method_mips_bits(tmp_path):
    for args, name in ((["--preset", "cod-mip"], "a.exr"), (["--method", "mip"], "b.exr")):
        code, _, err = run(["run", "--size", "64x48", "-q", "-o", name, *args], tmp_path)
        assert code == 0, err
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()


def test_a_preset_file_and_its_errors(tmp_path):
    f = tmp_path / "mine.json"
    f.write_text(json.dumps({"params": {"method": "mip", "levels": 2, "composite-mode": "mix",
                                        "strength": 0.5}}))
    p = params(tmp_path, "--preset", str(f))
    assert p["levels"] == 2 and p["composite_mode"] == "mix" and p["strength"] == 0.5
    (tmp_path / "o.exr").unlink()  # the refusals below must write nothing
    f.write_text(json.dumps({"params": {"methd": "mip"}}))
    code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", str(f)], tmp_path)
    assert code == 2 and "unknown key 'methd'" in err and str(f) in err
    f.write_text(json.dumps({"params": {"levels": "many"}}))
    code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", str(f)], tmp_path)
    assert code == 2 and "'levels' is not a number" in err
    f.write_text("{ not json")
    code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", str(f)], tmp_path)
    assert code == 2 and "not valid JSON" in err
    code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", "nope"], tmp_path)
    assert code == 2 and "learnopengl-pbb" in err  # the known names are listed
    code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", "gone.json"], tmp_path)
    assert code == 2 and "gone.json" in err
    assert not (tmp_path / "o.exr").exists()


def test_compare_runs_bloomrefs_article_shaders_and_every_level_passes(tmp_path):
    # An odd size, so that the host's halved float sizes are not the levels' (101 -> 50.5).
    code, out, err = run(["compare", "--scene", "demo", "--size", "202x134", "--preset",
                          "learnopengl-pbb", "--json", "c.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    r = json.loads((tmp_path / "c.json").read_text())
    stages = {s["stage"]: s for s in r["stages"]}
    assert set(stages) >= {"down.1", "down.6", "up.5", "up.1", "output"}
    assert all(s["isolated"]["verdict"] == "PASS" for s in stages.values())


def article_args(folder, own=False):
    if own:
        return ["--downsample-fs", str(OWN / "pbb_downsample.frag"), "--upsample-fs",
                str(OWN / "pbb_upsample.frag"), "--final-fs", str(OWN / "pbb_final.frag")]
    d = Path(folder)
    return ["--downsample-fs", str(d / "6.new_downsample.fs"), "--downsample-vs", str(d / "6.new_downsample.vs"),
            "--upsample-fs", str(d / "6.new_upsample.fs"), "--upsample-vs", str(d / "6.new_upsample.vs"),
            "--final-fs", str(d / "6.bloom_final.fs"), "--final-vs", str(d / "6.bloom_final.vs")]


def test_check_refuses_what_the_articles_host_cannot_run(tmp_path):
    base = ["check", "--scene", "demo", "--size", "64x48", "--shaders", "learnopengl-pbb"]
    code, _, err = run(base + ["--downsample-fs", str(OWN / "pbb_downsample.frag")], tmp_path)
    assert code == 2 and "--upsample-fs" in err
    code, _, err = run(base + article_args("", own=True) + ["--blur-fs", "x.fs"], tmp_path)
    assert code == 2 and "--blur-fs" in err
    # A sampler the host does not bind: refused before drawing, the file named.
    bad = tmp_path / "down.fs"
    bad.write_text((OWN / "pbb_downsample.frag").read_text().replace(
        "uniform int mipLevel = 1;", "uniform int mipLevel = 1;\nuniform sampler2D lut;").replace(
        "vec3 c = tap(vec2(0.0));", "vec3 c = tap(vec2(0.0)) + texture(lut, texCoord).rgb;"))
    code, _, err = run(base + ["--downsample-fs", str(bad), "--upsample-fs", str(OWN / "pbb_upsample.frag"),
                               "--final-fs", str(OWN / "pbb_final.frag")], tmp_path)
    gl_or_skip(code, err)
    assert code == 2 and str(bad) in err and "'lut'" in err and "learnopengl-pbb" in err


def test_check_with_bloomrefs_article_shaders_passes(tmp_path):
    code, out, err = run(["check", "--scene", "demo", "--size", "202x134", "--shaders",
                          "learnopengl-pbb", *article_args("", own=True), "--json", "r.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    judged = [s["stage"] for s in item["stages"]]
    assert judged[:2] == ["down.1", "down.2"] and judged[-1] == "output" and "up.1" in judged
    assert item["verdict"] == "PASS"


@pytest.mark.skipif(not ARTICLE or not CORPUS, reason="BLOOMREF_LEARNOPENGL_PBB_DIR and BLOOMREF_CORPUS not both set")
@pytest.mark.parametrize("image,verdict", [("StarField.exr", "PASS"), ("reference-crop.exr", "PASS"),
                                           ("uffizi_probe-128.exr", "FAIL"),
                                           ("WideColorGamut.exr", "FAIL")])
def test_the_articles_own_shaders_on_the_corpus(tmp_path, image, verdict):
    code, out, err = run(["check", os.path.join(CORPUS, image), "--shaders", "learnopengl-pbb",
                          *article_args(ARTICLE), "--json", "r.json"], tmp_path)
    gl_or_skip(code, err)
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["verdict"] == verdict, out
    if verdict == "FAIL":
        # Negative values through the final pass's gamma. The Karis average's encode of a group
        # with a negative channel (WideColorGamut) is NaN too, but its max(luma, 0.0001) gives
        # 0.0001 for it, as GLSL's max does on the devices (maxNum): down.1 passes.
        first = [s for s in item["stages"] if s["stage"] == item["first_divergent_stage"]][0]
        assert first["stage"] == "output"
        assert first["cause"]["id"] == "pow-negative" and first["cause"]["likely"]


def test_random_mip_chain_bugs_are_named_right_or_not_at_all(tmp_path):
    """One bug of random kind and size planted in bloomref's shaders for the article, on a
    built-in scene of random size: the cause named at the first divergent stage must be the
    planted one or none (a confident wrong cause never). BLOOMREF_FUZZ_CASES and
    BLOOMREF_FUZZ_SEED run more, or others."""
    import random
    rng = random.Random(int(os.environ.get("BLOOMREF_FUZZ_SEED", "5")))
    cases = int(os.environ.get("BLOOMREF_FUZZ_CASES", "10"))
    kinds = {
        # id: (file, find, replacement made from a random amount)
        "upsample-gain": ("pbb_upsample.frag", "level = sum / 16.0;",
                          lambda: "level = sum / 16.0 * %.3f;" % rng.uniform(1.15, 3.0)),
        "bloom-scaled": ("pbb_final.frag", "uniform float bloomStrength = 0.04;",
                         lambda: "uniform float bloomStrength = %.4f;" % rng.choice(
                             [rng.uniform(0.005, 0.03), rng.uniform(0.06, 0.5)])),
        "composite-mode": ("pbb_final.frag",
                           "hdr = mix(hdr, texture(bloomBlur, TexCoords).rgb, bloomStrength);",
                           lambda: "hdr += %.3f * texture(bloomBlur, TexCoords).rgb;" % rng.uniform(0.2, 2.0)),
        "level-size-rounding": ("pbb_downsample.frag", "texCoord + steps / srcResolution",
                                lambda: "texCoord + steps / vec2(textureSize(srcTexture, 0))"),
    }
    scenes = ["demo", "impulse", "hot-edge"]
    tally = {}
    for n in range(cases):
        kind = rng.choice(sorted(kinds))
        f, find, make = kinds[kind]
        folder = tmp_path / str(n)
        folder.mkdir()
        for s in ("pbb_downsample.frag", "pbb_upsample.frag", "pbb_final.frag"):
            text = (OWN / s).read_text()
            if s == f:
                assert text.count(find) == 1
                text = text.replace(find, make())
            (folder / s).write_text(text)
        # Odd sizes, so that the halved float sizes are not the levels' somewhere.
        size = "%dx%d" % (rng.randrange(97, 260, 2) + 1, rng.randrange(71, 200, 2) + 1)
        scene = rng.choice(scenes)
        code, out, err = run(["check", "--scene", scene, "--size", size, "--shaders", "learnopengl-pbb",
                              "--downsample-fs", str(folder / "pbb_downsample.frag"),
                              "--upsample-fs", str(folder / "pbb_upsample.frag"),
                              "--final-fs", str(folder / "pbb_final.frag"), "--sensitivity", "none",
                              "--json", str(folder / "r.json"), "-q"], tmp_path)
        gl_or_skip(code, err)
        assert code in (0, 1), err
        item = json.loads((folder / "r.json").read_text())["items"][0]
        # Right: the cause named first, or one the captures cannot tell from it ("as likely":
        # on a black scene mix(scene, bloom, s) and scene + s bloom are the same image).
        named = "none"
        if item["verdict"] != "PASS" and item.get("first_divergent_stage"):
            first = [s for s in item["stages"] if s["stage"] == item["first_divergent_stage"]][0]
            c = first.get("cause")
            if c and c.get("likely"):
                alike = [o["id"] for o in first.get("causes", []) if o.get("as_likely")]
                named = kind if kind in alike else c["id"]
        tally.setdefault(kind, []).append(named)
        assert named in (kind, "none"), "%s on %s %s: named %s (%s)" % (kind, scene, size, named,
                                                                      json.dumps(first.get("causes")))
    print({k: "%d right of %d" % (v.count(k), len(v)) for k, v in tally.items()})


def dump(tmp_path, name, *options):
    """The stages of preset learnopengl-pbb on a built-in scene of odd size, `options` planted."""
    return cli_support.dump(tmp_path, name, "learnopengl-pbb", "203x131", *options)


def judged(tmp_path, folder, keep, name):
    """check of `folder`'s stages in `keep` alone against the preset: the result's item."""
    return cli_support.judged(tmp_path, folder, keep, name, "learnopengl-pbb", "203x131")


def test_partial_captures_of_the_article_pipeline_pass_clean_and_fail_planted(tmp_path):
    clean = dump(tmp_path, "clean")
    for keep in (["output"], ["up.1", "output"], ["down.2", "up.3"]):
        item = judged(tmp_path, clean, keep, "clean-" + "-".join(keep))
        # No stage is out of bound; the item may only be a weak verdict (what it could see).
        assert all(s["isolated"]["verdict"] == "PASS" for s in item["stages"]), keep
        assert item["verdict"] == "PASS" or item["sensitivity"]["weak"], keep
    # The bloom twice as strong (bloomStrength 0.08 where 0.04 is declared). From the output
    # alone the bloom is 4% of the image, and what the uncaptured chain may carry hides a 2x
    # gain: never a PASS, a weak verdict that says it sees no gain that small.
    strong = dump(tmp_path, "strength", "--strength", "0.08")
    item = judged(tmp_path, strong, ["output"], "s-output")
    assert item["verdict"] == "WARN" and item["sensitivity"]["weak"]
    seen = item["sensitivity"]["gain"]["smallest_failed"]
    assert seen is None or seen > 2
    # With the last level captured too, the output fails and the cause is named.
    item = judged(tmp_path, strong, ["up.1", "output"], "s-up1")
    assert item["verdict"] == "FAIL"
    stage, named, cause = first_cause(item)
    assert (stage, named) == ("output", "bloom-scaled")
    assert "scaled by 2" in cause["detail"] or "scaled by 1.99" in cause["detail"]
    # scene + bloom where the mix is declared, with up.1 and the output.
    item = judged(tmp_path, dump(tmp_path, "add", "--composite-mode", "add", "--strength", "1"),
                  ["up.1", "output"], "a")
    assert item["verdict"] == "FAIL" and first_cause(item)[:2] == ("output", "composite-mode")
    # The tent's radius doubled (half a texel of level 1 where a quarter is declared), up.1 and
    # the output captured: what the chain before up.1 may carry hides it, so never a PASS but a
    # weak verdict naming the captures that would see more; with up.2 too, up.1 is out of bound
    # (within the WARN tier) and no cause is said to explain it.
    radius = dump(tmp_path, "radius", "--upsample-radius", "0.01")
    item = judged(tmp_path, radius, ["up.1", "output"], "r")
    assert item["verdict"] == "WARN" and item["sensitivity"]["weak"]
    assert "up.2" in item["sensitivity"]["strengthen_with"]
    item = judged(tmp_path, radius, ["up.2", "up.1", "output"], "r2")
    assert item["verdict"] in ("WARN", "FAIL") and item["first_divergent_stage"] == "up.1"
    assert first_cause(item)[1] == "none"
