"""bloomref.load and bloomref.save against OpenImageIO's reading and writing of the same files."""
import numpy as np
import OpenImageIO as oiio
import pytest

import bloomref
from conftest import bits, hdr_scene, read_exr, write_exr


def test_load_reads_what_openimageio_reads(tmp_path):
    scene = hdr_scene(20, 30)
    write_exr(tmp_path / "rgba.exr", scene)
    assert np.array_equal(bits(bloomref.load(tmp_path / "rgba.exr")), bits(scene))
    write_exr(tmp_path / "rgb.exr", scene[..., :3])
    loaded = bloomref.load(str(tmp_path / "rgb.exr"))
    assert loaded.shape == (20, 30, 4)
    assert np.array_equal(bits(loaded[..., :3]), bits(scene[..., :3]))
    assert (loaded[..., 3] == 1.0).all()  # RGB files get alpha 1


def test_save_exr_keeps_every_bit(tmp_path):
    scene = hdr_scene(17, 23)
    scene[2, 3, 0] = -4.5
    bloomref.save(tmp_path / "out.exr", scene)
    assert np.array_equal(bits(read_exr(tmp_path / "out.exr")), bits(scene))


def test_save_png_quantises(tmp_path):
    # round(clamp(x, 0, 1) * 255): 0.25 -> 63.75 -> 64, 0.6 -> 153, 2 -> 255, -1 -> 0.
    img = np.zeros((1, 4, 4), np.float32)
    img[0, :, :3] = np.array([0.25, 0.6, 2.0, -1.0], np.float32)[:, None]
    img[..., 3] = 1.0
    bloomref.save(tmp_path / "out.png", img)
    inp = oiio.ImageInput.open(str(tmp_path / "out.png"))
    codes = np.asarray(inp.read_image("uint8"))
    inp.close()
    assert codes.shape == (1, 4, 3)
    assert codes[0, :, 0].tolist() == [64, 153, 255, 0]


@pytest.mark.parametrize("call, message", [
    (lambda p: bloomref.load(p / "missing.exr"), "missing.exr"),
    (lambda p: bloomref.save(p / "out.jpg", np.zeros((2, 2, 4), np.float32)), "out.jpg"),
    (lambda p: bloomref.save(p / "out.exr", np.zeros((2, 2), np.float32)), "shape (2, 2)"),
    (lambda p: bloomref.load(3), "path must be a str"),
])
def test_bad_files_raise_value_error(tmp_path, call, message):
    with pytest.raises(ValueError) as e:
        call(tmp_path)
    assert message in str(e.value)
