"""--storage r11g11b10 and --storage rgba8: every stage stored in a packed float or an 8-bit
target, as blooms drawn into R11F_G11F_B10F or LDR targets store them.

- The CPU reference of the gaussian method against an independent numpy computation, stage by
  stage: seed 000's pipeline (bright pass, ten 9-tap passes with its weights, composite, tone
  map, gamma) with every stage stored as the format stores it: R11F_G11F_B10F's unsigned
  floats (6-bit mantissas for R and G, 5 for B, 5-bit exponents biased by 15, round to
  nearest), GL_RGBA8's clamp to [0, 1] and nearest 255th (GL 4.6, 2.3.5.2). The expected
  values are computed here from bloomref's stage before each, never taken from its output.
- compare: bloomref's GL shaders with every stage so stored pass on llvmpipe (the gaussian and
  mip methods, and the engine presets with their scene and composite targets so stored); the
  Vulkan path's own pipeline refuses them (exit 2), the presets' passes run them.
- check: a capture whose stages are f16 judged as 8-bit (and the other way round) fails at its
  first stage, also with only the last pass and the output captured; packed judged as f16 fails
  named, f16 judged as packed (finer than declared) passes; 8-bit passes 5% too strong fail at
  the first, the weight sum fitted, and with only the last pass captured are not passed.
- The tutorial's layout (check --shaders learnopengl) runs a user's correct shaders with packed
  targets and passes; it refuses 8-bit ones (its final pass stores no composite), as the
  article's layout does.
The GL and Vulkan cases skip without a device (exit 3) unless BLOOMREF_REQUIRE_GL=1 /
BLOOMREF_REQUIRE_VULKAN=1.
"""
import json
import os
from pathlib import Path

import numpy as np
import pytest

import cli_support
from cli_support import gl_or_skip, run
from test_first_axis import blur
from test_variants_numpy import LUMA709, read_rgb, stages_of, write_exr

SIZE = "203x131"


def unorm8(x):
    """An RGBA8 write: clamped to [0, 1], the nearest 255th (ties away from zero), NaN as 0."""
    x = np.nan_to_num(np.asarray(x, dtype=np.float64), nan=0.0)
    return np.floor(np.clip(x, 0.0, 1.0) * 255.0 + 0.5) / 255.0


def packed_float(x, mantissa):
    """An unsigned float with a 5-bit exponent biased by 15 and `mantissa` bits, rounded to the
    nearest, ties away from zero (GL asks for the closest value and names no rule for ties; this
    is the one bloomref's CPU stores with): negative values and NaN as 0, denormals below 2^-14,
    the largest finite value where it would overflow."""
    x = np.nan_to_num(np.asarray(x, dtype=np.float64), nan=0.0, posinf=np.inf)
    x = np.maximum(x, 0.0)
    largest = (2.0 - 2.0 ** -mantissa) * 2.0 ** 15
    e = np.floor(np.log2(np.maximum(x, 2.0 ** -14)))
    quantum = 2.0 ** (e - mantissa)
    return np.minimum(np.floor(x / quantum + 0.5) * quantum, largest)


def r11g11b10(x):
    return np.stack([packed_float(x[..., 0], 6), packed_float(x[..., 1], 6),
                     packed_float(x[..., 2], 5)], axis=-1)


STORE = {"rgba8": unorm8, "r11g11b10": r11g11b10}


def gaussian(scene, threshold, got):
    """Seed 000's pipeline, each stage before it is stored, computed here from bloomref's
    stage before it (itself checked against this), so that a value a computation's rounding
    puts on the other side of a tie between two stored values does not carry its difference
    on. The bright pass reads the scene unrounded (the seeds' MRT draw writes both at once),
    the composite the stored scene."""
    st = {"input": scene}
    lum = scene @ LUMA709
    st["bright"] = np.where((lum > threshold)[..., None], scene, 0.0)
    prev = "bright"
    for k in range(1, 11):
        st[f"blur.{k}"] = blur(got[prev], vertical=k % 2 == 0)
        prev = f"blur.{k}"
    st["composite"] = got["input"] + got[prev]
    st["tonemap"] = 1.0 - np.exp(-got["composite"])
    st["output"] = np.power(got["tonemap"], 1.0 / float(np.float32(2.2)))
    return st


def scene(seed):
    """Values across [0, 1.3] with some far brighter, 37x29: the 8-bit clamp and the packed
    floats' rounding both matter, and the bright pass keeps a good share."""
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.0, 1.3, size=(29, 37, 3))
    ys, xs = rng.integers(0, 29, 12), rng.integers(0, 37, 12)
    img[ys, xs] = rng.uniform(3.0, 40.0, size=(12, 3))
    return img.astype(np.float32)


@pytest.mark.parametrize("storage", ["r11g11b10", "rgba8"])
@pytest.mark.parametrize("seed", [20261130, 11])
def test_gaussian_with_every_stage_stored_equals_numpy(storage, seed):
    img = scene(seed)
    threshold = 0.6
    got = stages_of(img, "--storage", storage, "--threshold", str(threshold), "--precision", "f64",
                    "--plan", "full")
    unstored = gaussian(img.astype(np.float64), np.float32(threshold), got)
    assert set(unstored) <= set(got), sorted(got)
    for name, u in unstored.items():
        g, w = got[name], STORE[storage](u)
        # Equal to the stored value, but where the value before the store lies within 1e-5 of
        # a tie between two stored values: the seed's weights (summing to 0.9999994) taken as
        # given here and in whatever order bloomref sums them may put it on either side. Those
        # are one stored step apart.
        off = np.abs(g - w)
        bad = off > 1e-6 * np.maximum(np.abs(w), 2.0 ** -14)
        tie = np.abs(u - (g + w) / 2) <= 1e-5 * np.maximum(np.abs(u), 2.0 ** -14)
        step = np.maximum(np.abs(w) / 32.0, 2.0 ** -19) if storage == "r11g11b10" else 1 / 255
        assert np.all(tie[bad]), (storage, name, int(bad.sum()), float(off.max()))
        assert np.all((off <= step * 1.0001)[bad]), (storage, name)
        assert bad.sum() <= 0.01 * bad.size, (storage, name, int(bad.sum()))
    # The storage is exercised: an 8-bit scene clamps values above 1; a packed one has no
    # finer values than its mantissa holds.
    if storage == "rgba8":
        assert img.max() > 1 and got["input"].max() <= 1.0
        assert np.allclose(got["blur.10"] * 255, np.round(got["blur.10"] * 255), atol=1e-4)
    else:
        assert not np.array_equal(got["input"], img.astype(np.float64))
    assert got["blur.10"].max() > 0


@pytest.mark.parametrize("storage", ["r11g11b10", "rgba8"])
@pytest.mark.parametrize("options", [["--method", "gaussian", "--threshold", "0.5"],
                                     ["--method", "gaussian", "--kernel", "linear5",
                                      "--threshold", "0.3"],
                                     ["--method", "gaussian", "--gl-shaders", "compute",
                                      "--threshold", "0.5"],
                                     ["--method", "mip", "--threshold", "0.5"],
                                     ["--preset", "bevy"],
                                     ["--preset", "unity-urp", "--threshold", "0.5"],
                                     ["--preset", "threejs-unrealbloompass"]],
                         ids=["gaussian", "linear5", "compute", "mip", "bevy", "unity-urp",
                              "threejs"])
def test_gl_with_every_stage_stored_passes_compare(tmp_path, storage, options):
    code, out, err = run(["compare", "--scene", "demo", "--size", SIZE, *options, "--storage",
                          storage, "--json", "c.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0 and "verdict PASS" in out, out + err
    stages = json.loads((tmp_path / "c.json").read_text())["stages"]
    # The device's stages are its own stores: somewhere not the oracle's values exactly.
    assert max(s["isolated"]["max_abs"] for s in stages) > 0


def test_packed_storage_refuses_to_propagate_nan(tmp_path):
    """R11F_G11F_B10F holds NaN as the device chooses (llvmpipe: 0): kept NaN would be judged
    against a value no device promises."""
    code, out, err = run(["run", "--scene", "demo", "--size", "64x48", "--storage", "r11g11b10",
                          "--nonfinite", "propagate", "-o", "x.exr"], tmp_path)
    assert code == 2 and "--nonfinite zero or clamp" in err, out + err
    assert not (tmp_path / "x.exr").exists()


def test_the_articles_fused_final_pass_refuses_8bit_storage(tmp_path):
    code, out, err = run(["compare", "--scene", "demo", "--size", SIZE, "--preset",
                          "learnopengl-pbb", "--storage", "rgba8"], tmp_path)
    gl_or_skip(code, err)
    assert code == 2 and "--final-target rgba8" in err, out + err


def test_vulkan_runs_presets_and_refuses_its_own_pipeline(tmp_path):
    args = ["compare", "--backend", "vulkan", "--scene", "demo", "--size", SIZE]
    code, out, err = run(args + ["--preset", "bevy", "--storage", "r11g11b10"], tmp_path,
                         timeout=600)
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())
    assert code == 0 and "verdict PASS" in out, out + err
    code, out, err = run(args + ["--storage", "rgba8", "--threshold", "0.5"], tmp_path)
    assert code == 2 and "f32 or f16" in err, out + err


def dump(tmp_path, name, *options):
    d = tmp_path / name
    code, _, err = run(["run", "--scene", "demo", "--size", SIZE, "--threshold", "0.5", "-q",
                        "-o", str(tmp_path / (name + ".exr")), "--dump-stages", str(d), *options],
                       tmp_path)
    assert code == 0, err
    return d


def judged(tmp_path, folder, keep, name, *declared):
    sub = tmp_path / name
    sub.mkdir()
    for f in folder.iterdir():
        if keep is None or f.stem in keep:
            (sub / f.name).write_bytes(f.read_bytes())
    code, o, err = run(["check", "--scene", "demo", "--size", SIZE, "--threshold", "0.5",
                        *declared, "--stages", str(sub), "--json", str(sub / "r.json"), "-q"],
                       tmp_path)
    assert code in (0, 1), err
    return json.loads((sub / "r.json").read_text())["items"][0]


def test_an_8bit_blur_too_strong_fails_named_and_is_not_passed_in_part(tmp_path):
    """Every pass from blur.3 on 5% too strong (weights summing to 1.05), written back as 8-bit
    codes: with every stage captured it fails at blur.3 with the weight sum fitted around 1.05;
    with only the last pass and the output captured it is not passed (the 8-bit bounds carried
    through nine passes are too wide to see 5%: a weak verdict, which says so)."""
    eight = dump(tmp_path, "eight", "--storage", "rgba8")
    for k in range(3, 11):
        f = eight / f"blur.{k}.exr"
        write_exr(str(f), unorm8(read_rgb(str(f)) * 1.05).astype(np.float32))
    item = judged(tmp_path, eight, None, "strong", "--storage", "rgba8")
    cli_support.assert_fails_where_planted(item, "blur.3", ("weight-sum",), 1.05)
    part = judged(tmp_path, eight, ["blur.10", "output"], "strong-part", "--storage", "rgba8")
    assert part["verdict"] != "PASS", json.dumps(part["stages"])[:2000]
    assert part["verdict"] == "FAIL" or part["sensitivity"]["weak"], json.dumps(part)[:2000]


def test_captures_pass_as_stored_and_fail_as_another_storage(tmp_path):
    eight = dump(tmp_path, "eight", "--storage", "rgba8")
    half = dump(tmp_path, "half", "--storage", "f16")
    packed = dump(tmp_path, "packed", "--storage", "r11g11b10")
    assert judged(tmp_path, eight, None, "ok8", "--storage", "rgba8")["verdict"] == "PASS"
    assert judged(tmp_path, packed, None, "ok11", "--storage", "r11g11b10")["verdict"] == "PASS"
    # The scene's HDR values clamped by an 8-bit target (named), or kept by a half one: the
    # input.
    for folder, declared, name, cause in ((eight, "f16", "8-as-16", ("rgba8-storage",)),
                                          (half, "rgba8", "16-as-8", ("none",))):
        item = judged(tmp_path, folder, None, name, "--storage", declared)
        cli_support.assert_fails_where_planted(item, "input", cause)
        # With only the last pass and the output captured: still FAIL.
        part = judged(tmp_path, folder, ["blur.10", "output"], name + "-part", "--storage", declared)
        assert part["verdict"] == "FAIL", json.dumps(part["stages"])[:2000]
    # Packed floats judged as half ones are coarser than a half's rounding allows.
    item = judged(tmp_path, packed, None, "11-as-16", "--storage", "f16")
    cli_support.assert_fails_where_planted(item, "input", ("r11g11b10-storage",))
    # Half stages judged as packed floats are finer than the packed format's rounding: a device
    # that stores more precisely than declared is not wrong.
    assert judged(tmp_path, half, None, "16-as-11", "--storage", "r11g11b10")["verdict"] == "PASS"


SHADERS = Path(__file__).resolve().parents[2] / "data" / "bugs" / "shaders"


@pytest.mark.parametrize("storage", ["f16", "r11g11b10"])
def test_the_tutorials_layout_runs_a_users_shaders_with_packed_targets(tmp_path, storage):
    """The tutorial's scene pass (MRT) computes its bright image from the colour before its
    target stores it: with packed targets, whose rounding (1/64) moves texels across the
    threshold, the user's correct shaders still pass. 8-bit targets are refused: the final pass
    stores no composite for them to clamp."""
    shaders = ["--shaders", "learnopengl", "--bright-fs", str(SHADERS / "bright.fs"),
               "--blur-fs", str(SHADERS / "blur.fs"), "--final-fs", str(SHADERS / "final.fs")]
    code, out, err = run(["check", "--scene", "demo", "--size", SIZE, *shaders, "--storage",
                          storage, "--json", "r.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["verdict"] in ("PASS", "WARN") and item["first_divergent_stage"] is None, out
    code, out, err = run(["check", "--scene", "demo", "--size", SIZE, *shaders, "--storage",
                          "rgba8"], tmp_path)
    assert code == 2 and "--final-target rgba8" in err, out + err
