"""--chain-storage rgba8: the mip chain's levels stored as 8-bit normalised colour (GL_RGBA8), as
blooms drawn into LDR targets store them.

- The CPU reference against an independent numpy computation of Unity URP's chain (the passes of
  tests/cli/test_unity_numpy.py) with every stored level clamped to [0, 1] and rounded to the
  nearest 255th (GL 4.6, 2.3.5.2), nothing derived from bloomref's output.
- Every level bloomref dumps is in 255ths within [0, 1]; the stages after the chain are not.
- compare: bloomref's GL shaders of three presets' chains with 8-bit levels pass on llvmpipe, and
  on Vulkan (lavapipe) through the presets' descriptions.
- check: a capture whose levels are float, judged as 8-bit (and the other way round), fails at
  the first level, also with only some stages captured; a level 5% too bright in an 8-bit
  capture fails there.
The GL and Vulkan cases skip without a device (exit 3) unless BLOOMREF_REQUIRE_GL=1 /
BLOOMREF_REQUIRE_VULKAN=1.
"""
import json
import os

import numpy as np
import pytest

import cli_support
from cli_support import gl_or_skip, run
from test_bevy_numpy import lookup
from test_unity_numpy import SCATTER, blur_h, blur_v, level_sizes, prefilter
from test_variants_numpy import centres, random_hdr, read_rgb, stages_of, write_exr

SIZE = "203x131"
Q = 1.0 / 255.0


def unorm8(x):
    """An RGBA8 write: clamped to [0, 1], the nearest 255th (ties away from zero), NaN as 0."""
    x = np.nan_to_num(np.asarray(x, dtype=np.float64), nan=0.0)
    return np.floor(np.clip(x, 0.0, 1.0) * 255.0 + 0.5) / 255.0


def unity_rgba8(img):
    """URP's chain (test_unity_numpy.pipeline) with its stored targets 8-bit: the prefilter's
    mip, each horizontal pass's temporary, each mip and each upsample."""
    hgt, wid, _ = img.shape
    sizes = level_sizes(wid, hgt)
    st = {"down.1": unorm8(prefilter(img, *sizes[0]))}
    for k in range(2, len(sizes) + 1):
        tmp = unorm8(blur_h(st[f"down.{k - 1}"], *sizes[k - 1]))
        st[f"down.{k}"] = unorm8(blur_v(tmp))
    low = st[f"down.{len(sizes)}"]
    for k in range(len(sizes) - 1, 0, -1):
        high = st[f"down.{k}"]
        tw, th = sizes[k - 1]
        low = unorm8(high + (lookup(low, centres(tw), centres(th)) - high) * float(SCATTER))
        st[f"up.{k}"] = low
    st["bloom"] = lookup(low, centres(wid), centres(hgt))
    st["composite"] = img + st["bloom"]
    return st


def dumped(rgb, *options):
    return stages_of(rgb, "--storage", "f32", *options)


@pytest.mark.parametrize("seed", [20261130, 7])
def test_unity_chain_with_8bit_levels_equals_numpy(seed):
    # Values around 1, so that the clamp and the rounding both matter.
    img = (random_hdr(37, 29, seed) * 0.5).astype(np.float32)
    got = dumped(img, "--preset", "unity-urp", "--chain-storage", "rgba8", "--precision", "f64")
    want = unity_rgba8(img.astype(np.float64))
    for name, w in want.items():
        g = got[name]
        # The f64 reference's value of an exact 255th is that 255th rounded to float once.
        bad = np.abs(g - w) > 1e-6 * np.maximum(np.abs(w), 1.0)
        # A value within 1e-9 of a rounding tie may land on either side of it in either
        # computation: at most a handful of such texels, each one 255th apart.
        assert bad.sum() <= 3, (name, int(bad.sum()), float(np.abs(g - w).max()))
        assert np.all(np.abs(g - w)[bad] <= Q * 1.0001 * 20), name
    # The clamp is exercised: some level texels would exceed 1 unstored.
    assert np.max(prefilter(img.astype(np.float64), *level_sizes(37, 29)[0])) > 1.0


def test_levels_are_255ths_and_later_stages_are_not():
    img = random_hdr(64, 48, 3)
    for preset in ("bevy", "learnopengl-pbb", "unity-urp"):
        got = dumped(img, "--preset", preset, "--chain-storage", "rgba8")
        levels = [n for n in got if n.split(".")[0] in ("down", "up")]
        assert len(levels) >= 5, (preset, sorted(got))
        for n in levels:
            v = got[n]
            assert v.min() >= 0.0 and v.max() <= 1.0, (preset, n)
            assert np.allclose(v * 255.0, np.round(v * 255.0), atol=1e-4), (preset, n)
        comp = got["composite"] if "composite" in got else got["output"]
        assert not np.allclose(comp * 255.0, np.round(comp * 255.0), atol=1e-4), preset


@pytest.mark.parametrize("preset", ["bevy", "unity-urp", "learnopengl-pbb"])
def test_gl_with_8bit_levels_passes_compare(tmp_path, preset):
    code, out, err = run(["compare", "--scene", "demo", "--size", SIZE, "--preset", preset,
                          "--chain-storage", "rgba8", "--json", "c.json"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0 and "verdict PASS" in out, out + err
    stages = json.loads((tmp_path / "c.json").read_text())["stages"]
    # The device's levels are its own 8-bit writes: somewhere a 255th from the oracle's.
    assert max(s["isolated"]["max_abs"] for s in stages if s["stage"].startswith("up.")) > 0


def test_vulkan_with_8bit_levels_passes_compare(tmp_path):
    code, out, err = run(["compare", "--backend", "vulkan", "--scene", "demo", "--size", SIZE,
                          "--preset", "bevy", "--chain-storage", "rgba8"], tmp_path, timeout=600)
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())
    assert code == 0 and "verdict PASS" in out, out + err


def judged(tmp_path, folder, keep, name, *declared):
    return cli_support.judged(tmp_path, folder, keep, name, "bevy", SIZE, *declared)


def test_8bit_capture_passes_as_8bit_and_fails_as_float(tmp_path):
    eight = cli_support.dump(tmp_path, "eight", "bevy", SIZE, "--chain-storage", "rgba8")
    assert judged(tmp_path, eight, None, "ok", "--chain-storage", "rgba8")["verdict"] == "PASS"
    item = judged(tmp_path, eight, None, "as-f16")
    assert item["verdict"] == "FAIL" and item["first_divergent_stage"] == "down.1"
    first = [s for s in item["stages"] if s["stage"] == "down.1"][0]
    assert first["cause"]["id"] == "rgba8-storage" and first["cause"]["likely"], first["cause"]
    # Only the last level and the output captured: still FAIL.
    part = judged(tmp_path, eight, ["up.1", "output"], "part-as-f16")
    assert part["verdict"] == "FAIL", json.dumps(part["stages"])[:2000]


def test_float_capture_fails_as_8bit(tmp_path):
    half = cli_support.dump(tmp_path, "half", "bevy", SIZE)
    item = judged(tmp_path, half, None, "as-8", "--chain-storage", "rgba8")
    assert item["verdict"] == "FAIL" and item["first_divergent_stage"] == "down.1"
    part = judged(tmp_path, half, ["up.3", "output"], "part-as-8", "--chain-storage", "rgba8")
    assert part["verdict"] == "FAIL"


def test_a_level_5_percent_too_bright_fails_within_8bit(tmp_path):
    eight = cli_support.dump(tmp_path, "eight", "bevy", SIZE, "--chain-storage", "rgba8")
    path = eight / "up.3.exr"
    v = read_rgb(str(path))
    assert v.max() > 0.2  # bright enough that 5% is several 255ths
    write_exr(str(path), unorm8(v * 1.05).astype(np.float32))
    item = judged(tmp_path, eight, None, "bright", "--chain-storage", "rgba8")
    assert item["verdict"] == "FAIL" and item["first_divergent_stage"] == "up.3"


def test_8bit_levels_with_a_blend_constant_gl_would_clamp_are_refused(tmp_path):
    """GL clamps blend factors to [0, 1] for a fixed-point target (GL 4.6, 17.3.6): Bevy's
    constants with a low-frequency boost of 1.5 reach 1.43, which an 8-bit level cannot blend."""
    code, _, err = run(["run", "--size", "64x48", "-q", "-o", "o.exr", "--preset", "bevy",
                        "--chain-storage", "rgba8", "--low-frequency-boost", "1.5"], tmp_path)
    assert code == 2 and "GL clamps the blend factors" in err, err
    assert not (tmp_path / "o.exr").exists()
    # The same in f16 is judged as it is.
    code, _, err = run(["run", "--size", "64x48", "-q", "-o", "o.exr", "--preset", "bevy",
                        "--low-frequency-boost", "1.5"], tmp_path)
    assert code == 0, err
