"""--first-downsample box4 and --downsample box4: the 4-tap box downsample (four GL_LINEAR lookups
at (+-1, +-1) texels of the source, summed, times 0.25).

- The CPU reference against a closed form computed by numpy without any lookup: on even sizes each
  lookup at a texel corner is the mean of a 2x2 block, so a level is the mean of the 4x4 block
  around its texel (edges clamped); and against numpy's bilinear lookups on odd sizes.
- compare: bloomref's Bevy downsample shader draws it (GL and Vulkan), every stage passes.
- check: a capture made with the 13-tap filter, judged as the box, fails at the level where it
  enters; with only the last upsample and the output captured it never passes (it warns that it
  could not see, and names the stages to capture).
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
from test_variants_numpy import centres, random_hdr, stages_of as dumped

BOX = ["--method", "mip", "--prefilter", "none", "--first-downsample", "box4",
       "--downsample", "box4"]


def block_mean(src):
    """The 4x4 box of an even-sized level: texel (x, y) of the half-size level is the mean of
    source texels 2x-1 .. 2x+2 by 2y-1 .. 2y+2, clamped to the edge."""
    p = np.pad(src, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = src.shape[0] // 2, src.shape[1] // 2
    out = np.zeros((h, w, 3))
    for dy in range(4):
        for dx in range(4):
            out += p[dy:dy + 2 * h:2, dx:dx + 2 * w:2]
    return out / 16.0


def box4(src, tw, th):
    """Four bilinear lookups at +-1 source texel, summed, times 0.25 (odd sizes too)."""
    sh, sw = src.shape[:2]
    s, t = centres(tw), centres(th)
    return sum(lookup(src, s + dx / sw, t + dy / sh) for dy in (-1, 1) for dx in (-1, 1)) * 0.25


def test_even_levels_are_the_4x4_block_mean():
    img = random_hdr(64, 48, 11)
    got = dumped(img, *BOX, "--levels", "3", "--storage", "f32", "--precision", "f64")
    want = img.astype(np.float64)
    for k in (1, 2, 3):
        want = block_mean(want)
        assert np.allclose(got[f"down.{k}"], want, rtol=1e-6, atol=1e-9), k


def test_odd_levels_equal_numpy_lookups():
    img = random_hdr(37, 29, 12)
    got = dumped(img, *BOX, "--levels", "3", "--storage", "f32", "--precision", "f64")
    want = img.astype(np.float64)
    w, h = 37, 29
    for k in (1, 2, 3):
        w, h = w // 2, h // 2
        want = box4(want, w, h)
        assert np.allclose(got[f"down.{k}"], want, rtol=1e-6, atol=1e-9), k
    # Not the 13-tap filter: the two differ on this image.
    other = dumped(img, "--method", "mip", "--prefilter", "none", "--levels", "3", "--storage",
                   "f32", "--precision", "f64")
    assert not np.allclose(other["down.2"], got["down.2"], rtol=1e-3)


@pytest.mark.parametrize("backend", ["gl", "vulkan"])
def test_compare_draws_the_box_and_passes(tmp_path, backend):
    code, out, err = run(["compare", "--backend", backend, "--scene", "demo", "--size", "203x131",
                          "--preset", "bevy", "--downsample", "box4"], tmp_path, timeout=600)
    if backend == "vulkan" and code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())
    gl_or_skip(code, err)
    assert code == 0 and "verdict PASS" in out, out + err


def judged(tmp_path, folder, keep, name, *declared):
    return cli_support.judged(tmp_path, folder, keep, name, "bevy", "203x131", *declared)


def test_a_13_tap_capture_fails_as_the_box_whole_and_in_part(tmp_path):
    box = cli_support.dump(tmp_path, "box", "bevy", "203x131", "--downsample", "box4")
    assert judged(tmp_path, box, None, "ok", "--downsample", "box4")["verdict"] == "PASS"
    taps13 = cli_support.dump(tmp_path, "taps13", "bevy", "203x131")
    item = judged(tmp_path, taps13, None, "all", "--downsample", "box4")
    assert item["verdict"] == "FAIL" and item["first_divergent_stage"] == "down.2"
    # With only the last upsample and the output, the uncaptured chain's end-to-end bound (seven
    # levels of it) hides a difference of a few percent at up.1: never a PASS; a WARN that says
    # it could not see, and what to capture.
    for storage in ("r11g11b10", "f16"):
        d = cli_support.dump(tmp_path, "taps13-" + storage, "bevy", "203x131", "--chain-storage",
                             storage)
        part = judged(tmp_path, d, ["up.1", "output"], "part-" + storage, "--downsample", "box4",
                      "--chain-storage", storage)
        assert part["verdict"] in ("FAIL", "WARN"), json.dumps(part["stages"])[:1500]
        if part["verdict"] == "WARN":
            assert part["sensitivity"]["weak"] and "capture down.1" in part["sensitivity"][
                "strengthen_with"], json.dumps(part["sensitivity"])
