"""Shared fixtures of the Python module's tests: the bloomref executable (the CLI whose output
the module must match), image files written and read with OpenImageIO (a reader independent of
bloomref's own), and the corpus (BLOOMREF_CORPUS)."""
import os
import pathlib
import subprocess

import numpy as np
import OpenImageIO as oiio
import pytest

import bloomref


@pytest.fixture(scope="session")
def exe():
    """The bloomref command: BLOOMREF_EXE (set by ctest), else the build's beside the module."""
    path = os.environ.get("BLOOMREF_EXE") or str(
        pathlib.Path(bloomref.__file__).resolve().parent.parent / "cli" / "bloomref")
    assert os.access(path, os.X_OK), f"no bloomref executable at {path} (set BLOOMREF_EXE)"
    return path


@pytest.fixture
def cli(exe):
    """Runs the command; returns its CompletedProcess (exit code not checked)."""
    def run(*args):
        return subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
    return run


def read_exr(path):
    """An image file as float32 H x W x C, read by OpenImageIO."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    pixels = inp.read_image("float")
    inp.close()
    return np.asarray(pixels, dtype=np.float32)


def write_exr(path, image):
    """Writes float32 H x W x 4 as a float EXR (lossless) with OpenImageIO."""
    h, w, c = image.shape
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(w, h, c, "float")
    spec.channelnames = ("R", "G", "B", "A")[:c]
    assert out.open(str(path), spec), out.geterror()
    assert out.write_image(np.ascontiguousarray(image, dtype=np.float32))
    out.close()


def bits(a):
    """The array's float32 values as integers: equal arrays of bits, NaN included."""
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def hdr_scene(h, w, seed=7):
    """A deterministic HDR scene: dim noise below the threshold and a few bright pixels."""
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 4), np.float32)
    img[..., :3] = rng.uniform(0.0, 0.6, (h, w, 3))
    img[..., 3] = 1.0
    for y, x, v in [(h // 3, w // 4, 12.0), (h // 2, 3 * w // 4, 3.5), (h - 2, 1, 40.0)]:
        img[y, x, :3] = v
    return img


@pytest.fixture
def corpus():
    """The corpus folder, or None (then the corpus tests say so and pass, as the C++ tests do)."""
    path = os.environ.get("BLOOMREF_CORPUS")
    if not path:
        print("BLOOMREF_CORPUS is not set: corpus comparisons not run")
        return None
    assert os.path.isdir(path), f"BLOOMREF_CORPUS={path} is not a folder"
    return pathlib.Path(path)
