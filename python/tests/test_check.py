"""bloomref.check: the command's verdicts as a dict, on folders, files and arrays; errors."""
import json

import numpy as np
import pytest

import bloomref


@pytest.fixture
def dumped(tmp_path, cli):
    """A built-in scene and the oracle's own stages as the command dumps them (every one passes)."""
    scene = tmp_path / "scene.exr"
    assert cli("scenes", "demo", "--size", "96x64", "-o", scene).returncode == 0
    r = cli("run", scene, "--plan", "full", "--dump-stages", tmp_path / "mine", "-q")
    assert r.returncode == 0, r.stderr
    return scene, tmp_path / "mine"


def test_a_folder_gives_the_commands_json(tmp_path, cli, dumped):
    scene, folder = dumped
    r = cli("check", scene, "--stages", folder, "--json", tmp_path / "r.json", "-q")
    assert r.returncode == 0, r.stderr
    expected = json.loads((tmp_path / "r.json").read_text())
    result = bloomref.check(scene, folder)
    assert result["verdict"] == expected["verdict"] == "PASS"
    assert result["exit_code"] == 0
    assert set(result) == set(expected)
    ours, theirs = result["items"][0], expected["items"][0]
    assert ours["first_divergent_stage"] is None
    assert [s["stage"] for s in ours["stages"]] == [s["stage"] for s in theirs["stages"]]
    assert [s["isolated"]["verdict"] for s in ours["stages"]] == \
           [s["isolated"]["verdict"] for s in theirs["stages"]]
    assert len(ours["stages"]) == 15  # input, bright, 10 passes, composite, tonemap, output


def test_arrays_judge_a_skipped_pass(dumped):
    scene, _ = dumped
    stages = bloomref.run(scene, keep_stages=True, plan="full")
    # A ping-pong bug: pass 3 leaves its input unchanged (docs/check.md's tutorial).
    given = {"blur.2": stages["blur.2"], "blur.3": stages["blur.2"], "output": stages["output"]}
    result = bloomref.check(stages["input"], given)
    assert result["verdict"] == "FAIL" and result["exit_code"] == 1
    item = result["items"][0]
    assert item["first_divergent_stage"] == "blur.3"
    files = {s["stage"]: s["file"] for s in item["stages"]}
    assert files["blur.3"] == "stages['blur.3'] (array)"
    assert item["scene"] == "scene (array)"


def test_a_dict_of_paths_and_options(dumped):
    scene, folder = dumped
    result = bloomref.check(scene, {"output": folder / "output.exr"}, profile="llvmpipe")
    # The output alone is a clean capture: it does not fail, and it is PASS exactly when it
    # could see a bloom 5% too strong (otherwise WARN: weak verdict).
    sensitivity = result["items"][0]["sensitivity"]
    assert result["verdict"] == ("WARN" if sensitivity["weak"] else "PASS")
    assert sensitivity["required_gain"] == 1.05
    assert result["profile"]["name"] == "llvmpipe"
    assert [s["stage"] for s in result["items"][0]["stages"]][-1] == "output"


@pytest.mark.parametrize("stages, options, message", [
    ({"blur.2": np.zeros((10, 96, 4), np.float32)}, {}, "stages['blur.2'] (array): is 96x10"),
    ({"glow": np.zeros((64, 96, 4), np.float32)}, {}, "stages['glow']: not a stage name"),
    ({"blur.12": np.zeros((64, 96, 4), np.float32)}, {}, "has no such stage"),
    ({"output": np.zeros((64, 96), np.float32)}, {}, "shape (64, 96)"),
    (None, {"profile": "amiga"}, "--profile 'amiga'"),
    (None, {"colour": 1}, "--colour"),
    (None, {"knee": 0.3}, "--knee does nothing without --prefilter soft-knee"),
])
def test_bad_input_raises_value_error(dumped, stages, options, message):
    scene, folder = dumped
    with pytest.raises(ValueError) as e:
        bloomref.check(scene, folder if stages is None else stages, **options)
    assert message in str(e.value)


def test_nothing_compared_raises_value_error(tmp_path, dumped):
    scene, _ = dumped
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="nothing compared"):
        bloomref.check(scene, tmp_path / "empty")


def test_a_pass_count_without_that_stage(dumped):
    scene, folder = dumped
    with pytest.raises(ValueError, match="has no such stage"):
        bloomref.check(scene, folder, passes=4)


def test_arrays_are_judged_without_writing_a_file(dumped, monkeypatch, tmp_path):
    # TMPDIR names a file: no temporary folder can be made there, so a check that wrote its
    # arrays to one (as bloomref.check once did) fails; judged in memory, it passes.
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    monkeypatch.setenv("TMPDIR", str(blocker))
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    scene, _ = dumped
    stages = bloomref.run(scene, keep_stages=True, plan="full")
    given = {"blur.1": stages["blur.1"], "output": stages["output"]}
    result = bloomref.check(stages["input"], given, sensitivity="none")
    assert result["verdict"] == "PASS"
    assert [s["stage"] for s in result["items"][0]["stages"]] == ["blur.1", "output"]
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_an_empty_dict_says_nothing_was_compared_and_prints_nothing(dumped, capfd):
    scene, _ = dumped
    with pytest.raises(ValueError) as e:
        bloomref.check(scene, {})
    assert "nothing compared" in str(e.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_run_refuses_an_option_its_mode_ignores():
    """bloomref.run parses its options as the command does: one given without the mode that
    reads it is a ValueError (even at its default); a preset's own values under a mode given
    beside it are not (unity-urp's knee under --prefilter none)."""
    img = np.full((6, 6, 4), 2.0, np.float32)
    with pytest.raises(ValueError, match="--passes does nothing without --method gaussian"):
        bloomref.run(img, method="mip", passes=10)
    assert bloomref.run(img, preset="unity-urp", prefilter="none").shape == img.shape
