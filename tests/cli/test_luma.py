"""--luma rec601: the threshold's luminance with Rec. 601's weights (0.299, 0.587, 0.114);
--luma-space srgb|gamma: taken of max(c, 0) encoded by IEC 61966-2-1's curve or by x^(1/gamma).

- Against numpy: the gaussian method's bright stage is the input where 0.299 r + 0.587 g +
  0.114 b > 1, on a scene where Rec. 601 and Rec. 709 disagree on many texels; the article's
  pipeline (learnopengl-pbb), computed in numpy with the bright image by Rec. 601, equals
  bloomref's in f64 stage by stage (test_variants_numpy's pipeline with its weights swapped).
- The adaptive plan gives the full plan's bits (its fast paths test Rec. 709's luminance and
  step aside).
- A capture with the other weights fails at its first thresholded stage, naming `luma-weights`
  and the --luma that declares it, both ways and for both methods.
- GL and Vulkan run it (compare passes for both methods). Skipped without a device unless
  BLOOMREF_REQUIRE_GL=1 / BLOOMREF_REQUIRE_VULKAN=1.
- The encoded spaces the same way: the bright mask against numpy's encode (f64, texels kept
  clear of the threshold), adaptive against full bits, a capture in another space named
  `threshold-color-space` with the --luma-space that declares it (or one as likely), GL and
  Vulkan on the demo and on a corpus image (BLOOMREF_CORPUS).
"""
import json
import os

import numpy as np
import pytest

import test_variants_numpy as tv
from cli_support import run
from test_variants_numpy import stages_of

SCHEMAS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs", "schemas")
REC601 = np.array([0.299, 0.587, 0.114])
REC709 = np.array([0.2126, 0.7152, 0.0722])


def scene(w=48, h=36, seed=11):
    """Texels up to 2 with a few of 5 to 50; no luminance (either weights) within 1e-3 of 1."""
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.0, 2.0, size=(h, w, 3))
    n = w * h // 50
    img[rng.integers(0, h, n), rng.integers(0, w, n)] = rng.uniform(5.0, 50.0, size=(n, 3))
    for _ in range(4):
        near = (np.abs(img @ REC601 - 1) < 1e-3) | (np.abs(img @ REC709 - 1) < 1e-3)
        img[near] *= 1.01
    return img.astype(np.float32)


def device_or_skip(code, err, backend):
    """Exit 3 (no device) skips, or fails under BLOOMREF_REQUIRE_GL / _VULKAN=1."""
    if code != 3:
        return
    require = "BLOOMREF_REQUIRE_GL" if backend == "gl" else "BLOOMREF_REQUIRE_VULKAN"
    if os.environ.get(require) == "1":
        pytest.fail(f"no {backend} device although {require}=1: {err}")
    pytest.skip(f"no {backend} device: {err.strip()}")


def dump(rgb, *extra):
    return stages_of(rgb, *extra)


def test_the_bright_stage_thresholds_rec601_luma():
    img = scene()
    x = img.astype(np.float64)
    want = np.where((x @ REC601 > 1.0)[..., None], x, 0.0)
    disagree = int(np.sum((x @ REC601 > 1.0) != (x @ REC709 > 1.0)))
    assert disagree > 50  # the weights are told apart on this scene
    got = dump(img, "--plan", "full", "--luma", "rec601")["bright"]
    assert np.array_equal(got, want)


def test_the_articles_pipeline_with_rec601_equals_numpy(monkeypatch):
    img = scene(37, 29, 3)
    monkeypatch.setattr(tv, "LUMA709", REC601)  # the numpy pipeline's bright pass
    want = tv.pipeline(img.astype(np.float64), 3)
    got = tv.run_bloomref(img, 3, ["--precision", "f64", "--luma", "rec601"])
    tv.check_stages(got, want, 3, True, "pbb rec601 f64")


@pytest.mark.parametrize("method", ["gaussian", "mip"])
def test_the_adaptive_plan_keeps_the_full_plans_bits(method):
    img = np.zeros((120, 160, 3), dtype=np.float32)  # sparse: the adaptive plan's fast paths
    img[30:34, 40:44] = (0.2, 3.0, 0.2)                # bright by either weights
    img[80:83, 100:104] = (4.0, 0.1, 0.1)              # 601: 1.21, 709: 0.93
    full = dump(img, "--method", method, "--plan", "full", "--luma", "rec601")
    adaptive = dump(img, "--method", method, "--plan", "adaptive", "--luma", "rec601")
    assert np.array_equal(full["output"], adaptive["output"])
    seven = dump(img, "--method", method, "--plan", "adaptive")
    assert not np.array_equal(full["output"], seven["output"])


@pytest.mark.parametrize("method,stage", [("gaussian", "bright"), ("mip", "down.1")])
@pytest.mark.parametrize("dumped,declared", [("rec601", "rec709"), ("rec709", "rec601")])
def test_a_capture_with_the_other_weights_is_named(tmp_path, method, stage, dumped, declared):
    size = ["--scene", "demo", "--size", "160x96", "--method", method]
    assert run(["run", *size, "--plan", "full", "--luma", dumped, "--dump-stages", "d", "-q"],
               tmp_path)[0] == 0
    code, out, err = run(["check", *size, "--stages", "d", "--luma", declared, "--json", "r.json",
                          "-q"], tmp_path)
    assert code == 1, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["first_divergent_stage"] == stage
    cause = item["first_divergent_cause"]
    assert cause["id"] == "luma-weights" and cause["likely"], cause
    assert cause["detail"] == f"--luma {dumped} declares it"
    with open(os.path.join(SCHEMAS, "check-result.v1.json")) as f:  # the results' schema names it
        assert cause["id"] in json.load(f)["$defs"]["cause"]["properties"]["id"]["enum"]
    # Declared as dumped, the same captures pass.
    code, out, err = run(["check", *size, "--stages", "d", "--luma", dumped, "-q"], tmp_path)
    assert code == 0, out + err


@pytest.mark.parametrize("backend", ["gl", "vulkan"])
@pytest.mark.parametrize("method", ["gaussian", "mip"])
def test_gl_and_vulkan_run_rec601(tmp_path, backend, method):
    code, out, err = run(["compare", "--scene", "demo", "--size", "160x96", "--method", method,
                          "--luma", "rec601", "--backend", backend], tmp_path)
    device_or_skip(code, err, backend)
    assert code == 0, out + err
    assert "verdict PASS" in out


def test_a_manifest_declares_it(tmp_path):
    size = ["--scene", "demo", "--size", "160x96"]
    assert run(["run", *size, "--plan", "full", "--luma", "rec601", "--dump-stages", "d", "-q"],
               tmp_path)[0] == 0
    assert run(["scenes", "demo", "--size", "160x96", "-o", "scene.exr"], tmp_path)[0] == 0
    manifest = {"version": 1, "params": {"luma": "rec601"},
                "items": [{"id": "demo", "scene": "scene.exr", "stages": "d"}]}
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    code, out, err = run(["check", "--manifest", "m.json", "-q"], tmp_path)
    assert code == 0, out + err
    with open(os.path.join(SCHEMAS, "check-manifest.v1.json")) as f:  # and its schema allows it
        params = json.load(f)["properties"]["params"]["properties"]
    assert params["luma"]["enum"] == ["rec709", "rec601"]
    assert params["first_axis"]["enum"] == ["horizontal", "vertical"]


def encode(x, space, gamma=2.2):
    x = np.maximum(x, 0.0)
    if space == "gamma":
        return x ** (1.0 / gamma)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1.0 / 2.4) - 0.055)


def encoded_scene(space, w=48, h=36, seed=13):
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.0, 1.5, size=(h, w, 3))
    for _ in range(6):  # every luminance clear of the threshold in both spaces
        near = ((np.abs(encode(img, space) @ REC709 - 1) < 2e-3) | (np.abs(img @ REC709 - 1) < 2e-3))
        img[near] *= 1.02
    return img.astype(np.float32)


@pytest.mark.parametrize("space", ["srgb", "gamma"])
def test_the_bright_stage_thresholds_encoded_luminance(space):
    img = encoded_scene(space)
    x = img.astype(np.float64)
    mask = encode(x, space) @ REC709 > 1.0
    assert int(np.sum(mask != (x @ REC709 > 1.0))) > 40  # the spaces are told apart
    got = dump(img, "--plan", "full", "--luma-space", space)["bright"]
    assert np.array_equal(got, np.where(mask[..., None], x, 0.0))


@pytest.mark.parametrize("space", ["srgb", "gamma"])
@pytest.mark.parametrize("method", ["gaussian", "mip"])
def test_an_encoded_space_keeps_the_full_plans_bits(space, method):
    img = np.zeros((120, 160, 3), dtype=np.float32)
    img[30:34, 40:44] = (3.0, 3.0, 3.0)  # bright in every space
    img[80:83, 100:104] = (0.0, 1.5, 0.0)  # bright only linear (0.86 of the threshold encoded)
    full = dump(img, "--method", method, "--plan", "full", "--luma-space", space)
    adaptive = dump(img, "--method", method, "--plan", "adaptive", "--luma-space", space)
    assert np.array_equal(full["output"], adaptive["output"])
    linear = dump(img, "--method", method, "--plan", "adaptive")
    assert not np.array_equal(full["output"], linear["output"])


@pytest.mark.parametrize("method,stage", [("gaussian", "bright"), ("mip", "down.1")])
@pytest.mark.parametrize("dumped,declared", [("gamma", "linear"), ("srgb", "linear"),
                                             ("linear", "gamma")])
def test_a_capture_in_another_space_is_named(tmp_path, method, stage, dumped, declared):
    size = ["--scene", "demo", "--size", "160x96", "--method", method]
    assert run(["run", *size, "--plan", "full", "--luma-space", dumped, "--dump-stages", "d",
                "-q"], tmp_path)[0] == 0
    code, out, err = run(["check", *size, "--stages", "d", "--luma-space", declared, "--json",
                          "r.json", "-q"], tmp_path)
    assert code == 1, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["first_divergent_stage"] == stage
    first = item["first_divergent_cause"]
    assert first["id"] == "threshold-color-space" and first["likely"], first
    # The space dumped is named first, or as likely as the one named (sRGB's curve and gamma
    # 2.2 may pick the same texels).
    causes = [s for s in item["stages"] if s["stage"] == stage][0]["causes"]
    truth = [c for c in causes if c["detail"] == f"--luma-space {dumped} declares it"]
    assert truth and (truth[0]["detail"] == first["detail"] or truth[0]["as_likely"]), causes
    code, out, err = run(["check", *size, "--stages", "d", "--luma-space", dumped, "-q"], tmp_path)
    assert code == 0, out + err


@pytest.mark.parametrize("backend", ["gl", "vulkan"])
@pytest.mark.parametrize("space", ["srgb", "gamma"])
@pytest.mark.parametrize("method", ["gaussian", "mip"])
def test_gl_and_vulkan_run_an_encoded_space(tmp_path, backend, space, method):
    args = ["compare", "--scene", "demo", "--size", "160x96"]
    corpus = os.environ.get("BLOOMREF_CORPUS", "")
    if corpus and method == "gaussian" and space == "gamma":  # a real image's edges too
        args = ["compare", os.path.join(corpus, "GoldenGate.exr")]
    code, out, err = run([*args, "--method", method, "--luma-space", space, "--backend", backend],
                         tmp_path)
    device_or_skip(code, err, backend)
    assert code == 0, out + err
    assert "verdict PASS" in out


@pytest.mark.parametrize("option,dumped,declared,cause", [
    ("--luma", "rec601", "rec709", "luma-weights"),
    ("--luma-space", "gamma", "linear", "threshold-color-space")])
def test_only_the_last_pass_and_output_captured(tmp_path, option, dumped, declared, cause):
    """With blur.10 and output alone, the other luminance still fails where it is first seen,
    the cause named; declared as dumped, the same two captures pass."""
    size = ["--scene", "demo", "--size", "160x96"]
    assert run(["run", *size, "--plan", "full", option, dumped, "--dump-stages", "d", "-q"],
               tmp_path)[0] == 0
    (tmp_path / "some").mkdir()
    for stage in ("blur.10", "output"):
        (tmp_path / "d" / f"{stage}.exr").rename(tmp_path / "some" / f"{stage}.exr")
    code, out, err = run(["check", *size, "--stages", "some", option, declared, "--json",
                          "r.json", "-q"], tmp_path)
    assert code == 1, out + err
    item = json.loads((tmp_path / "r.json").read_text())["items"][0]
    assert item["first_divergent_stage"] == "blur.10"
    assert item["first_divergent_cause"]["id"] == cause and item["first_divergent_cause"]["likely"]
    code, out, err = run(["check", *size, "--stages", "some", option, dumped, "--json", "c.json",
                          "-q"], tmp_path)
    assert code == 0, out + err
    assert json.loads((tmp_path / "c.json").read_text())["verdict"] == "PASS"
