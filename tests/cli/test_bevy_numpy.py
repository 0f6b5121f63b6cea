"""bloomref's CPU reference of Bevy's bloom (preset bevy) against an independent numpy computation
written from Bevy's sources (bevyengine/bevy at 4805ca7, crates/bevy_post_process/src/bloom/:
bloom.wesl for the passes, mod.rs for the texture sizes, the pass order and compute_blend_factor,
settings.rs for Bloom::NATURAL, upsampling_pipeline.rs for the blend state).

Nothing here is derived from bloomref's output: every expected image is computed by numpy from the
input image alone. Bevy computes the texture size and the blend constants on the CPU in f32; numpy
does so in float32 too. The shader literals (Rec. 709 weights, 0.0001, 3.40282347e37) are f32, so
the f64 truth uses their float32 values. Levels and the view are kept in f32 here (--storage f32
--chain-storage f32): the comparison is of the arithmetic, not of Rg11b10Ufloat's rounding.
"""

import numpy as np
import pytest

from test_variants_numpy import (F32, F32_REL, centres, check_constants, check_images,
                                 random_hdr, stages_of)

INTENSITY = F32(0.15)
LF_BOOST, LF_CURVATURE, HIGH_PASS = F32(0.7), F32(0.95), F32(1.0)
MAX_MIP_DIMENSION = 512
MIP_COUNT = 8  # ilog2(512).max(2) - 1
LUMA709 = np.array([F32(0.2126), F32(0.7152), F32(0.0722)], dtype=np.float64)
EXPOSURE, GAMMA = float(F32(1.0)), float(F32(2.2))

# Bloom::OLD_SCHOOL (settings.rs): intensity 0.05, threshold 0.6, threshold_softness 0.2,
# BloomCompositeMode::Additive.
OLD_INTENSITY, OLD_THRESHOLD, OLD_SOFTNESS = F32(0.05), F32(0.6), F32(0.2)


def run_bloomref(rgb, extra=(), preset="bevy"):
    """Runs bloomref's `preset` on rgb (float32 HxWx3), levels and view in f32, and returns
    {stage: HxWx3 float64}."""
    return stages_of(rgb, "--preset", preset, "--storage", "f32", "--chain-storage", "f32", *extra)


def axis(coords, n):
    """GL_LINEAR with clamp-to-edge along one axis: the two texels and their weights."""
    u = np.asarray(coords, dtype=np.float64) * n - 0.5
    i = np.floor(u)
    a = u - i
    i = i.astype(np.int64)
    return np.clip(i, 0, n - 1), np.clip(i + 1, 0, n - 1), a


def lookup(img, s, t):
    """Bilinear lookups of img (h x w x 3) at every (s[x], t[y]) -> len(t) x len(s) x 3."""
    x0, x1, ax = axis(s, img.shape[1])
    y0, y1, ay = axis(t, img.shape[0])
    rows = img[y0] * (1.0 - ay)[:, None, None] + img[y1] * ay[:, None, None]
    return rows[:, x0] * (1.0 - ax)[None, :, None] + rows[:, x1] * ax[None, :, None]


def rust_round(v):
    """f32::round: half away from zero."""
    return int(np.floor(abs(v) + 0.5)) * (1 if v >= 0 else -1)


def texture_sizes(w, h):
    """prepare_bloom_textures: (viewport * (512 / viewport.y)).round().max(1), then >> mip."""
    ratio = F32(MAX_MIP_DIMENSION) / F32(h)
    w0 = max(1, rust_round(F32(w) * ratio))
    h0 = max(1, rust_round(F32(h) * ratio))
    return [(max(1, w0 >> k), max(1, h0 >> k)) for k in range(MIP_COUNT)]


def blend_factor(mip, max_mip, energy_conserving=True, intensity=INTENSITY):
    """compute_blend_factor, in float32 as Bevy's host code computes it."""
    x = F32(mip) / F32(max_mip)
    lf = (F32(1.0) - np.power(F32(1.0) - x, F32(1.0) / (F32(1.0) - LF_CURVATURE))) * LF_BOOST
    hp = F32(1.0) - np.clip((x - HIGH_PASS) / HIGH_PASS, F32(0.0), F32(1.0))
    if energy_conserving:
        lf = lf * (F32(1.0) - intensity)
    return float((intensity + lf) * hp)


def taps13(src, tw, th):
    """The 13 lookups of sample_input_13_tap, offsets in texels of src (UNIFORM_SCALE path)."""
    s, t = centres(tw), centres(th)
    dx, dy = 1.0 / src.shape[1], 1.0 / src.shape[0]

    def tap(i, j):
        return lookup(src, s + i * dx, t + j * dy)

    return dict(a=tap(-2, 2), b=tap(0, 2), c=tap(2, 2), d=tap(-2, 0), e=tap(0, 0),
                f=tap(2, 0), g=tap(-2, -2), h=tap(0, -2), i=tap(2, -2), j=tap(-1, 1),
                k=tap(1, 1), l=tap(-1, -1), m=tap(1, -1))


def downsample_first(src, tw, th):
    q = taps13(src, tw, th)
    groups = [(q["a"] + q["b"] + q["d"] + q["e"]) * (0.125 / 4),
              (q["b"] + q["c"] + q["e"] + q["f"]) * (0.125 / 4),
              (q["d"] + q["e"] + q["g"] + q["h"]) * (0.125 / 4),
              (q["e"] + q["f"] + q["h"] + q["i"]) * (0.125 / 4),
              (q["j"] + q["k"] + q["l"] + q["m"]) * (0.5 / 4)]
    total = sum(g * (1.0 / (1.0 + (g @ LUMA709) / 4.0))[..., None] for g in groups)
    return np.clip(total, float(F32(0.0001)), float(F32(3.40282347e37)))


def soft_threshold(color):
    """bloom.wesl soft_threshold with OLD_SCHOOL's precomputations (settings.rs,
    extract_component: knee = threshold x softness, in f32)."""
    knee = OLD_THRESHOLD * OLD_SOFTNESS
    x, y = float(OLD_THRESHOLD), float(OLD_THRESHOLD - knee)
    z, w = float(F32(2.0) * knee), float(F32(0.25) / (knee + F32(0.00001)))
    brightness = color.max(axis=-1)
    softness = np.clip(brightness - y, 0.0, z)
    softness = softness * softness * w
    contribution = np.maximum(brightness - x, softness) / np.maximum(brightness, float(F32(0.00001)))
    return color * contribution[..., None]


def downsample(src, tw, th):
    q = taps13(src, tw, th)
    return ((q["a"] + q["c"] + q["g"] + q["i"]) * 0.03125
            + (q["b"] + q["d"] + q["f"] + q["h"]) * 0.0625
            + (q["e"] + q["j"] + q["k"] + q["l"] + q["m"]) * 0.125)


def tent(small, tw, th):
    """sample_input_3x3_tent: taps one texel of `small` apart."""
    s, t = centres(tw), centres(th)
    dx, dy = 1.0 / small.shape[1], 1.0 / small.shape[0]
    out = np.zeros((th, tw, 3))
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            out += (4 >> (abs(i) + abs(j))) / 16.0 * lookup(small, s + i * dx, t + j * dy)
    return out


def pipeline(img, old_school=False):
    """Every stage of Bevy's bloom, float64, in bloomref's stage names: down.k is Bevy's mip k-1
    after the downsamples, up.k that mip after the upsample blended into it. old_school: the
    OLD_SCHOOL settings (the soft threshold, additive blending)."""
    hgt, wid, _ = img.shape
    sizes = texture_sizes(wid, hgt)
    st = {"input": img}
    src = img
    for k, (tw, th) in enumerate(sizes, start=1):
        src = downsample_first(src, tw, th) if k == 1 else downsample(src, tw, th)
        if k == 1 and old_school:
            src = soft_threshold(src)
        st[f"down.{k}"] = src
    # for mip in (1..mip_count).rev(): draw mip into mip - 1, blend constant C(mip), dst (1 - C)
    # (EnergyConserving) or dst (Additive)
    intensity = OLD_INTENSITY if old_school else INTENSITY
    keep = (lambda c: 1.0) if old_school else (lambda c: 1.0 - c)
    up = st[f"down.{MIP_COUNT}"]
    for mip in range(MIP_COUNT - 1, 0, -1):
        tw, th = sizes[mip - 1]
        c = blend_factor(mip, MIP_COUNT - 1, not old_school, intensity)
        up = tent(up, tw, th) * c + st[f"down.{mip}"] * keep(c)
        st[f"up.{mip}"] = up
    st["bloom"] = tent(up, wid, hgt)
    c0 = blend_factor(0, MIP_COUNT - 1, not old_school, intensity)
    st["composite"] = st["bloom"] * c0 + img * keep(c0)
    st["tonemap"] = 1.0 - np.exp(-st["composite"] * EXPOSURE)
    st["output"] = np.power(np.maximum(st["tonemap"], 0.0), 1.0 / GAMMA)
    return st


def check_stages(got, want, f64, label):
    check_images(got, want, sorted(want), f64, label)


# Wider and narrower than the 512-high first level, and one taller than it (a true downsample).
CASES = {
    "random37x29": lambda: random_hdr(37, 29, 20261129),
    "random61x23": lambda: random_hdr(61, 23, 5),
    "impulse40x30": lambda: np.pad(np.full((1, 1, 3), (9.0, 3.0, 1.0), dtype=np.float32),
                                   ((12, 17), (25, 14), (0, 0))),
    "random33x600": lambda: random_hdr(33, 600, 77),
}


@pytest.mark.parametrize("precision", ["f64", "f32"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_bevy_equals_numpy(case, precision):
    img = CASES[case]()
    got = run_bloomref(img, ["--precision", precision])
    check_stages(got, pipeline(img.astype(np.float64)), precision == "f64", f"{case} {precision}")


@pytest.mark.parametrize("precision", ["f64", "f32"])
@pytest.mark.parametrize("case", ["random37x29", "random33x600"])
def test_old_school_equals_numpy(case, precision):
    img = CASES[case]()
    got = run_bloomref(img, ["--precision", precision], preset="bevy-old-school")
    check_stages(got, pipeline(img.astype(np.float64), old_school=True), precision == "f64",
                 f"{case} old-school {precision}")


def test_soft_threshold_by_hand():
    """threshold 0.6, knee 0.12: below 0.48 nothing passes; at 0.54 (mid-knee) the quadratic
    (0.06^2 / 0.48 = 0.0075, over 0.54); above 0.72 the hard part (b - 0.6) / b."""
    for b, want in ((0.3, 0.0), (0.54, 0.06 ** 2 / 0.48 / 0.54), (2.0, 1.4 / 2.0)):
        got = soft_threshold(np.array([[b, b / 2, 0.0]]))[0, 0] / b
        assert got == pytest.approx(want, rel=1e-4), (b, got, want)


def test_sizes_and_constants_by_hand():
    """The texture sizes and blend constants, by hand: 37x29 gives round(37 x 512 / 29) = 653
    wide; the constants at mip 0 and the last mip are closed forms of compute_blend_factor."""
    assert texture_sizes(37, 29)[0] == (653, 512)
    assert texture_sizes(1920, 1080)[:2] == [(910, 512), (455, 256)]
    # mip 0: (1 - 1^20) = 0, so C = intensity; the last mip: (1 - 0^20) = 1, C = 0.15 + 0.7 x 0.85
    assert blend_factor(0, 7) == pytest.approx(0.15, abs=1e-7)
    assert blend_factor(7, 7) == pytest.approx(0.15 + 0.7 * 0.85, abs=1e-6)


@pytest.mark.parametrize("precision", ["f64", "f32"])
def test_constant_image_closed_form(precision):
    """A constant v: each group is v g (g its weight), times 1 / (1 + g L / 4); the later levels
    and the tent keep a constant, and each blend C x + (1 - C) x keeps it, so every level and the
    bloom equal down.1 and the composite is 0.85 v + 0.15 down.1."""
    v = np.array([3.0, 2.0, 1.5])
    img = np.broadcast_to(v.astype(np.float32), (29, 37, 3)).copy()
    got = run_bloomref(img, ["--precision", precision])
    lum = float(v @ LUMA709)
    d1 = 4 * (v * 0.125) / (1 + 0.125 * lum / 4) + (v * 0.5) / (1 + 0.5 * lum / 4)
    want = {f"down.{k}": d1 for k in range(1, MIP_COUNT + 1)}
    want.update({f"up.{k}": d1 for k in range(1, MIP_COUNT)})
    want["bloom"] = d1
    want["composite"] = 0.85 * v + 0.15 * d1
    check_constants(got, want, 1e-7 if precision == "f64" else 2e-6, precision)


def test_blend_constants_are_what_is_tested():
    """Bevy's additive mode's constants (lf boost not scaled by 1 - intensity) give up levels the
    comparison rejects: the test tells the constants apart."""
    img = CASES["random37x29"]()
    got = run_bloomref(img, ["--precision", "f32"])
    want = pipeline(img.astype(np.float64))
    hgt, wid, _ = img.shape
    sizes = texture_sizes(wid, hgt)
    c = blend_factor(3, MIP_COUNT - 1, energy_conserving=False)
    other = tent(want["up.4"], *sizes[2]) * c + want["down.3"] * (1.0 - c)
    scale = float(np.max(np.abs(want["up.3"])))
    diff = float(np.max(np.abs(got["up.3"] - other)))
    assert diff > 100 * F32_REL * scale, f"up.3 differs from the other constants by only {diff:.3e}"
