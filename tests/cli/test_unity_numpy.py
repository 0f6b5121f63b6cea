"""bloomref's CPU reference of Unity URP's bloom (preset unity-urp) against an independent numpy
computation written from Unity's sources (Unity-Technologies/Graphics at 032e79e,
com.unity.render-pipelines.universal/: Shaders/PostProcessing/Bloom.shader for the passes,
Runtime/Passes/PostProcessPass.cs SetupBloom for the sizes, the pass order and the constants,
Shaders/PostProcessing/UberPost.shader for where the bloom meets the scene).

Nothing here is derived from bloomref's output: every expected image is computed by numpy from the
input image alone. Unity computes its constants on the CPU in f32 (threshold, knee, scatter) and
the shader's literals are floats, so the f64 truth uses their float32 values. The levels are kept
in f32 here (--storage f32 --chain-storage f32): the comparison is of the arithmetic, not of
B10G11R11's rounding.
"""

import math

import numpy as np
import pytest

import test_bevy_numpy
from test_bevy_numpy import lookup
from test_variants_numpy import F32, centres, check_constants, check_images, random_hdr

# SetupBloom with the Volume's defaults: threshold GammaToLinearSpace(0.9), knee threshold x 0.5,
# clamp 65472, scatter Mathf.Lerp(0.05, 0.95, 0.7); intensity 1 (the preset's choice).
THRESHOLD = F32(((0.9 + 0.055) / 1.055) ** 2.4)
KNEE = THRESHOLD * F32(0.5)
CLAMP = F32(65472.0)
SCATTER = F32(0.05) + (F32(0.95) - F32(0.05)) * F32(0.7)
EPS = float(F32(1e-4))
H_WEIGHTS = [0.01621622, 0.05405405, 0.12162162, 0.19459459, 0.22702703,
             0.19459459, 0.12162162, 0.05405405, 0.01621622]
V_OFFSETS = [-3.23076923, -1.38461538, 0.0, 1.38461538, 3.23076923]
V_WEIGHTS = [0.07027027, 0.31621622, 0.22702703, 0.31621622, 0.07027027]


def run_bloomref(rgb, extra=()):
    """Runs bloomref's preset unity-urp on rgb (float32 HxWx3): {stage: HxWx3 float64}."""
    return test_bevy_numpy.run_bloomref(rgb, extra, preset="unity-urp")


def level_sizes(w, h):
    """SetupBloom: tw = w >> 1, th = h >> 1; mipCount = Clamp(FloorToInt(Mathf.Log(max, 2) - 1),
    1, 16) with Mathf.Log in double rounded to float; each further mip Max(1, n >> 1)."""
    tw, th = w >> 1, h >> 1
    count = int(math.floor(F32(math.log(max(tw, th)) / math.log(2.0)) - F32(1.0)))
    count = min(max(count, 1), 16)
    sizes = [(tw, th)]
    for _ in range(count - 1):
        tw, th = max(1, tw >> 1), max(1, th >> 1)
        sizes.append((tw, th))
    return sizes


def prefilter(img, tw, th):
    """FragPrefilter: one lookup, min(clamp, colour), the soft threshold."""
    color = np.minimum(lookup(img, centres(tw), centres(th)), float(CLAMP))
    t, k = float(THRESHOLD), float(KNEE)
    b = color.max(axis=-1)
    soft = np.clip(b - t + k, 0.0, 2.0 * k)
    soft = soft * soft / (4.0 * k + EPS)
    return color * (np.maximum(b - t, soft) / np.maximum(b, EPS))[..., None]


def blur_h(src, tw, th):
    """FragBlurH into a tw x th level: nine lookups 2 texels of src apart along x."""
    s, t = centres(tw), centres(th)
    step = 2.0 / src.shape[1]
    return sum(w * lookup(src, s + (i - 4) * step, t) for i, w in enumerate(H_WEIGHTS))


def blur_v(src):
    """FragBlurV on a level of its own size: five lookups along y."""
    th, tw = src.shape[:2]
    s, t = centres(tw), centres(th)
    return sum(w * lookup(src, s, t + o / th) for o, w in zip(V_OFFSETS, V_WEIGHTS))


def pipeline(img, scatter=SCATTER):
    """Every stage of URP's bloom, float64, in bloomref's stage names: down.k is URP's
    _BloomMipDown[k-1], up.k its _BloomMipUp[k-1]."""
    hgt, wid, _ = img.shape
    sizes = level_sizes(wid, hgt)
    st = {"input": img, "down.1": prefilter(img, *sizes[0])}
    for k in range(2, len(sizes) + 1):
        st[f"down.{k}"] = blur_v(blur_h(st[f"down.{k - 1}"], *sizes[k - 1]))
    low = st[f"down.{len(sizes)}"]
    for k in range(len(sizes) - 1, 0, -1):
        high = st[f"down.{k}"]
        tw, th = sizes[k - 1]
        low = high + (lookup(low, centres(tw), centres(th)) - high) * float(scatter)
        st[f"up.{k}"] = low
    st["bloom"] = lookup(low, centres(wid), centres(hgt))
    st["composite"] = img + st["bloom"]
    st["tonemap"] = 1.0 - np.exp(-st["composite"])
    st["output"] = np.power(np.maximum(st["tonemap"], 0.0), 1.0 / float(F32(2.2)))
    return st


CASES = {
    "random37x29": lambda: random_hdr(37, 29, 20261130),
    "random64x48": lambda: random_hdr(64, 48, 3),
    "impulse41x33": lambda: np.pad(np.full((1, 1, 3), (9.0, 3.0, 1.0), dtype=np.float32),
                                   ((15, 17), (20, 20), (0, 0))),
    "random21x130": lambda: random_hdr(21, 130, 11),
}


@pytest.mark.parametrize("precision", ["f64", "f32"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_unity_equals_numpy(case, precision):
    img = CASES[case]()
    got = run_bloomref(img, ["--precision", precision])
    want = pipeline(img.astype(np.float64))
    check_images(got, want, sorted(want), precision == "f64", f"{case} {precision}")


def test_sizes_by_hand():
    """1920x1080: 960 wide at mip 0, log2(960) = 9.9, so 8 mips down to 7x4; 37x29: 18x14,
    log2(18) = 4.17, 3 mips; 64x48: 32x24, log2(32) = 5 exactly, 4 mips."""
    assert level_sizes(1920, 1080) == [(960, 540), (480, 270), (240, 135), (120, 67), (60, 33),
                                       (30, 16), (15, 8), (7, 4)]
    assert level_sizes(37, 29) == [(18, 14), (9, 7), (4, 3)]
    assert len(level_sizes(64, 48)) == 4


def test_soft_threshold_by_hand():
    """b = 3: past the knee, (3 - T) / 3; b = T: mid-knee, knee^2 / (4 knee + 1e-4) / T, about
    1/8; b = T - knee: nothing passes."""
    t, k = float(THRESHOLD), float(KNEE)
    for b, want in ((3.0, (3.0 - t) / 3.0), (t, k * k / (4 * k + 1e-4) / t), (t - k - 1e-3, 0.0)):
        img = np.full((4, 4, 3), (b, b / 2, 0.0))
        got = prefilter(img, 2, 2)[0, 0, 0] / b
        assert got == pytest.approx(want, rel=1e-6, abs=1e-12), (b, got, want)
    assert k * k / (4 * k) / t == pytest.approx(1 / 8, rel=1e-7)  # knee = T / 2


@pytest.mark.parametrize("precision", ["f64", "f32"])
def test_constant_image_closed_form(precision):
    """A constant v (max channel 3): down.1 = v (3 - T) / 3; each further level multiplies by the
    two passes' weight sums (0.99999999 and 1.00000001 as the literals sum); a lerp of equal
    values keeps them, so up.k and the bloom are down.k's, and the composite is v + up.1."""
    v = np.array([3.0, 2.0, 1.5])
    img = np.broadcast_to(v.astype(np.float32), (48, 64, 3)).copy()
    got = run_bloomref(img, ["--precision", precision])
    d1 = v * (3.0 - float(THRESHOLD)) / 3.0
    sh, sv = sum(H_WEIGHTS), sum(V_WEIGHTS)
    assert sh == pytest.approx(0.99999999, abs=1e-12) and sv == pytest.approx(1.00000001, abs=1e-12)
    levels = len(level_sizes(64, 48))
    want = {f"down.{k}": d1 * (sh * sv) ** (k - 1) for k in range(1, levels + 1)}
    want["up.1"] = d1  # lerps of values within 1e-7 of each other
    want["bloom"] = d1
    want["composite"] = v + d1
    check_constants(got, want, 1e-7 if precision == "f64" else 2e-6, precision)


def test_scatter_is_what_is_tested():
    """Another scatter (0.7, the Volume's value before Lerp(0.05, 0.95)) gives an up.1 the
    comparison rejects: the test tells the constants apart."""
    img = CASES["random64x48"]()
    got = run_bloomref(img, ["--precision", "f32"])
    other = pipeline(img.astype(np.float64), scatter=F32(0.7))
    want = pipeline(img.astype(np.float64))
    scale = float(np.max(np.abs(want["up.1"])))
    diff = float(np.max(np.abs(got["up.1"] - other["up.1"])))
    assert diff > 100 * 1e-5 * scale, f"up.1 differs from scatter 0.7's by only {diff:.3e}"
