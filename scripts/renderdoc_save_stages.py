#!/usr/bin/env python3
"""Saves the bloom passes of a RenderDoc capture as the stage images `bloomref check` reads.

For each event id given, the capture is replayed up to that draw and the draw's first colour
target is saved as NAME.exr (OpenEXR keeps the floats) in FOLDER. Names are check's stage names
(bright, blur.1 ... blur.N, down.k, up.k, composite, tonemap, output), plus `scene` for the HDR
target the bloom read (pass it to check as SCENE).

Outside RenderDoc, with its Python module on PYTHONPATH (renderdoc.so / renderdoc.pyd, built
with RenderDoc):

    python3 renderdoc_save_stages.py frame.rdc capture scene=1198 bright=1203 blur.1=1210 ...
    bloomref check capture/scene.exr --stages capture

Inside RenderDoc's Python shell (Window > Python Shell), with the capture open:

    import renderdoc_save_stages as s
    pyrenderdoc.Replay().BlockInvoke(
        lambda c: s.save_stages(c, s.parse_events(["scene=1198", "bright=1203"]), "capture"))

Event ids are those of RenderDoc's Event Browser. Each file is written under a hidden name and
renamed when complete, so a failed save leaves nothing half-written under a stage's name.
"""
import os
import re
import sys

STAGE = re.compile(r"^(scene|input|bright|bloom|composite|tonemap|output|(blur|down|up)\.[1-9][0-9]*)$")


class UsageError(Exception):
    pass


def parse_events(specs):
    """NAME=EVENT_ID strings -> [(event_id, name)] in the order given."""
    events, seen = [], set()
    for spec in specs:
        name, sep, eid = spec.partition("=")
        if not sep or not eid.isdigit():
            raise UsageError(f"'{spec}' is not NAME=EVENT_ID (e.g. blur.1=1210)")
        if not STAGE.match(name):
            raise UsageError(f"'{name}' is not a stage name check reads "
                             "(scene, bright, blur.N, down.N, up.N, composite, tonemap, output)")
        if name in seen:
            raise UsageError(f"'{name}' is named twice")
        seen.add(name)
        events.append((int(eid), name))
    if not events:
        raise UsageError("no NAME=EVENT_ID given")
    return events


def first_target(controller):
    """The resource of the first bound colour target at the current event, or None."""
    for target in controller.GetPipelineState().GetOutputTargets():
        # RenderDoc 1.x names it `resource` in newer versions, `resourceId` in older ones.
        rid = getattr(target, "resource", None)
        if rid is None:
            rid = getattr(target, "resourceId", None)
        if rid is not None and int(rid) != 0:
            return rid
    return None


def save_stages(controller, events, folder, rd=None):
    """Saves each (event_id, name) draw's first colour target as FOLDER/NAME.exr."""
    rd = rd or __import__("renderdoc")
    os.makedirs(folder, exist_ok=True)
    saved = []
    for event_id, name in events:
        controller.SetFrameEvent(event_id, True)  # the state after that draw
        rid = first_target(controller)
        if rid is None:
            raise UsageError(f"event {event_id} ({name}) has no colour target bound")
        save = rd.TextureSave()
        save.resourceId = rid
        save.mip = 0
        save.slice.sliceIndex = 0
        save.alpha = rd.AlphaMapping.Preserve
        save.destType = rd.FileType.EXR
        path = os.path.join(folder, name + ".exr")
        hidden = os.path.join(folder, "." + name + ".saving.exr")
        result = controller.SaveTexture(save, hidden)
        if result is False or not os.path.exists(hidden):
            if os.path.exists(hidden):
                os.remove(hidden)
            raise UsageError(f"RenderDoc could not save event {event_id} ({name}): {result}")
        os.replace(hidden, path)
        saved.append(path)
    return saved


def succeeded(rd, status):
    # RenderDoc 1.14 and later return a ResultCode, earlier versions a ReplayStatus.
    codes = getattr(rd, "ResultCode", None) or getattr(rd, "ReplayStatus")
    return status == codes.Succeeded


def open_capture(rd, path):
    cap = rd.OpenCaptureFile()
    status = cap.OpenFile(path, "", None)
    if not succeeded(rd, status):
        raise UsageError(f"{path}: RenderDoc cannot open it ({status})")
    if not cap.LocalReplaySupport():
        raise UsageError(f"{path}: this machine cannot replay the capture")
    if hasattr(rd, "ReplayOptions"):
        status, controller = cap.OpenCapture(rd.ReplayOptions(), None)
    else:
        status, controller = cap.OpenCapture(None)
    if not succeeded(rd, status):
        raise UsageError(f"{path}: the replay does not start ({status})")
    return cap, controller


def main(argv):
    if len(argv) < 3 or argv[0] in ("-h", "--help"):
        print(__doc__.strip().split("\n\n")[0] + "\n\nusage: renderdoc_save_stages.py CAPTURE.rdc "
              "FOLDER NAME=EVENT_ID...", file=sys.stderr)
        return 2
    capture, folder, specs = argv[0], argv[1], argv[2:]
    try:
        events = parse_events(specs)
        if not os.path.isfile(capture):
            raise UsageError(f"{capture}: no such file")
        try:
            import renderdoc as rd
        except ImportError:
            raise UsageError("the renderdoc Python module is not on PYTHONPATH "
                             "(it is built with RenderDoc: renderdoc.so or renderdoc.pyd)")
        if hasattr(rd, "InitialiseReplay"):
            rd.InitialiseReplay(rd.GlobalEnvironment(), [])
        cap, controller = open_capture(rd, capture)
        try:
            for path in save_stages(controller, events, folder, rd):
                print(path)
        finally:
            controller.Shutdown()
            cap.Shutdown()
            if hasattr(rd, "ShutdownReplay"):
                rd.ShutdownReplay()
    except UsageError as e:
        print(f"renderdoc_save_stages: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
