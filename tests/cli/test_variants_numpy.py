"""bloomref's CPU reference of LearnOpenGL's "Physically Based Bloom" mip chain (preset
learnopengl-pbb) against an independent numpy computation written from the article's shaders
(src/8.guest/2022/6.physically_based_bloom: 6.new_downsample.fs, 6.new_upsample.fs,
6.bloom_final.fs, physically_based_bloom.cpp).

Nothing here is derived from bloomref's output: every expected image is computed by numpy from the
input image alone.

Conventions taken from the article:
- the uniforms (threshold, strength, exposure, gamma, filterRadius, srcResolution) and the
  shaders' literals (0.299f, 0.587f, 0.114f, 1.0 / 2.2) are GLSL floats, so the f64 truth uses
  their float32 values, computed exactly in double from there;
- the downsample's texel step is 1 / srcResolution, where the host halves a float size per level
  (glm::vec2 mipSize *= 0.5f), while the texture is (int)mipSize wide;
- the upsample is blended additively (GL_ONE, GL_ONE) into the next larger level, which holds
  that level's downsample.

Stage files are float32 EXR, so the f64 run's dumps are the f64 values rounded once to float:
the f64 comparison allows half a float ulp of the expected value on top of a relative 1e-9 of
the stage's maximum (and 1e-12 absolute).
"""

import os
import subprocess
import tempfile

import numpy as np
import OpenImageIO as oiio
import pytest

F32 = np.float32

# Preset learnopengl-pbb, as float32 values (the article's uniforms are floats).
THRESHOLD = float(F32(1.0))
STRENGTH = float(F32(0.04))
EXPOSURE = float(F32(1.0))
GAMMA = float(F32(2.2))
RADIUS = float(F32(0.005))
# 6.new_downsample.fs: const float invGamma = 1.0 / 2.2; Rec. 601 weights as float literals.
KARIS_INV_GAMMA = float(F32(1.0) / F32(2.2))
LUMA601 = np.array([F32(0.299), F32(0.587), F32(0.114)], dtype=np.float64)
LUMA709 = np.array([0.2126, 0.7152, 0.0722])

PBB = ["--preset", "learnopengl-pbb", "--storage", "f32", "--chain-storage", "f32"]

F64_REL = 1e-9
F64_ABS = 1e-12
F32_REL = 1e-5


# --------------------------------------------------------------------------------------------
# bloomref and image files


def bloomref_exe():
    exe = os.environ["BLOOMREF_EXE"]  # set by ctest (tests/CMakeLists.txt)
    assert os.path.isfile(exe), f"bloomref executable not found: {exe}"
    return exe


def write_exr(path, rgb):
    h, w, _ = rgb.shape
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., :3] = rgb
    out = oiio.ImageOutput.create(path)
    assert out is not None, oiio.geterror()
    spec = oiio.ImageSpec(w, h, 4, oiio.FLOAT)
    assert out.open(path, spec), out.geterror()
    assert out.write_image(rgba), out.geterror()
    out.close()


def read_rgb(path):
    inp = oiio.ImageInput.open(path)
    assert inp is not None, f"cannot open {path}: {oiio.geterror()}"
    px = inp.read_image(0, 0, 0, 4, oiio.FLOAT)
    inp.close()
    assert px is not None, f"cannot read {path}"
    return np.asarray(px, dtype=np.float64)[..., :3]


def stages_of(rgb, *options):
    """`bloomref run` of rgb (float32 HxWx3) with `options`: {stage: HxWx3 float64}."""
    with tempfile.TemporaryDirectory(prefix="stages_") as tmp:
        src = os.path.join(tmp, "in.exr")
        write_exr(src, rgb)
        dump = os.path.join(tmp, "stages")
        cmd = [bloomref_exe(), "run", src, *options, "--dump-stages", dump, "-q"]
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, f"{' '.join(cmd)} failed ({res.returncode}): {res.stderr}"
        return {f[:-4]: read_rgb(os.path.join(dump, f)) for f in os.listdir(dump)
                if f.endswith(".exr")}


def run_bloomref(rgb, levels, extra=()):
    """Runs bloomref's article chain on rgb and returns {stage: HxWx3 float64}."""
    return stages_of(rgb, *PBB, "--levels", str(levels), *extra)


# --------------------------------------------------------------------------------------------
# The article's pipeline in numpy (float64)


def level_sizes(w, h, levels):
    return [(max(1, w // 2 ** k), max(1, h // 2 ** k)) for k in range(1, levels + 1)]


def axis_weights(coords, n):
    """GL_LINEAR with clamp-to-edge along one axis: (len(coords) x n) weights."""
    u = coords * n - 0.5
    i = np.floor(u)
    a = u - i
    i = i.astype(np.int64)
    m = np.zeros((len(coords), n))
    rows = np.arange(len(coords))
    np.add.at(m, (rows, np.clip(i, 0, n - 1)), 1.0 - a)
    np.add.at(m, (rows, np.clip(i + 1, 0, n - 1)), a)
    return m


def lookup(img, s, t):
    """Bilinear lookups of img (h x w x 3) at every (s[x], t[y]) -> len(t) x len(s) x 3."""
    mx = axis_weights(np.asarray(s, dtype=np.float64), img.shape[1])
    my = axis_weights(np.asarray(t, dtype=np.float64), img.shape[0])
    return np.einsum("yh,hxc->yxc", my, np.einsum("hwc,xw->hxc", img, mx))


def centres(n):
    return (np.arange(n) + 0.5) / n


def bright(img):
    lum = img @ LUMA709
    return np.where((lum > THRESHOLD)[..., None], img, 0.0)


def karis_weight(g):
    return 1.0 / (1.0 + 0.25 * (np.power(g, KARIS_INV_GAMMA) @ LUMA601))


def downsample(src, tw, th, step_w, step_h, karis):
    """6.new_downsample.fs: 13 lookups of src around each target texel centre."""
    s, t = centres(tw), centres(th)
    dx, dy = 1.0 / step_w, 1.0 / step_h

    def tap(i, j):
        return lookup(src, s + i * dx, t + j * dy)

    a, b, c = tap(-2, 2), tap(0, 2), tap(2, 2)
    d, e, f = tap(-2, 0), tap(0, 0), tap(2, 0)
    g, h, i = tap(-2, -2), tap(0, -2), tap(2, -2)
    j, k, l, m = tap(-1, 1), tap(1, 1), tap(-1, -1), tap(1, -1)
    if karis:
        groups = [(a + b + d + e) * 0.03125, (b + c + e + f) * 0.03125,
                  (d + e + g + h) * 0.03125, (e + f + h + i) * 0.03125,
                  (j + k + l + m) * 0.125]
        total = sum(gr * karis_weight(gr)[..., None] for gr in groups)
        return np.fmax(total, 0.0001)  # maxNum: a NaN group (pow of a negative) gives 0.0001
    return e * 0.125 + (a + c + g + i) * 0.03125 + (b + d + f + h) * 0.0625 + (j + k + l + m) * 0.125


def tent(small, tw, th, r):
    """6.new_upsample.fs: the 3x3 tent with taps r apart in texture coordinates."""
    s, t = centres(tw), centres(th)
    out = np.zeros((th, tw, 3))
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            out += (4 >> (abs(i) + abs(j))) / 16.0 * lookup(small, s + i * r, t + j * r)
    return out


def pipeline(img, levels, float_step=True, radius=None):
    """Every stage of the article's bloom, float64. float_step=False uses 1 / the texture's
    integer size as the downsample step instead of the host's halved float size; radius
    replaces the preset's upsample radius."""
    radius = RADIUS if radius is None else radius
    hgt, wid, _ = img.shape
    sizes = level_sizes(wid, hgt, levels)
    st = {"input": img, "bright": bright(img)}
    src = st["bright"]
    host_w, host_h = F32(wid), F32(hgt)  # glm::vec2 mipSize, halved per level
    for k, (tw, th) in enumerate(sizes, start=1):
        if float_step:
            step_w, step_h = float(host_w), float(host_h)
        else:
            step_w, step_h = src.shape[1], src.shape[0]
        src = downsample(src, tw, th, step_w, step_h, karis=(k == 1))
        st[f"down.{k}"] = src
        host_w, host_h = host_w * F32(0.5), host_h * F32(0.5)
    up = st[f"down.{levels}"]
    for k in range(levels - 1, 0, -1):
        tw, th = sizes[k - 1]
        up = st[f"down.{k}"] + tent(up, tw, th, radius)
        st[f"up.{k}"] = up
    st["bloom"] = lookup(st["up.1"], centres(wid), centres(hgt))
    st["composite"] = img * (1.0 - STRENGTH) + st["bloom"] * STRENGTH
    st["tonemap"] = 1.0 - np.exp(-st["composite"] * EXPOSURE)
    st["output"] = np.power(np.maximum(st["tonemap"], 0.0), 1.0 / GAMMA)
    return st


def stage_names(levels):
    return (["input", "bright"] + [f"down.{k}" for k in range(1, levels + 1)]
            + [f"up.{k}" for k in range(levels - 1, 0, -1)]
            + ["bloom", "composite", "tonemap", "output"])


# --------------------------------------------------------------------------------------------
# Inputs


def random_hdr(w, h, seed):
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.0, 1.6, size=(h, w, 3))
    # a few very bright texels
    n = max(3, w * h // 100)
    ys, xs = rng.integers(0, h, n), rng.integers(0, w, n)
    img[ys, xs] = rng.uniform(5.0, 50.0, size=(n, 3))
    # keep every texel's luminance clear of the threshold, so that float32 and float64 rounding
    # of the luminance cannot disagree on which texels are bright
    lum = img @ LUMA709
    near = np.abs(lum - THRESHOLD) < 1e-3
    img[near] *= 1.01
    return img.astype(np.float32)


def impulse(w, h, x, y, value=(8.0, 4.0, 2.0)):
    img = np.zeros((h, w, 3), dtype=np.float32)
    img[y, x] = value
    return img


# name: (image, levels, upsample radius given on the command line or None for the preset's).
# On small images the preset's radius 0.005 is less than the distance from a level's texel
# centres to the next smaller level's, so the tent's taps fall in one bilinear cell and the
# radius hardly matters; the wide image (level 2 is 64 texels wide: centres 1/256 < 0.005
# apart) and the explicit radius 0.03 make the tent's taps cross texel centres.
CASES = {
    "random37x29": (lambda: random_hdr(37, 29, 20240611), 3, None),
    "random37x29_L4": (lambda: random_hdr(37, 29, 7), 4, None),
    "random64x48": (lambda: random_hdr(64, 48, 12345), 3, None),
    "random256x20_wide": (lambda: random_hdr(256, 20, 4242), 3, None),
    "random37x29_radius0.03": (lambda: random_hdr(37, 29, 31337), 3, 0.03),
    "impulse37x29": (lambda: impulse(37, 29, 17, 11), 3, None),
    "impulse64x48_edge": (lambda: impulse(64, 48, 1, 46), 3, None),
}


def run_case(case, precision):
    make, levels, radius = CASES[case]
    img = make()
    extra = ["--precision", precision]
    if radius is not None:
        extra += ["--upsample-radius", repr(radius)]
        radius = float(F32(radius))
    got = run_bloomref(img, levels, extra)
    return got, pipeline(img.astype(np.float64), levels, radius=radius), levels


# --------------------------------------------------------------------------------------------
# Comparison


def check_stages(got, want, levels, f64, label):
    check_images(got, want, stage_names(levels), f64, label)


def check_images(got, want, names, f64, label):
    """Every stage in `names` dumped, and each within the tolerance of its numpy image: half a
    float ulp (f64 dumps) or F32_REL of the stage's largest value (f32), plus the absolute floor."""
    assert sorted(got) == sorted(names), f"{label}: dumped stages {sorted(got)}, expected {names}"
    for name in names:
        g, w = got[name], want[name]
        assert g.shape == w.shape, f"{label}: stage {name}: shape {g.shape}, expected {w.shape}"
        scale = float(np.max(np.abs(w)))
        if f64:
            # the dump is the f64 value rounded to float32: half an ulp of the expected value
            half_ulp = 0.5 * np.spacing(np.abs(w).astype(np.float32)).astype(np.float64)
            tol = half_ulp * (1 + 1e-6) + F64_REL * scale + F64_ABS
        else:
            tol = F32_REL * scale + F64_ABS
        err = np.abs(g - w) - tol
        if np.any(err > 0):
            y, x, c = np.unravel_index(np.argmax(err), err.shape)
            pytest.fail(f"{label}: stage {name}: texel (col {x}, row {y}) channel {'RGB'[c]}: "
                        f"bloomref {g[y, x, c]!r}, numpy {w[y, x, c]!r}, "
                        f"|diff| {abs(g[y, x, c] - w[y, x, c]):.3e} > tolerance "
                        f"{np.broadcast_to(tol, err.shape)[y, x, c]:.3e} "
                        f"(stage max {scale:.6g}); {int(np.sum(err > 0))} texel channels over")


# --------------------------------------------------------------------------------------------
# Tests


@pytest.mark.parametrize("case", sorted(CASES))
def test_f64_equals_numpy(case):
    got, want, levels = run_case(case, "f64")
    check_stages(got, want, levels, True, f"{case} f64")


@pytest.mark.parametrize("case", sorted(CASES))
def test_f32_equals_numpy(case):
    got, want, levels = run_case(case, "f32")
    check_stages(got, want, levels, False, f"{case} f32")


@pytest.mark.parametrize("precision", ["f64", "f32"])
def test_constant_image_closed_form(precision):
    w, h, levels = 37, 29, 4
    v = np.array([3.0, 2.0, 1.5])  # luminance 2.1765 > 1: all bright
    assert v @ LUMA709 > THRESHOLD
    img = np.broadcast_to(v.astype(np.float32), (h, w, 3)).copy()
    got = run_bloomref(img, levels, ["--precision", precision])

    # down.1: every lookup of a constant is the constant; the four outer groups are
    # 4 v * 0.03125 = v / 8, the inner one 4 v * 0.125 = v / 2, each times its Karis weight.
    def kw(g):
        return 1.0 / (1.0 + 0.25 * float(np.dot(g ** KARIS_INV_GAMMA, LUMA601)))

    outer, inner = v / 8.0, v / 2.0
    d1 = 4.0 * outer * kw(outer) + inner * kw(inner)
    # levels >= 2: weights 0.125 + 4 * 0.03125 + 4 * 0.0625 + 4 * 0.125 = 1 keep the constant;
    # the tent (weights summing to 1) keeps it too, so up.1 = the sum of the K levels.
    bloom = levels * d1
    composite = v * (1.0 - STRENGTH) + bloom * STRENGTH
    tonemap = 1.0 - np.exp(-composite * EXPOSURE)
    output = tonemap ** (1.0 / GAMMA)
    want = {"bright": v, "bloom": bloom, "composite": composite, "tonemap": tonemap,
            "output": output}
    for k in range(1, levels + 1):
        want[f"down.{k}"] = d1
    for k in range(1, levels):
        want[f"up.{k}"] = (levels - k + 1) * d1
    check_constants(got, want, 1e-7 if precision == "f64" else 1e-6, precision)


def check_constants(got, want, rel, label):
    """Each stage in `want` (an RGB constant) within `rel` of it at every texel (plus 1e-12)."""
    for name, value in want.items():
        g = got[name]
        err = np.max(np.abs(g - value), axis=(0, 1))
        assert np.all(err <= rel * np.abs(value) + 1e-12), (
            f"constant {label}: stage {name}: expected {value}, got range "
            f"{g.reshape(-1, 3).min(axis=0)}..{g.reshape(-1, 3).max(axis=0)}")


def test_float_step_is_what_is_tested():
    """On an odd-sized image, the step 1 / the texture's integer size gives a down.2 that the
    comparison's tolerance would reject: the host's float size is what is being checked. And
    --texel-step texture, bloomref's other step, matches numpy's integer-size variant."""
    levels = 3
    img = random_hdr(37, 29, 99)  # level 1 is 18 x 14 where the host's size is 18.5 x 14.5
    want_float = pipeline(img.astype(np.float64), levels, float_step=True)
    want_int = pipeline(img.astype(np.float64), levels, float_step=False)
    got = run_bloomref(img, levels, ["--precision", "f64"])
    check_stages(got, want_float, levels, True, "float step f64")
    for name in ("down.2", "down.3"):
        scale = float(np.max(np.abs(want_float[name])))
        diff = float(np.max(np.abs(got[name] - want_int[name])))
        assert diff > 100 * F32_REL * scale, (
            f"stage {name}: the integer-size step differs from bloomref by only {diff:.3e} "
            f"(stage max {scale:.3g}): the test could not tell the steps apart")
    # down.1 reads the full-resolution image, whose float size is its integer size
    assert np.array_equal(want_int["down.1"], want_float["down.1"]), "stage down.1"
    got_int = run_bloomref(img, levels, ["--precision", "f64", "--texel-step", "texture"])
    check_stages(got_int, want_int, levels, True, "texture step f64")


def test_radius_is_what_is_tested():
    """On the wide image the tent's taps cross texel centres: a radius 2% off the preset's
    0.005 gives an up.1 that the comparison's tolerance would reject."""
    got, want, levels = run_case("random256x20_wide", "f32")
    make, levels, _ = CASES["random256x20_wide"]
    off = pipeline(make().astype(np.float64), levels, radius=RADIUS * 1.02)
    scale = float(np.max(np.abs(want["up.1"])))
    diff = float(np.max(np.abs(got["up.1"] - off["up.1"])))
    assert diff > 10 * F32_REL * scale, (
        f"stage up.1: a radius of {RADIUS * 1.02} differs from bloomref by only {diff:.3e} "
        f"(stage max {scale:.3g}): the test could not tell the radii apart")
