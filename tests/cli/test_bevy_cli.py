"""Preset bevy (Bevy's bloom, data/presets/bevy.json) through the bloomref command.

- `--preset bevy` sets Bevy's values (bevyengine/bevy crates/bevy_post_process/src/bloom/,
  Bloom::NATURAL); options given beside it override them.
- `compare --preset bevy` (and bevy-old-school): bloomref's GLSL of Bevy's passes (gpu/shaders/bevy_*.frag) in Bevy's
  render-graph order (gpu/src/bevy_host.cpp), judged stage by stage against the CPU reference.
- `check --preset bevy --stages`: clean dumps pass, also with only some stages; dumps made with
  one of Bevy's choices changed fail, at the stage the change enters, and never with a wrong
  cause.
The GL case skips without GL (exit 3) unless BLOOMREF_REQUIRE_GL=1. The CPU reference itself is
checked against numpy in tests/cli/test_bevy_numpy.py.
"""
import json
import os

import pytest

import cli_support
from cli_support import assert_fails_where_planted, first_cause, gl_or_skip, run

CORPUS = os.environ.get("BLOOMREF_CORPUS", "")
SIZE = "203x131"  # odd: the first level is round(203 x 512 / 131) = 793 wide, its halves odd


def test_preset_sets_bevys_values_and_options_override_them(tmp_path):
    code, _, err = run(["run", "--size", "40x30", "-q", "-o", "o.exr", "--json", "r.json",
                        "--preset", "bevy"], tmp_path)
    assert code == 0, err
    r = json.loads((tmp_path / "r.json").read_text())
    p = r["params"]
    assert p["method"] == "mip" and p["prefilter"] == "none" and p["karis"] is True
    assert p["karis_form"] == "group-linear" and p["first_level_height"] == 512
    assert p["level_combine"] == "mix" and p["level_weights"] == "bevy" and p["levels"] == 8
    assert p["composite_mode"] == "mix" and p["strength"] == 0.15
    assert p["storage"] == "f16" and p["chain_storage"] == "r11g11b10"
    assert r["mip_levels_used"] == 8
    code, _, err = run(["run", "--size", "40x30", "-q", "-o", "o.exr", "--json", "r.json",
                        "--strength", "0.3", "--preset", "bevy", "--level-combine", "add"], tmp_path)
    assert code == 0, err
    p = json.loads((tmp_path / "r.json").read_text())["params"]
    assert p["strength"] == 0.3 and p["level_combine"] == "add" and p["karis_form"] == "group-linear"


def test_bad_values_of_bevys_options_are_refused(tmp_path):
    for args, words in ((["--low-frequency-boost-curvature", "1"], "curvature"),
                        (["--high-pass-frequency", "0"], "high-pass"),
                        (["--first-level-height", "-1"], "first-level-height"),
                        (["--level-weights", "unity"], "one, bevy"),
                        (["--strength", "1.5"], "--strength in [0, 1]")):
        code, _, err = run(["run", "--size", "8x8", "-q", "-o", "o.exr", "--preset", "bevy", *args],
                           tmp_path)
        assert code == 2 and words in err, (args, err)
    assert not (tmp_path / "o.exr").exists()


@pytest.mark.parametrize("preset", ["bevy", "bevy-old-school"])
def test_compare_runs_bloomrefs_bevy_shaders_and_every_stage_passes(tmp_path, preset):
    code, out, err = run(["compare", "--scene", "demo", "--size", SIZE, "--preset", preset,
                          "--json", "c.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    stages = {s["stage"]: s for s in json.loads((tmp_path / "c.json").read_text())["stages"]}
    assert set(stages) == {"input", "composite", "output"} | {f"down.{k}" for k in range(1, 9)} | {
        f"up.{k}" for k in range(1, 8)}
    assert all(s["isolated"]["verdict"] == "PASS" for s in stages.values())
    assert all(s["end_to_end"]["verdict"] == "PASS" for s in stages.values())


@pytest.mark.skipif(not CORPUS, reason="BLOOMREF_CORPUS not set")
@pytest.mark.parametrize("image", ["GoldenGate.exr", "StarField.exr"])
def test_compare_bevy_on_the_corpus(tmp_path, image):
    code, out, err = run(["compare", os.path.join(CORPUS, image), "--preset", "bevy"], tmp_path,
                         timeout=600)
    gl_or_skip(code, err)
    assert code == 0 and "verdict PASS" in out, out + err


def dump(tmp_path, name, *options):
    """The stages of preset bevy on the demo scene, `options` planted."""
    return cli_support.dump(tmp_path, name, "bevy", SIZE, *options)


def judged(tmp_path, folder, keep, name):
    """check of `folder`'s stages in `keep` (all when None) against preset bevy: the item."""
    return cli_support.judged(tmp_path, folder, keep, name, "bevy", SIZE)


def test_clean_dumps_pass_whole_and_in_part(tmp_path):
    clean = dump(tmp_path, "clean")
    item = judged(tmp_path, clean, None, "all")
    assert item["verdict"] == "PASS", json.dumps(item["sensitivity"])
    for keep in (["composite"], ["up.1", "composite"], ["down.3", "up.4", "output"]):
        item = judged(tmp_path, clean, keep, "part-" + "-".join(keep))
        assert all(s["isolated"]["verdict"] == "PASS" for s in item["stages"]), keep
        assert item["verdict"] == "PASS" or item["sensitivity"]["weak"], keep


# One of Bevy's choices changed in the dump (the planted error), the stage where it enters, and
# the causes allowed to be named there (none is always allowed: unexplained is not wrong).
PLANTED = [
    # Bevy's Additive constants (lf boost not scaled by 1 - intensity) on the energy-conserving
    # blend: the first blend, up.7, is off.
    (("--level-combine", "add"), "up.7", {"none"}),
    # intensity 0.3: every blend constant and the composite; up.7's is 0.79 for 0.745.
    (("--strength", "0.3"), "up.7", {"level-blend-constant"}),
    # no Karis average on the first level.
    (("--karis-form", "per-tap"), "down.1", {"none"}),
    # no low-frequency boost: every level's constant the intensity alone, 0.15 for 0.745.
    (("--low-frequency-boost", "0"), "up.7", {"level-blend-constant"}),
]


@pytest.mark.parametrize("planted,stage,causes", PLANTED, ids=[" ".join(p[0]) for p in PLANTED])
def test_a_changed_choice_fails_where_it_enters(tmp_path, planted, stage, causes):
    item = judged(tmp_path, dump(tmp_path, "planted", *planted), None, "all")
    # A fitted constant's interval holds the planted one (up.7's, for the constants).
    planted_c = {"--strength": 0.3 + 0.7 * 0.7, "--low-frequency-boost": 0.15}.get(planted[0])
    assert_fails_where_planted(item, stage, causes, planted_c)


def test_old_school_soft_threshold_is_judged(tmp_path):
    """bevy-old-school's soft threshold at 0.6: dumps made with it at 0.3 fail at down.1, where
    it enters, the threshold fitted; clean ones pass."""
    def item(name, *options):
        folder = cli_support.dump(tmp_path, name, "bevy-old-school", SIZE, *options)
        return cli_support.judged(tmp_path, folder, None, name + "-judged", "bevy-old-school", SIZE)
    assert item("clean")["verdict"] == "PASS"
    low = item("low", "--threshold", "0.3")
    assert low["verdict"] == "FAIL" and low["first_divergent_stage"] == "down.1"
    stage, named, cause = first_cause(low)
    assert named == "threshold-other", cause  # the soft threshold fitted, 0.3 inside its interval
    assert cause["fitted"]["low"] <= 0.3 <= cause["fitted"]["high"], cause


def test_a_stronger_bloom_never_passes_with_only_the_composite(tmp_path):
    strong = dump(tmp_path, "strong", "--strength", "0.3")
    item = judged(tmp_path, strong, ["composite"], "c")
    assert item["verdict"] != "PASS", json.dumps(item["sensitivity"])
    item = judged(tmp_path, strong, ["up.1", "composite"], "uc")
    assert item["verdict"] == "FAIL"


def test_a_half_size_first_level_is_refused_by_size(tmp_path):
    """Levels half the image (bloomref's default) where Bevy's are 512 high: exit 2, the file and
    both sizes named."""
    half = dump(tmp_path, "half", "--first-level-height", "0")
    code, _, err = run(["check", "--scene", "demo", "--size", SIZE, "--preset", "bevy",
                        "--stages", str(half), "-q"], tmp_path)
    assert code == 2 and "down.1.exr" in err and "101x65" in err and "793x512" in err, err
