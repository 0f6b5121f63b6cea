"""bloomref's CPU reference of three.js's bloom (preset threejs) against an independent numpy
computation written from three.js's source (mrdoob/three.js at fef3c54,
examples/jsm/tsl/display/BloomNode.js: setSize for the sizes, updateBefore for the pass order,
luminosityHighPass, _getSeparableBlurMaterial and compositePass for the passes).

Nothing here is derived from bloomref's output: every expected image is computed by numpy from
the input image alone. three.js computes its blur coefficients in JavaScript (double) and uploads
them as float32 uniforms, and the shader's constants (1.2, the threshold plus smoothWidth) are
float32, so the f64 truth uses their float32 values. The levels are kept in f32 here (--storage
f32 --chain-storage f32): the comparison is of the arithmetic, not of HalfFloat's rounding.
"""

import math

import numpy as np
import pytest

import test_bevy_numpy
from test_bevy_numpy import lookup
from test_variants_numpy import F32, centres, check_images, random_hdr

KERNELS = [6, 10, 14, 18, 22]          # kernelSizeArray
FACTORS = [1.0, 0.8, 0.6, 0.4, 0.2]    # bloomFactors
THRESHOLD, SMOOTH_WIDTH, RADIUS, STRENGTH = 0.0, 0.01, 0.0, 1.0  # the constructor's defaults
LUMA709 = np.array([0.2126, 0.7152, 0.0722])


def run_bloomref(rgb, extra=()):
    return test_bevy_numpy.run_bloomref(rgb, extra, preset="threejs")


def js_round_half(n):
    """Math.round(n / 2) for a positive integer n: halves round up."""
    return int(math.floor(n / 2 + 0.5))


def level_sizes(w, h, mips=5):
    """setSize: the bright target and mip 0 at (round(w / 2), round(h / 2)), each next mip
    round(n / 2): [bright, mip 0, .., mip 4]."""
    rx, ry = js_round_half(w), js_round_half(h)
    out = [(rx, ry)]
    for _ in range(mips):
        out.append((rx, ry))
        rx, ry = js_round_half(rx), js_round_half(ry)
    return out


def coefficients(radius, sigma=None, normalise=False):
    """_getSeparableBlurMaterial: 0.39894 * exp(-0.5 i^2 / sigma^2) / sigma, sigma = R / 3 (or
    the one given), as float32 uniforms; `normalise`: each divided by c_0 + 2 (c_1 + ...) in
    double first (UnrealBloomPass's weightSum, folded into the uniforms as bloomref does)."""
    sigma = radius / 3 if sigma is None else sigma
    w = [0.39894 * math.exp(-0.5 * i * i / (sigma * sigma)) / sigma for i in range(radius)]
    total = math.fsum([w[0]] + [2 * v for v in w[1:]]) if normalise else 1.0
    return [float(F32(v / total)) for v in w]


def high_pass(img, tw, th, threshold=THRESHOLD, luma=LUMA709):
    """luminosityHighPass: the lookup times smoothstep(t, t + smoothWidth, luminance)."""
    texel = lookup(img, centres(tw), centres(th))
    e0 = float(F32(threshold))
    e1 = float(F32(threshold) + F32(SMOOTH_WIDTH))
    t = np.clip((texel @ luma - e0) / (e1 - e0), 0.0, 1.0)
    return texel * (t * t * (3.0 - 2.0 * t))[..., None]


def blur(src, tw, th, radius, horizontal, sigma=None, normalise=False):
    """One separable pass into a tw x th target: taps at +-i / (the target's size)."""
    c = coefficients(radius, sigma, normalise)
    s, t = centres(tw), centres(th)

    def tap(i):
        return lookup(src, s + i / tw, t) if horizontal else lookup(src, s, t + i / th)

    out = tap(0) * c[0]
    for i in range(1, radius):
        out = out + (tap(i) + tap(-i)) * c[i]
    return out


def factor(f, radius=RADIUS):
    """lerpBloomFactor in float32: mix(f, 1.2 - f, radius)."""
    f, r = F32(f), F32(radius)
    return float(f * (F32(1) - r) + (F32(1.2) - f) * r)


def pipeline(img, threshold=THRESHOLD, sigmas=None, kernels=KERNELS, normalise=False,
             luma=LUMA709, radius=RADIUS, store=lambda x: x):
    """The whole chain; `store` is what each stored level goes through (its target's format)."""
    hgt, wid, _ = img.shape
    sizes = level_sizes(wid, hgt)
    st = {"input": img, "down.1": store(high_pass(img, *sizes[0], threshold, luma))}
    prev = st["down.1"]
    for k in range(1, len(sizes)):
        tw, th = sizes[k]
        sigma = sigmas[k - 1] if sigmas else None
        h = store(blur(prev, tw, th, kernels[k - 1], True, sigma, normalise))
        prev = store(blur(h, tw, th, kernels[k - 1], False, sigma, normalise))
        st[f"down.{k + 1}"] = prev
    s0 = sizes[0]
    up = sum(factor(FACTORS[i], radius) * lookup(st[f"down.{i + 2}"], centres(s0[0]),
                                                  centres(s0[1]))
             for i in range(5))
    st["up.1"] = store(up * STRENGTH)
    st["bloom"] = lookup(st["up.1"], centres(wid), centres(hgt))
    st["composite"] = img + st["bloom"]
    st["tonemap"] = 1.0 - np.exp(-st["composite"])
    st["output"] = np.power(np.maximum(st["tonemap"], 0.0), 1.0 / float(F32(2.2)))
    return st


def dim(w, h, seed):
    """Values whose luminance lies across the smoothstep's ramp (0 .. 0.01) and above it."""
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, 0.03, size=(h, w, 3)).astype(np.float32)


CASES = {
    "random37x29": lambda: random_hdr(37, 29, 20261130),
    "random64x48": lambda: random_hdr(64, 48, 3),
    "dim45x31": lambda: dim(45, 31, 5),
    "impulse41x33": lambda: np.pad(np.full((1, 1, 3), (9.0, 3.0, 1.0), dtype=np.float32),
                                   ((15, 17), (20, 20), (0, 0))),
}


@pytest.mark.parametrize("precision", ["f64", "f32"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_threejs_equals_numpy(case, precision):
    img = CASES[case]()
    got = run_bloomref(img, ["--precision", precision])
    want = pipeline(img.astype(np.float64))
    check_images(got, want, sorted(want), precision == "f64", f"{case} {precision}")


def test_sizes_by_hand():
    # 203 / 2 = 101.5 rounds to 102; 102, 51, 26, 13; 131 -> 66, 66, 33, 17, 9.
    assert level_sizes(203, 131) == [(102, 66), (102, 66), (51, 33), (26, 17), (13, 9), (7, 5)]
    img = random_hdr(203, 131, 1)
    got = run_bloomref(img)
    for k, (w, h) in enumerate(level_sizes(203, 131), start=1):
        assert got[f"down.{k}"].shape == (h, w, 3), k
    assert got["up.1"].shape == (66, 102, 3)


def test_constant_image_closed_form():
    """A constant scene stays constant through clamp-to-edge lookups: each pass multiplies it by
    its coefficients' sum (c_0 + 2 (c_1 + ...), not normalised), so mip k holds v x S_1^2 ..
    S_k^2, and up.1 = v x sum_k F_k S_1^2 .. S_k^2 (F_k the factors: 1.0 .. 0.2 at radius 0)."""
    v = np.array([2.0, 1.0, 0.5])
    img = np.broadcast_to(v, (24, 40, 3)).astype(np.float32)
    got = run_bloomref(img, ["--precision", "f64"])
    sums = [math.fsum([coefficients(r)[0]] + [2 * c for c in coefficients(r)[1:]]) for r in KERNELS]
    # The coefficients' sums: the normal density sampled at the integers and cut below 3 sigma,
    # 0.34% (R = 22) to 0.55% (R = 6) short of 1.
    assert all(0.994 < s < 0.997 for s in sums), sums
    gain, total = 1.0, 0.0
    for k, s in enumerate(sums):
        gain *= s * s
        assert np.allclose(got[f"down.{k + 2}"], v * gain, rtol=1e-6, atol=0), k
        total += [1.0, 0.8, 0.6, 0.4, 0.2][k] * gain
    assert np.allclose(got["up.1"], v * total, rtol=1e-6, atol=0)
    assert 2.9 < total < 3.0  # 1 + 0.8 + 0.6 + 0.4 + 0.2, less what the kernels lose (2%)


def test_radius_and_strength_are_what_is_tested():
    """The factors mirror about 0.6 as the radius goes to 1 (1.0 -> 0.2), and the strength scales
    the sum: checked against numpy with both changed."""
    img = random_hdr(37, 29, 9)
    got = run_bloomref(img, ["--precision", "f64", "--level-radius", "1", "--level-strength",
                             "0.5"])
    want = pipeline(img.astype(np.float64))
    sizes = level_sizes(37, 29)
    mirrored = sum(factor(FACTORS[i], 1.0) * lookup(want[f"down.{i + 2}"], centres(sizes[0][0]),
                                                     centres(sizes[0][1])) for i in range(5))
    assert factor(1.0, 1.0) == pytest.approx(0.2, abs=1e-7)
    assert np.allclose(got["up.1"], mirrored * 0.5, rtol=1e-6, atol=1e-12)
    assert not np.allclose(got["up.1"], want["up.1"], rtol=1e-2)


def test_given_sigmas_equal_numpy():
    """--level-sigmas: a sigma per mip instead of R / 3 (a blur of a given sigma)."""
    img = random_hdr(37, 29, 13)
    sigmas = [1.0, 2.5, 3.0, 4.0, 9.0]
    got = run_bloomref(img, ["--precision", "f64", "--level-sigmas", ",".join(map(str, sigmas))])
    want = pipeline(img.astype(np.float64), sigmas=sigmas)
    check_images(got, want, sorted(want), True, "sigmas")
    default = pipeline(img.astype(np.float64))
    assert not np.allclose(want["down.2"], default["down.2"], rtol=1e-3)
