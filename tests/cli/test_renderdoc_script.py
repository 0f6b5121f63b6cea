"""scripts/renderdoc_save_stages.py against a stand-in for RenderDoc's `renderdoc` module.

RenderDoc is not installable here, so a fake module plays the replay: each event's colour target
is a stage image bloomref dumped, and SaveTexture copies it. What is tested is the script's own
part (event parsing, both API generations, hidden-then-renamed files, errors) and the whole flow
a user follows: save the stages, then `bloomref check` them (PASS; two passes swapped: FAIL at
the first of them).
"""
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import types

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "..", "scripts", "renderdoc_save_stages.py")
EXE = os.environ.get("BLOOMREF_EXE", os.path.join(HERE, "..", "..", "build", "cli", "bloomref"))


def load_script():
    spec = importlib.util.spec_from_file_location("renderdoc_save_stages", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class ResourceId(int):
    pass


class Descriptor:
    def __init__(self, rid, new_api):
        if new_api:
            self.resource = ResourceId(rid)
        else:
            self.resourceId = ResourceId(rid)


def fake_renderdoc(textures, new_api=True, capture_ok=True):
    """A `renderdoc` module whose replay draws `textures` {event_id: file}."""
    rd = types.ModuleType("renderdoc")
    codes = types.SimpleNamespace(Succeeded=0, FileIOFailed=1)
    if new_api:
        rd.ResultCode = codes
        rd.ReplayOptions = lambda: object()
    else:
        rd.ReplayStatus = codes
    rd.AlphaMapping = types.SimpleNamespace(Preserve="preserve")
    rd.FileType = types.SimpleNamespace(EXR="exr")
    rd.calls = []

    class TextureSave:
        def __init__(self):
            self.slice = types.SimpleNamespace(sliceIndex=None)

    rd.TextureSave = TextureSave

    class Controller:
        event = None

        def SetFrameEvent(self, eid, force):
            self.event = eid
            rd.calls.append(("event", eid))

        def GetPipelineState(self):
            targets = [Descriptor(0, new_api)]  # an unbound slot first, then the target
            if self.event in textures:
                targets.append(Descriptor(self.event, new_api))
            return types.SimpleNamespace(GetOutputTargets=lambda: targets)

        def SaveTexture(self, save, path):
            assert save.destType == "exr" and save.mip == 0 and save.slice.sliceIndex == 0
            shutil.copyfile(textures[int(save.resourceId)], path)
            rd.calls.append(("save", os.path.basename(path)))
            return codes.Succeeded

        def Shutdown(self):
            rd.calls.append(("shutdown",))

    class Capture:
        def OpenFile(self, path, driver, progress):
            return codes.Succeeded if capture_ok else codes.FileIOFailed

        def LocalReplaySupport(self):
            return True

        def OpenCapture(self, *args):
            assert len(args) == (2 if new_api else 1)
            return codes.Succeeded, Controller()

        def Shutdown(self):
            pass

    rd.OpenCaptureFile = Capture
    return rd


@pytest.fixture(scope="module")
def dumped(tmp_path_factory):
    """bloomref's own stages of a 48x40 demo scene (the textures the fake capture holds)."""
    d = tmp_path_factory.mktemp("dump")
    subprocess.run([EXE, "run", "--scene", "demo", "--size", "48x40", "--plan", "full",
                    "--dump-stages", str(d / "stages"), "-o", str(d / "out.exr")], check=True)
    return d / "stages"


def events_of(dumped, names):
    # Event ids as a capture numbers its draws: increasing, not contiguous.
    return {1000 + 7 * i: str(dumped / (("input" if n == "scene" else n) + ".exr"))
            for i, n in enumerate(names)}


NAMES = ["scene", "bright"] + [f"blur.{k}" for k in range(1, 11)] + ["output"]


@pytest.mark.parametrize("new_api", [True, False])
def test_saved_stages_pass_check(tmp_path, dumped, monkeypatch, new_api):
    textures = events_of(dumped, NAMES)
    rd = fake_renderdoc(textures, new_api)
    monkeypatch.setitem(sys.modules, "renderdoc", rd)
    (tmp_path / "frame.rdc").write_bytes(b"capture")
    specs = [f"{n}={eid}" for eid, n in zip(textures, NAMES)]
    s = load_script()
    assert s.main([str(tmp_path / "frame.rdc"), str(tmp_path / "capture")] + specs) == 0
    assert [c for c in rd.calls if c[0] == "save"] == [("save", "." + n + ".saving.exr") for n in NAMES]
    assert rd.calls[-1] == ("shutdown",)
    files = sorted(os.listdir(tmp_path / "capture"))
    assert files == sorted(n + ".exr" for n in NAMES)  # no hidden file left
    r = subprocess.run([EXE, "check", str(tmp_path / "capture/scene.exr"), "--stages",
                        str(tmp_path / "capture"), "--json", str(tmp_path / "r.json")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    result = json.loads((tmp_path / "r.json").read_text())
    assert [st["stage"] for st in result["items"][0]["stages"]] == NAMES[1:]


def test_two_passes_swapped_fail_at_the_first(tmp_path, dumped, monkeypatch):
    textures = events_of(dumped, NAMES)
    ids = list(textures)
    names = list(NAMES)
    names[3], names[4] = names[4], names[3]  # blur.2 saved under blur.3 and blur.3 under blur.2
    rd = fake_renderdoc(textures)
    monkeypatch.setitem(sys.modules, "renderdoc", rd)
    (tmp_path / "frame.rdc").write_bytes(b"capture")
    s = load_script()
    assert s.main([str(tmp_path / "frame.rdc"), str(tmp_path / "capture")] +
                  [f"{n}={eid}" for eid, n in zip(ids, names)]) == 0
    r = subprocess.run([EXE, "check", str(tmp_path / "capture/scene.exr"), "--stages",
                        str(tmp_path / "capture"), "--json", str(tmp_path / "r.json")],
                       capture_output=True, text=True)
    assert r.returncode == 1, r.stdout + r.stderr
    assert json.loads((tmp_path / "r.json").read_text())["items"][0]["first_divergent_stage"] == "blur.2"


def test_bad_events_and_captures_are_exit_2(tmp_path, monkeypatch, capsys):
    s = load_script()
    with pytest.raises(s.UsageError, match="not NAME=EVENT_ID"):
        s.parse_events(["blur.1:1210"])
    with pytest.raises(s.UsageError, match="not a stage name"):
        s.parse_events(["blur.0=1210"])
    with pytest.raises(s.UsageError, match="named twice"):
        s.parse_events(["bright=1", "bright=2"])
    assert s.parse_events(["down.3=12", "output=40"]) == [(12, "down.3"), (40, "output")]
    monkeypatch.setitem(sys.modules, "renderdoc", fake_renderdoc({}, capture_ok=False))
    (tmp_path / "frame.rdc").write_bytes(b"capture")
    assert s.main([str(tmp_path / "frame.rdc"), str(tmp_path / "c"), "bright=5"]) == 2
    assert "cannot open" in capsys.readouterr().err
    assert s.main([str(tmp_path / "missing.rdc"), str(tmp_path / "c"), "bright=5"]) == 2
    assert "no such file" in capsys.readouterr().err
    # A draw with no colour target bound names the event.
    monkeypatch.setitem(sys.modules, "renderdoc", fake_renderdoc({}))
    assert s.main([str(tmp_path / "frame.rdc"), str(tmp_path / "c"), "bright=5"]) == 2
    assert "event 5 (bright) has no colour target" in capsys.readouterr().err
