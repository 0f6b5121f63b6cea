"""What bloomref check, merge and run write when names, ids, device keys and shaders are hostile.

Each finding of the outside probes (docs/design.md, "Untrusted names and shaders") has a test
here that fails without its fix; then a property test feeds random bytes into every field a user
controls and parses every output with a real parser: xml.etree for JUnit, html.parser for the
reports, json for the results, and a GitHub table check for Markdown.
"""
import html.parser
import json
import os
import random
import re
import resource
import shutil
import signal
import subprocess
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

EXE = os.environ["BLOOMREF_EXE"]
SIZE = "32x24"


def run(args, cwd, env=None, timeout=120):
    e = dict(os.environ)
    e.update(env or {})
    p = subprocess.run([EXE] + [os.fsencode(a) if isinstance(a, bytes) else a for a in args],
                       cwd=cwd, capture_output=True, env=e, timeout=timeout)
    return p.returncode, p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace")


@pytest.fixture(scope="module")
def stages(tmp_path_factory):
    """A dump of the demo scene's stages; its input.exr is the scene."""
    d = tmp_path_factory.mktemp("dump")
    code, out, err = run(["run", "--size", SIZE, "-o", "o.exr", "--dump-stages", "st", "-q"], d)
    assert code == 0, err
    return d / "st"


def copy_stages(src, dst):
    dst = os.fsencode(str(dst) if isinstance(dst, Path) else dst)
    os.makedirs(dst, exist_ok=True)
    for f in src.iterdir():
        shutil.copy(f, os.path.join(dst, os.fsencode(f.name)))


class Attributes(html.parser.HTMLParser):
    """Every tag's attributes, and every href, of an HTML page."""

    def __init__(self):
        super().__init__()
        self.attrs, self.hrefs = [], []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            self.attrs.append(k)
            if k in ("href", "src") and v is not None and not v.startswith("data:"):
                self.hrefs.append(v)


def parse_html(path):
    p = Attributes()
    p.feed(Path(path).read_text(encoding="utf-8"))
    p.close()
    return p


def markdown_rows_ok(text):
    """Every table row of a GitHub Markdown table has as many cells as its header."""
    lines = text.split("\n")  # CommonMark ends lines at \n and \r only
    width = None
    for line in lines:
        if not line.startswith("|"):
            width = None
            continue
        cells = len(re.findall(r"(?<!\\)\|", line)) - 1
        if width is None:
            width = cells
        elif cells != width:
            return False
    return True


# --- the findings, one by one -------------------------------------------------------------------

def test_a_folder_named_dotdot_is_an_item_named_by_its_folder(stages, tmp_path):
    # Stages in a/, checked from a/c as '..' with --report rep: the item was '..', and the report
    # went to rep/.. = a/c, replacing the user's index.html there.
    (tmp_path / "a" / "c").mkdir(parents=True)
    copy_stages(stages, tmp_path / "a")
    mine = "<html>mine</html>"
    (tmp_path / "a" / "c" / "index.html").write_text(mine)
    code, out, err = run(["check", "--size", SIZE, "--stages", "..", "--report", "rep", "-q",
                          "--artifacts", "all", "--json", "r.json"], tmp_path / "a" / "c")
    assert code == 0, err
    assert (tmp_path / "a" / "c" / "index.html").read_text() == mine
    assert json.loads((tmp_path / "a" / "c" / "r.json").read_text())["items"][0]["id"] == "a"
    assert (tmp_path / "a" / "c" / "rep" / "a" / "index.html").exists()
    assert sorted(os.listdir(tmp_path / "a" / "c")) == ["index.html", "r.json", "rep"]


def test_invalid_utf8_in_names_and_keys_is_kept_escaped_and_the_job_finishes(stages, tmp_path):
    folder = os.path.join(os.fsencode(str(tmp_path)), b"bad\xffname")
    copy_stages(stages, folder)
    code, out, err = run(["check", "--size", SIZE, "--stages", b"bad\xffname",
                          "--device-vendor", b"\xff", "--json", "r.json", "--junit", "r.xml",
                          "--markdown", "r.md", "-q"], tmp_path)
    assert code == 0, err
    j = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    assert j["device"]["vendor"] == "\\xFF"
    assert j["items"][0]["id"] == "bad\\xFFname"
    ET.parse(tmp_path / "r.xml")
    assert markdown_rows_ok((tmp_path / "r.md").read_text(encoding="utf-8"))
    # run keeps its output image and writes its JSON.
    code, out, err = run(["run", "--size", SIZE, "-o", b"o\xff.exr", "--json", "rj.json", "-q"],
                         tmp_path)
    assert code == 0, err
    assert os.path.exists(os.path.join(os.fsencode(str(tmp_path)), b"o\xff.exr"))
    json.loads((tmp_path / "rj.json").read_text(encoding="utf-8"))


def test_quotes_in_a_folder_name_do_not_make_html_attributes(stages, tmp_path):
    name = "x' onmouseover='alert(1)"
    copy_stages(stages, tmp_path / name)
    # a failing stage: its report section links the user's file
    (tmp_path / name / "blur.3.exr").unlink()
    shutil.copy(stages / "blur.4.exr", tmp_path / name / "blur.3.exr")
    code, out, err = run(["check", "--size", SIZE, "--stages", name, "--report", "rep", "-q",
                          "--artifacts", "all"], tmp_path)
    assert code == 1, err
    page = parse_html(tmp_path / "rep" / name / "index.html")
    assert "onmouseover" not in page.attrs
    linked = [h for h in page.hrefs if h.endswith("blur.3.exr") and "%27" in h]
    assert linked, page.hrefs  # the link is there, percent-encoded
    assert all(":" not in h for h in page.hrefs)


def test_an_input_under_a_report_files_name_is_never_replaced(stages, tmp_path):
    rep = tmp_path / "rep" / "one"
    rep.mkdir(parents=True)
    shutil.copy(stages / "blur.3.exr", rep / "blur.3.oracle.exr")
    before = (rep / "blur.3.oracle.exr").read_bytes()
    manifest = {"version": 1, "items": [{"id": "one", "scene": str(stages / "input.exr"),
                                         "stages": {"blur.3": str(rep / "blur.3.oracle.exr")}}]}
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    code, out, err = run(["check", "--manifest", "m.json", "--report", "rep", "-q"], tmp_path)
    assert code == 2
    assert "blur.3.oracle.exr" in err and "--report" in err
    assert (rep / "blur.3.oracle.exr").read_bytes() == before


def test_control_characters_and_latin1_never_break_junit_or_markdown(stages, tmp_path):
    scene = os.path.join(os.fsencode(str(tmp_path)), b"sc\xe9ne.exr")
    shutil.copy(stages / "input.exr", scene)
    copy_stages(stages, tmp_path / "a|b")
    code, out, err = run(["check", b"sc\xe9ne.exr", "--stages", "a|b", "--device-vendor", "v\x01x",
                          "--device-renderer", "r<&>\"'", "--junit", "r.xml", "--markdown", "r.md",
                          "-q"], tmp_path)
    assert code == 0, err
    suites = ET.parse(tmp_path / "r.xml").getroot()
    props = {p.get("name"): p.get("value") for p in suites.iter("property")}
    assert props["device.vendor"] == "v\\x01x"
    assert props["device.renderer"] == "r<&>\"'"
    assert props["scene"].endswith("sc\\xE9ne.exr")
    md = (tmp_path / "r.md").read_text(encoding="utf-8")
    assert markdown_rows_ok(md) and "a\\|b" in md


@pytest.mark.parametrize("bad_id", ["\u0000x", "a\u0001b", "line\nbreak", "../up", ".hidden", ""])
def test_a_manifest_id_that_cannot_name_a_folder_is_refused(stages, tmp_path, bad_id):
    manifest = {"version": 1, "items": [{"id": bad_id, "scene": str(stages / "input.exr"),
                                         "stages": str(stages)}]}
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    code, out, err = run(["check", "--manifest", "m.json", "-q"], tmp_path)
    assert code == 2 and "items[0].id" in err, err


def test_a_declared_raw_size_is_compared_before_anything_is_read(stages, tmp_path):
    (tmp_path / "st").mkdir()
    big = tmp_path / "st" / "bright.raw"
    with open(big, "wb") as f:  # sparse: the size an 8192x8192 f32 RGBA image has
        f.truncate(8192 * 8192 * 16)
    manifest = {"version": 1, "items": [{"id": "one", "scene": str(stages / "input.exr"),
                                         "stages": {"bright": {"path": str(big), "width": 8192,
                                                               "height": 8192}}}]}
    (tmp_path / "m.json").write_text(json.dumps(manifest))
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t = time.monotonic()
    code, out, err = run(["check", "--manifest", "m.json", "-q"], tmp_path)
    assert code == 2 and "declared 8192x8192" in err, err
    assert time.monotonic() - t < 10
    after = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    assert after < 300 * 1024 or after == before  # KiB: nowhere near the file's 1 GiB


def test_max_memory_bounds_check_as_it_bounds_run(stages, tmp_path):
    # check holds about a dozen stage-sized images: a limit below that is refused before any
    # work, naming the option; the same scene within the default limit is judged.
    code, out, err = run(["check", str(stages / "input.exr"), "--stages", str(stages),
                          "--max-memory", "40K", "-q"], tmp_path)
    assert code == 2 and "--max-memory" in err, err
    code, out, err = run(["check", str(stages / "input.exr"), "--stages", str(stages), "-q"],
                         tmp_path)
    assert code == 0, err


def test_a_frame_list_whose_results_cannot_fit_is_refused_at_once(tmp_path):
    t = time.monotonic()
    code, out, err = run(["check", "s.####.exr", "--stages", "st.####/", "--frames", "1-10000000",
                          "-q", "--progress", "none"], tmp_path)
    assert code == 2 and "--shard" in err, err
    assert time.monotonic() - t < 20


def test_a_report_that_cannot_be_written_leaves_the_other_results(stages, tmp_path):
    copy_stages(stages, tmp_path / "st")
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "st").write_text("a file where the item's report folder goes")
    code, out, err = run(["check", "--size", SIZE, "--stages", "st", "--report", "rep",
                          "--json", "r.json", "--junit", "r.xml", "-q"], tmp_path)
    assert code == 6, err
    assert "--report" in err
    j = json.loads((tmp_path / "r.json").read_text())
    assert j["verdict"] == "PASS" and j["output_errors"][0]["option"] == "--report"
    ET.parse(tmp_path / "r.xml")


def test_merge_refuses_an_unknown_status(stages, tmp_path):
    copy_stages(stages, tmp_path / "st.0001")
    shutil.copy(stages / "input.exr", tmp_path / "s.0001.exr")
    code, out, err = run(["check", "s.####.exr", "--stages", "st.####/", "--frames", "1",
                          "--json", "r.json", "-q", "--progress", "none"], tmp_path)
    assert code == 0, err
    j = json.loads((tmp_path / "r.json").read_text())
    j["items"][0]["verdict"] = "MAYBE"
    (tmp_path / "bad.json").write_text(json.dumps(j))
    code, out, err = run(["merge", "bad.json", "-q"], tmp_path)
    assert code == 2 and "MAYBE" in err, err


# --- users' shaders: bounded in memory and time, nothing left behind ---------------------------

BLUR = """#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D image;
uniform bool horizontal;
uniform float w[5] = float[](0.2270270270, 0.1945945946, 0.1216216216, 0.0540540541, 0.0162162162);
EXTRA
void main() {
  vec2 texel = 1.0 / vec2(textureSize(image, 0));
  vec2 d = horizontal ? vec2(texel.x, 0.0) : vec2(0.0, texel.y);
  vec3 sum = texture(image, TexCoords).rgb * w[0];
  for (int i = 1; i < LOOP; ++i) {
    sum += texture(image, TexCoords + d * float(i)).rgb * w[i % 5];
    sum += texture(image, TexCoords - d * float(i)).rgb * w[i % 5];
  }
  colour = vec4(sum + TAIL, 1.0);
}
"""
FINAL = """#version 330 core
out vec4 FragColor;
in vec2 TexCoords;
uniform sampler2D scene;
uniform sampler2D bloomBlur;
uniform bool bloom;
uniform float exposure;
void main() {
  vec3 hdr = texture(scene, TexCoords).rgb;
  if (bloom) hdr += texture(bloomBlur, TexCoords).rgb;
  vec3 result = vec3(1.0) - exp(-hdr * exposure);
  FragColor = vec4(pow(result, vec3(1.0 / 2.2)), 1.0);
}
"""


def shader_files(tmp_path, extra="", loop="5", tail="vec3(0.0)"):
    (tmp_path / "blur.fs").write_text(BLUR.replace("EXTRA", extra).replace("LOOP", loop)
                                      .replace("TAIL", tail))
    (tmp_path / "final.fs").write_text(FINAL)


def gl_or_skip(code, err):
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_GL") == "1":
            pytest.fail("no GL device, and BLOOMREF_REQUIRE_GL=1: " + err)
        pytest.skip("no GL device")


SHADERS = ["check", "--scene", "demo", "--size", SIZE, "--shaders", "learnopengl",
           "--blur-fs", "blur.fs", "--final-fs", "final.fs", "-q"]


def test_well_behaved_shaders_pass_within_the_default_limits(tmp_path):
    shader_files(tmp_path)
    code, out, err = run(SHADERS, tmp_path)
    gl_or_skip(code, err)
    assert code == 0, err


def test_a_shader_that_needs_gigabytes_to_link_is_stopped_at_its_memory_limit(tmp_path):
    shader_files(tmp_path, extra="uniform float big[100000000];",
                 tail="vec3(big[int(TexCoords.x)])")
    t = time.monotonic()
    code, out, err = run(SHADERS + ["--shader-memory", "600M"], tmp_path, env={"TMPDIR": str(tmp_path)})
    gl_or_skip(code, err)
    assert code == 2 and "blur.fs" in err and "memory" in err, err
    assert time.monotonic() - t < 60
    assert not [n for n in os.listdir(tmp_path) if n.startswith("bloomref-")]


def test_a_shader_that_never_ends_is_stopped_at_its_time_limit(tmp_path):
    shader_files(tmp_path, loop="1000000000")
    t = time.monotonic()
    code, out, err = run(SHADERS + ["--shader-timeout", "3"], tmp_path, env={"TMPDIR": str(tmp_path)})
    gl_or_skip(code, err)
    assert code == 2 and "blur.fs" in err and "longer than 3 s" in err, err
    assert time.monotonic() - t < 30
    assert not [n for n in os.listdir(tmp_path) if n.startswith("bloomref-")]


def test_sigterm_during_the_shaders_leaves_no_temporary_folder(tmp_path):
    shader_files(tmp_path, loop="1000000000")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    p = subprocess.Popen([EXE] + SHADERS + ["--shader-timeout", "60"], cwd=tmp_path,
                         env=dict(os.environ, TMPDIR=str(tmp)),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 20
    while not os.listdir(tmp) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if p.poll() is not None:
        gl_or_skip(p.returncode, p.stderr.read().decode())
        pytest.fail("check ended before it was signalled: %d" % p.returncode)
    assert os.listdir(tmp)  # the scratch folder while the passes run
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=20) == -signal.SIGTERM
    time.sleep(0.2)
    assert os.listdir(tmp) == []
    # the child that ran the shaders ended with it
    ps = subprocess.run(["pgrep", "-f", str(tmp_path / "blur.fs")], capture_output=True)
    assert ps.stdout.strip() == b""


# --- property: random bytes in every field a user controls -------------------------------------

def random_name(rng, allow_invalid=True):
    pool = [b"'", b'"', b"<", b">", b"&", b"|", b"`", b"*", b"_", b"[", b"]", b"\\", b"#", b"!",
            b" ", b"\t", b"\x01", b"\x1f", b"\x7f", b":", b"%", b"?", b"=", b"a", b"Z", b"0",
            "é".encode(), "\u2028".encode(), "\ufffe".encode(), "😀".encode(), b"]]>", b"--",
            b"javascript:", b"<script>", b"&amp;", b"\r"]
    if allow_invalid:
        pool += [b"\xff", b"\xc3", b"\xed\xa0\x80", b"\xf4\x90\x80\x80", b"\xc0\xaf"]
    name = b"".join(rng.choice(pool) for _ in range(rng.randint(1, 8)))
    return name.replace(b"/", b"_").lstrip(b".") or b"x"


def check_outputs(folder):
    j = json.loads((folder / "r.json").read_text(encoding="utf-8"))
    ET.parse(folder / "r.xml")
    md = (folder / "r.md").read_text(encoding="utf-8")
    assert markdown_rows_ok(md), md
    for page in (folder / "rep").rglob("index.html"):
        p = parse_html(page)
        assert not [a for a in p.attrs if a.startswith("on")], (page, p.attrs)
        assert all(":" not in h for h in p.hrefs), p.hrefs
    return j


def test_random_bytes_in_every_field_make_outputs_real_parsers_read(stages, tmp_path):
    rng = random.Random(int(os.environ.get("BLOOMREF_PROPERTY_SEED", "54")))
    base = os.fsencode(str(tmp_path))
    for i in range(12):
        case = tmp_path / ("case%d" % i)
        case.mkdir()
        folder = random_name(rng)
        scene = random_name(rng) + b".exr"
        copy_stages(stages, os.path.join(os.fsencode(str(case)), folder))
        os.remove(os.path.join(os.fsencode(str(case)), folder, b"blur.2.exr"))  # a gap
        shutil.copy(stages / "blur.4.exr", os.path.join(os.fsencode(str(case)), folder, b"blur.3.exr"))
        shutil.copy(stages / "input.exr", os.path.join(os.fsencode(str(case)), scene))
        keys = []
        for opt in ("--device-api", "--device-vendor", "--device-renderer", "--device-driver"):
            keys.append(opt.encode() + b"=" + random_name(rng))
        code, out, err = run(["check", b"./" + scene, "--stages", b"./" + folder, "--json", "r.json", "--junit",
                              "r.xml", "--markdown", "r.md", "--report", "rep", "-q",
                              "--artifacts", "all"] + keys, case)
        assert code == 1, (folder, err)  # blur.3 is blur.4: a failure, with its cause and links
        j = check_outputs(case)
        assert j["verdict"] == "FAIL"
    # manifests: ids are JSON text (no invalid bytes); shard results merged
    items = []
    for i in range(6):
        ident = random_name(rng, allow_invalid=False).decode("utf-8", "replace")
        ident = "".join(c for c in ident if ord(c) >= 0x20 and c not in "/\\\x7f\ufffe").lstrip(".") or "x"
        ident = "%d%s" % (i, ident)
        items.append({"id": ident, "scene": str(stages / "input.exr"), "stages": str(stages)})
    (tmp_path / "m.json").write_text(json.dumps({"version": 1, "items": items}))
    code, out, err = run(["check", "--manifest", "m.json", "--shard", "1/2", "--json", "s1.json",
                          "--junit", "r.xml", "--markdown", "r.md", "-q", "--progress", "none"],
                         tmp_path)
    assert code == 0, err
    code, out, err = run(["check", "--manifest", "m.json", "--shard", "2/2", "--json", "s2.json",
                          "-q", "--progress", "none", "--report", "rep"], tmp_path)
    assert code == 0, err
    ET.parse(tmp_path / "r.xml")
    assert markdown_rows_ok((tmp_path / "r.md").read_text(encoding="utf-8"))
    code, out, err = run(["merge", "s1.json", "s2.json", "--json", "m.json.out", "--junit",
                          "merged.xml", "--markdown", "merged.md", "--report", "rep", "-q"],
                         tmp_path)
    assert code == 0, err
    ids = {s.get("name") for s in ET.parse(tmp_path / "merged.xml").getroot().iter("testsuite")}
    assert ids == {it["id"] for it in items}
    assert markdown_rows_ok((tmp_path / "merged.md").read_text(encoding="utf-8"))
    page = parse_html(tmp_path / "rep" / "index.html")
    assert not [a for a in page.attrs if a.startswith("on")]
    assert all(":" not in h for h in page.hrefs), page.hrefs
