"""bloomref.run: values computed here by hand, the CLI's output bits, arrays in and out, errors."""
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import bloomref
from conftest import bits, hdr_scene, read_exr, write_exr

F32_ULP = 2.0 ** -24  # relative


def tone_and_gamma(hdr, exposure=1.0, gamma=2.2):
    """docs/design.md, "Specification", stages 5 and 6, in double: pow(1 - exp(-hdr * exposure), 1 / gamma)."""
    return (1.0 - np.exp(-np.float64(hdr) * exposure)) ** (1.0 / gamma)


def uniform(h, w, value):
    img = np.full((h, w, 4), value, np.float32)
    img[..., 3] = 1.0
    return img


def test_below_threshold_is_tone_map_and_gamma_only():
    # Nothing is bright: the bloom is 0 and each value is the tone map and gamma of the scene's.
    out = bloomref.run(uniform(9, 13, 0.5), exposure=2.0, gamma=2.0)
    expected = tone_and_gamma(0.5, exposure=2.0, gamma=2.0)  # sqrt(1 - e^-1) = 0.79506...
    assert out.shape == (9, 13, 4) and out.dtype == np.float32
    np.testing.assert_allclose(out[..., :3], expected, rtol=8 * F32_ULP, atol=0)


def test_uniform_bright_scene_adds_strength_times_itself():
    # Luminance 2 > 1: bright = scene. Each blur pass of a uniform image keeps it (the discrete9
    # weights 924, 792, 495, 220, 66 over 4070 sum to 1, up to float rounding of each tap), so
    # composite = 2 + 0.5 * 2 = 3.
    out = bloomref.run(uniform(12, 20, 2.0), strength=0.5, passes=4)
    np.testing.assert_allclose(out[..., :3], tone_and_gamma(3.0), rtol=32 * F32_ULP, atol=0)


def test_threshold_option_turns_the_bloom_off():
    out = bloomref.run(uniform(6, 6, 2.0), threshold=5.0)
    np.testing.assert_allclose(out[..., :3], tone_and_gamma(2.0), rtol=8 * F32_ULP, atol=0)


@pytest.mark.parametrize("options", [
    {},
    {"storage": "f16"},
    {"method": "mip", "karis": True},
    {"passes": 4, "kernel": "linear5", "exposure": 0.7, "plan": "full"},
])
def test_same_bits_as_the_command(tmp_path, cli, options):
    scene = hdr_scene(45, 70)
    write_exr(tmp_path / "in.exr", scene)
    args = []
    for key, value in options.items():
        name = "--" + key.replace("_", "-")
        args += [name] if value is True else [name, value]
    r = cli("run", tmp_path / "in.exr", "-o", tmp_path / "out.exr", "-q", *args)
    assert r.returncode == 0, r.stderr
    expected = read_exr(tmp_path / "out.exr")
    out = bloomref.run(scene, **options)
    assert out.shape == expected.shape
    assert np.array_equal(bits(out), bits(expected))
    # The same from the file, read by bloomref itself.
    assert np.array_equal(bits(bloomref.run(tmp_path / "in.exr", **options)), bits(expected))


def test_keep_stages_are_the_commands_dumped_stages(tmp_path, cli):
    scene = hdr_scene(30, 41)
    write_exr(tmp_path / "in.exr", scene)
    r = cli("run", tmp_path / "in.exr", "--dump-stages", tmp_path / "stages", "--plan", "full",
            "--passes", "4", "-q")
    assert r.returncode == 0, r.stderr
    stages = bloomref.run(scene, keep_stages=True, plan="full", passes=4)
    assert list(stages) == ["input", "bright", "blur.1", "blur.2", "blur.3", "blur.4",
                            "composite", "tonemap", "output"]
    for name, image in stages.items():
        assert np.array_equal(bits(image), bits(read_exr(tmp_path / "stages" / f"{name}.exr"))), name


def test_corpus_image_same_bits_as_the_command(tmp_path, cli, corpus):
    if corpus is None:
        return
    path = corpus / "reference-crop.exr"  # 160x160 half RGB
    r = cli("run", path, "-o", tmp_path / "out.exr", "--storage", "f16", "-q")
    assert r.returncode == 0, r.stderr
    expected = read_exr(tmp_path / "out.exr")
    assert np.array_equal(bits(bloomref.run(path, storage="f16")), bits(expected))
    rgb = read_exr(path)  # H x W x 3: alpha 1, as the command reads it
    assert rgb.shape[2] == 3
    assert np.array_equal(bits(bloomref.run(rgb, storage="f16")), bits(expected))


def test_arrays_in_and_out():
    scene = hdr_scene(40, 64)
    before = scene.copy()
    out = bloomref.run(scene)
    assert np.array_equal(bits(scene), bits(before))  # the input is read, never written
    assert out.flags["C_CONTIGUOUS"] and out.flags["WRITEABLE"]
    assert out.base is not None  # owns the executor's buffer through a capsule: no copy
    # A crop of a float32 array (rows of another length) is read in place: same as a copy of it.
    crop = scene[5:30, 8:50]
    assert not crop.flags["C_CONTIGUOUS"]
    assert np.array_equal(bits(bloomref.run(crop)), bits(bloomref.run(crop.copy())))
    # RGB and float64 are converted: the same as RGBA float32 with alpha 1.
    assert np.array_equal(bits(bloomref.run(scene[..., :3].astype(np.float64))), bits(out))
    assert np.array_equal(bits(bloomref.run(np.asfortranarray(scene))), bits(out))


def test_released_outputs_are_written_again():
    # An output Python releases keeps its buffer for the next run of that size: runs that
    # discard, hold and release their outputs in turn give the same bits each time.
    scene = hdr_scene(48, 80)
    first = bloomref.run(scene)
    bloomref.run(scene)  # released at once: its buffer is kept
    a = bloomref.run(scene)  # written into it
    b = bloomref.run(scene)  # nothing kept now: a new buffer
    del a
    c = bloomref.run(scene)
    for out in (b, c):
        assert np.array_equal(bits(out), bits(first))


@pytest.mark.parametrize("options", [{}, {"plan": "full"}, {"method": "mip"},
                                     {"precision": "f64"}, {"storage": "f16"}])
def test_out_receives_the_output_apart_and_in_place(options):
    # The bits of a run without out=, for every kind of out: a numpy array, an array the module
    # made (its buffer kept: the same address), the scene's own array (in place), numpy's or
    # the module's. The function returns out itself.
    scene = hdr_scene(48, 80)
    before = scene.copy()
    expected = bits(bloomref.run(scene, **options))
    mine = bloomref.run(hdr_scene(48, 80, seed=3))  # a buffer of the module's
    numpy_out = np.empty((48, 80, 4), np.float32)
    for out in (numpy_out, mine):
        address = out.ctypes.data
        assert bloomref.run(scene, out=out, **options) is out
        assert out.ctypes.data == address
        assert np.array_equal(bits(out), expected)
        assert np.array_equal(bits(scene), bits(before))  # the scene is read, not written
    for work in (scene.copy(), bloomref.run(scene)):
        np.copyto(work, scene)
        address = work.ctypes.data
        assert bloomref.run(work, out=work, **options) is work
        assert work.ctypes.data == address
        assert np.array_equal(bits(work), expected)


def test_out_runs_again_after_a_module_array_went_in_place():
    # An array of the module's whose buffer was handed over and taken back serves as out and as
    # an input again, and its release still keeps the buffer (test_released_outputs...).
    scene = hdr_scene(40, 64)
    expected = bits(bloomref.run(scene))
    work = bloomref.run(scene)
    for _ in range(3):
        np.copyto(work, scene)
        bloomref.run(work, out=work)
        assert np.array_equal(bits(work), expected)
    assert np.array_equal(bits(bloomref.run(scene, out=work)), expected)
    del work
    assert np.array_equal(bits(bloomref.run(scene)), expected)


def test_out_with_the_gl_backend_receives_the_gl_output():
    # The GL backend's output, copied into out (numpy's or the module's): its bits.
    scene = hdr_scene(40, 64)
    try:
        expected = bits(bloomref.run(scene, backend="gl"))
    except bloomref.GlUnavailable:
        if os.environ.get("BLOOMREF_REQUIRE_GL") == "1":
            raise
        pytest.skip("no GL device")
    for out in (np.empty((40, 64, 4), np.float32), bloomref.run(scene)):
        assert bloomref.run(scene, backend="gl", out=out) is out
        assert np.array_equal(bits(out), expected)


@pytest.mark.parametrize("out, options, message", [
    (np.zeros((8, 8, 4), np.float32), {}, "shape (8, 8, 4) is not the output's, (16, 24, 4)"),
    (np.zeros((16, 24, 4), np.float64), {}, "dtype float64 is not float32"),
    (np.zeros((16, 24, 3), np.float32), {}, "shape (16, 24, 3)"),
    (np.zeros((16, 24, 4), np.float32, order="F"), {}, "not C-contiguous"),
    ([[0.0]], {}, "expected a numpy array, got list"),
    (np.zeros((16, 24, 4), np.float32), {"keep_stages": True}, "out and keep_stages"),
])
def test_bad_out_raises_value_error(out, options, message):
    with pytest.raises(ValueError) as e:
        bloomref.run(hdr_scene(16, 24), out=out, **options)
    assert message in str(e.value)


def test_read_only_out_raises_value_error():
    out = np.zeros((16, 24, 4), np.float32)
    out.setflags(write=False)
    with pytest.raises(ValueError, match="read-only"):
        bloomref.run(hdr_scene(16, 24), out=out)


FAILING_RUNS = """
import resource, sys
import numpy as np
import bloomref
scene = np.full((1000, 1000, 4), 4.0, np.float32)  # bright everywhere: every buffer needed
out = bloomref.run(scene, plan="full", threads=1)  # 15.3 MiB of the module's (none kept)
expected = out.copy()
soft, hard = resource.getrlimit(resource.RLIMIT_AS)
failed = 0
# From below the process's size: memory freed but still mapped (the heap's slack) can carry a
# whole run with no new mapping, so a limit at the size itself may fail nothing.
for margin_mib in range(-16, 80, 2):
    np.copyto(out, scene)
    size = int(next(l for l in open("/proc/self/status") if l.startswith("VmSize")).split()[1])
    resource.setrlimit(resource.RLIMIT_AS, (size * 1024 + margin_mib * (1 << 20), hard))
    ran = False
    try:
        bloomref.run(out, out=out, plan="full", threads=1)
        ran = True
    except (MemoryError, RuntimeError):
        failed += 1
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    out[:] = 1.0  # the buffer is still the array's: written and read whole
    assert float(out.sum()) == out.size
    if ran and failed:  # past the limits that fail
        break
np.copyto(out, scene)
bloomref.run(out, out=out, plan="full", threads=1)
assert np.array_equal(out, expected)
print("failed runs:", failed)
"""


def test_a_run_that_fails_in_place_leaves_out_usable(tmp_path):
    # Runs in place on an array of the module's under an address-space limit raised step by
    # step, so that some fail (out of memory) after the executor took the buffer: the array
    # keeps it (the executor gives it back), so writing and reading it all does not crash the
    # process, and a run without the limit gives the output's bits. (Without the give-back
    # the process dies reading the array.)
    script = tmp_path / "failing_runs.py"
    script.write_text(FAILING_RUNS)
    # Blocks of 1 MiB or more mapped and unmapped on their own (glibc's mallopt tunable), so
    # that a buffer freed under the array would no longer be mapped.
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                       env=dict(os.environ, MALLOC_MMAP_THRESHOLD_="1048576"))
    assert r.returncode == 0, r.stderr[-2000:]
    failed = int(r.stdout.split("failed runs:")[1])
    assert failed > 0  # the limit did make runs fail


def huge_advised(begin, end):
    """Whether every mapping of this process overlapping [begin, end) is advised for huge pages
    ("hg" in its VmFlags, /proc/self/smaps: the kernel's record); False where none overlaps."""
    flags, overlaps = [], False
    with open("/proc/self/smaps") as f:
        for line in f:
            if line.startswith("VmFlags:"):
                if overlaps:
                    flags.append("hg" in line.split()[1:])
            elif "-" in line.split()[0]:
                lo, hi = (int(x, 16) for x in line.split()[0].split("-"))
                overlaps = lo < end and begin < hi
    return bool(flags) and all(flags)


@pytest.mark.skipif(not os.path.exists("/sys/kernel/mm/transparent_hugepage"),
                    reason="no transparent huge pages in this kernel")
def test_large_outputs_are_advised_for_huge_pages_as_numpy_arrays_are():
    # An 8 MiB output: its whole 2 MiB pages advised for huge pages, as numpy advises its own
    # arrays of 4 MiB or more (the threshold itself: tests/machinery/test_pixel_memory.cpp).
    huge = 2 << 20
    out = bloomref.run(hdr_scene(512, 1024))
    start = out.ctypes.data
    first, last = -(-start // huge) * huge, (start + out.nbytes) // huge * huge
    assert last > first
    assert huge_advised(first, last)


def test_the_gil_is_released_while_it_runs():
    scene = hdr_scene(720, 1280)
    count = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            count[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    try:
        start = count[0]
        bloomref.run(scene, plan="full", threads=1)
        during = count[0] - start  # Python ran in the other thread only if the GIL was free
    finally:
        stop.set()
        t.join()
    assert during > 1000


@pytest.mark.parametrize("image, options, message", [
    (np.zeros((4, 4), np.float32), {}, "shape (4, 4) is not H x W x 4"),
    (np.zeros((4, 4, 2), np.float32), {}, "shape (4, 4, 2)"),
    (np.zeros((0, 4, 4), np.float32), {}, "is empty"),
    (np.zeros((4, 4, 4), np.int32), {}, "dtype int32 is not floating point"),
    ([[0.0]], {}, "expected a numpy array"),
    (np.zeros((4, 4, 4), np.float32), {"passes": "x"}, "--passes"),
    (np.zeros((4, 4, 4), np.float32), {"method": "blob"}, "--method 'blob' is not one of"),
    (np.zeros((4, 4, 4), np.float32), {"storage": "f8"}, "--storage"),
    (np.zeros((4, 4, 4), np.float32), {"colour": 1}, "unknown option 'colour'"),
    (np.zeros((4, 4, 4), np.float32), {"backend": "vulkan"}, "--backend 'vulkan'"),
    (np.zeros((4, 4, 4), np.float32), {"gamma": 0}, "gamma"),
])
def test_bad_input_raises_value_error(image, options, message):
    with pytest.raises(ValueError) as e:
        bloomref.run(image, **options)
    assert message in str(e.value)


def test_nonfinite_error_policy_names_the_problem():
    scene = hdr_scene(8, 8)
    scene[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        bloomref.run(scene, nonfinite="error")
    out = bloomref.run(scene)  # zero: the NaN becomes 0
    assert np.isfinite(out).all()


def test_missing_file_raises_value_error(tmp_path):
    with pytest.raises(ValueError, match="no-such.exr"):
        bloomref.run(tmp_path / "no-such.exr")
