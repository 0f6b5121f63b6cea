"""The corpus holds exactly the images data/corpus.sha256 lists, each with its SHA-256 (computed
by Python's hashlib). Without BLOOMREF_CORPUS the corpus half is skipped; the list is always
read."""
import hashlib
import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
LIST = ROOT / "data" / "corpus.sha256"
IMAGE_SUFFIXES = {".exr", ".hdr"}


def listed():
    sums = {}
    for line in LIST.read_text().splitlines():
        if not line:
            continue
        digest, sep, name = line[:64], line[64:66], line[66:]
        assert sep == "  " and len(digest) == 64, line
        int(digest, 16)  # hex digits, or ValueError
        sums[name] = digest
    return sums


def test_the_list_names_fifteen_images():
    assert len(listed()) == 15


def test_the_corpus_holds_exactly_the_listed_images():
    corpus = os.environ.get("BLOOMREF_CORPUS")
    if not corpus:
        pytest.skip("BLOOMREF_CORPUS is not set: corpus checksums not checked")
    corpus = pathlib.Path(corpus)
    if not corpus.is_absolute() and not corpus.is_dir():
        corpus = ROOT / corpus  # relative to the repository, as the C++ tests take it
    assert corpus.is_dir(), f"BLOOMREF_CORPUS={corpus} is not a folder"
    sums = listed()
    present = {p.name: p for p in corpus.iterdir()
               if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES}
    assert sorted(present) == sorted(sums), "images listed and images present differ"
    for name, path in present.items():
        assert hashlib.sha256(path.read_bytes()).hexdigest() == sums[name], name
