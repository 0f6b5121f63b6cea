"""What the command-line tests of presets and pipeline descriptions share: running bloomref,
skipping without GL, dumping a preset's stages and judging some of them, the first failing
stage's cause. BLOOMREF_EXE (set by ctest) is the binary."""
import json
import os
import subprocess

import pytest

EXE = os.environ["BLOOMREF_EXE"]


def run(args, cwd, timeout=300):
    p = subprocess.run([EXE] + args, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def gl_or_skip(code, err):
    """Exit 3 (no GL) skips the test, or fails it under BLOOMREF_REQUIRE_GL=1."""
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_GL") == "1":
            pytest.fail("no GL although BLOOMREF_REQUIRE_GL=1: " + err)
        pytest.skip("no GL: " + err.strip())


def dump(tmp_path, name, preset, size, *options):
    """The stages of `preset` on the built-in demo scene at `size`, `options` planted: a folder."""
    d = tmp_path / name
    code, _, err = run(["run", "--scene", "demo", "--size", size, "--preset", preset, "-q",
                        "-o", str(tmp_path / (name + ".exr")), "--dump-stages", str(d), *options],
                       tmp_path)
    assert code == 0, err
    return d


def judged(tmp_path, folder, keep, name, preset, size, *declared):
    """check of `folder`'s stages named in `keep` (all when None) against `preset` with the
    options `declared` beside it: the item."""
    sub = tmp_path / name
    sub.mkdir()
    for f in folder.iterdir():
        if keep is None or f.stem in keep:
            (sub / f.name).write_bytes(f.read_bytes())
    code, _, err = run(["check", "--scene", "demo", "--size", size, "--preset", preset,
                        *declared, "--stages", str(sub), "--json", str(sub / "r.json"), "-q"],
                       tmp_path)
    assert code in (0, 1), err
    return json.loads((sub / "r.json").read_text())["items"][0]


def first_cause(item):
    """(first failing stage, the id of its likely cause or "none", the cause object)."""
    first = [s for s in item["stages"] if s["stage"] == item["first_divergent_stage"]][0]
    c = first.get("cause")
    return first["stage"], c["id"] if c and c.get("likely") else "none", c


def assert_fails_where_planted(item, stage, causes, planted_value=None):
    """A dump with a planted error: FAIL, first at `stage`, its cause one of `causes` ("none":
    unexplained); a named cause's fitted interval holds `planted_value` when one is given."""
    assert item["verdict"] == "FAIL"
    first, named, cause = first_cause(item)
    assert first == stage, (first, json.dumps(cause))
    assert named in causes, json.dumps(cause)
    if named != "none" and planted_value is not None:
        fitted = cause["fitted"]
        assert fitted["low"] <= planted_value <= fitted["high"], json.dumps(cause)
