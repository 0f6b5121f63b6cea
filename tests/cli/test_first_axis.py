"""--first-axis vertical: the gaussian method's blur passes starting on the vertical axis.

- Against numpy: each pass of bloomref's CPU run is a 9-tap convolution with seed 000's weights
  (../shared/seeds/000: weight[] = 0.227027, 0.1945946, 0.1216216, 0.054054, 0.016216) along
  the axis the option says, clamp to edge, computed here from the pass before (the first from the
  run's own bright stage); the other axis would be far out of the tolerance.
- Against itself transposed: a vertical-first run of a scene and a horizontal-first run of the
  transposed scene give every stage transposed, bit for bit (the sampler treats both axes alike).
- On GL: compare passes; the tutorial's host code runs a user's blur starting vertical, and its
  passes pass; a horizontal-first capture judged as vertical-first fails at blur.1 naming
  `horizontal-first`. Skipped without GL unless BLOOMREF_REQUIRE_GL=1.
- Refused with the mip method, which has no blur passes.
"""
import json
import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from cli_support import gl_or_skip, run
from test_variants_numpy import bloomref_exe, random_hdr, read_rgb, write_exr

WEIGHTS = [0.227027, 0.1945946, 0.1216216, 0.054054, 0.016216]


def dump(rgb, *extra):
    """bloomref run on rgb (float32 HxWx3) with the stages dumped: {stage: HxWx3 float64}."""
    with tempfile.TemporaryDirectory(prefix="first_axis_") as tmp:
        src = os.path.join(tmp, "in.exr")
        write_exr(src, rgb)
        out = os.path.join(tmp, "stages")
        cmd = [bloomref_exe(), "run", src, "--plan", "full", *extra, "--dump-stages", out, "-q"]
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        return {f[:-4]: read_rgb(os.path.join(out, f)) for f in os.listdir(out) if f.endswith(".exr")}


def blur(img, vertical):
    """One pass: sum of w[|i|] * img shifted by i texels along the axis, i in -4..4, clamped."""
    n = img.shape[0 if vertical else 1]
    out = np.zeros_like(img)
    for i in range(-4, 5):
        idx = np.clip(np.arange(n) + i, 0, n - 1)
        out += WEIGHTS[abs(i)] * (img[idx] if vertical else img[:, idx])
    return out


def scene():
    # Values up to 1.6 and a few texels of 5 to 50, 37x29: no side is the other's length, so a
    # pass on the wrong axis (or the transposition) cannot come out right by symmetry.
    return random_hdr(37, 29, 5)


def test_each_pass_runs_on_the_axis_the_option_says():
    stages = dump(scene(), "--first-axis", "vertical")
    prev = stages["bright"]
    scale = float(np.abs(prev).max())
    assert scale > 1
    for k in range(1, 11):
        vertical = k % 2 == 1
        want = blur(prev, vertical)
        got = stages[f"blur.{k}"]
        err = float(np.abs(got - want).max())
        other = float(np.abs(got - blur(prev, not vertical)).max())
        assert err <= 1e-5 * scale, (k, err)
        assert other > 1e-3 * scale, (k, other)  # the axes are told apart
        prev = got


def test_a_vertical_first_run_is_a_transposed_horizontal_first_one():
    rgb = scene()
    v = dump(rgb, "--first-axis", "vertical")
    h = dump(np.ascontiguousarray(rgb.transpose(1, 0, 2)))
    assert set(v) == set(h)
    for name in v:
        assert np.array_equal(v[name], h[name].transpose(1, 0, 2)), name


def test_refused_with_the_mip_method_and_named_when_wrong(tmp_path):
    code, out, err = run(["run", "--size", "40x30", "--method", "mip", "--first-axis", "vertical",
                          "-o", "o.exr"], tmp_path)
    assert code == 2 and "--first-axis vertical needs --method gaussian" in err
    code, out, err = run(["run", "--size", "40x30", "--first-axis", "diagonal", "-o", "o.exr"], tmp_path)
    assert code == 2 and "--first-axis" in err and "horizontal" in err
    assert not (tmp_path / "o.exr").exists()


def test_gl_passes_and_a_capture_on_the_other_axis_is_named(tmp_path):
    code, out, err = run(["compare", "--scene", "demo", "--size", "96x64", "--first-axis", "vertical"],
                         tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    assert "verdict PASS" in out
    # The seeds' horizontal-first dump, judged where vertical-first is declared.
    assert run(["run", "--scene", "demo", "--size", "96x64", "--plan", "full", "--dump-stages", "h",
                "-q"], tmp_path)[0] == 0
    code, out, err = run(["check", "--scene", "demo", "--size", "96x64", "--stages", "h",
                          "--first-axis", "vertical", "--json", "r.json", "-q"], tmp_path)
    assert code == 1, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["first_divergent_stage"] == "blur.1"
    cause = item["first_divergent_cause"]
    assert cause["id"] == "horizontal-first" and cause["likely"]
    assert "--first-axis horizontal" in cause["detail"]
    schema = Path(__file__).resolve().parents[2] / "docs" / "schemas" / "check-result.v1.json"
    assert cause["id"] in json.loads(schema.read_text())["$defs"]["cause"]["properties"]["id"]["enum"]


# bloomref's own shaders in the layout of LearnOpenGL's bloom (the bug corpus's): `horizontal`
# is the host's to set.
SHADERS = Path(__file__).resolve().parents[2] / "data" / "bugs" / "shaders"


def test_the_tutorials_host_starts_a_users_blur_on_the_declared_axis(tmp_path):
    shaders = ["--shaders", "learnopengl", "--blur-fs", str(SHADERS / "blur.fs"), "--final-fs",
               str(SHADERS / "final.fs")]
    code, out, err = run(["check", "--scene", "demo", "--size", "96x64", *shaders,
                          "--first-axis", "vertical", "--json", "r.json", "-q"], tmp_path)
    gl_or_skip(code, err)
    assert code == 0, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["verdict"] == "PASS"
    assert [s["stage"] for s in item["stages"]][:3] == ["blur.1", "blur.2", "blur.3"]
