"""What a run's set-up remembers in the cache instead of recomputing: the digest of the runtime's sources
(runtime/native/build.py remembered_digest) and the body image's checksum (runtime/native/image.py
remembered_checksum). A remembered value must be the computed one, and an edit must not be hidden."""
from __future__ import annotations

import os

import numpy as np

from ffrf_fmu.runtime.native import build, image


def test_remembered_checksum_is_the_checksum(tmp_path, monkeypatch):
    monkeypatch.setenv("FFRF_FMU_CACHE_DIR", str(tmp_path))
    payload = np.random.default_rng(0).integers(0, 2**62, 500).astype("<u8").tobytes()
    expected = image.checksum(payload)
    assert image.remembered_checksum(payload) == expected  # computed, then written
    memos = list((tmp_path / "image_checksums").rglob("*"))
    files = [p for p in memos if p.is_file()]
    assert len(files) == 1 and files[0].read_text() == f"{expected:016x}"
    assert image.remembered_checksum(payload) == expected  # read back
    files[0].write_text("not hex digits!!")  # a damaged memo is not trusted
    assert image.remembered_checksum(payload) == expected
    other = payload[:-8] + b"\x01" * 8
    assert image.remembered_checksum(other) == image.checksum(other) != expected
    # an image packed with it is read back, checksum checked (unpack computes it afresh)
    entries = {"a": np.arange(6.0).reshape(2, 3), "n": np.array([3])}
    back = image.unpack(image.pack(entries))
    assert np.array_equal(back["a"], entries["a"]) and back["n"][0] == 3


def test_remembered_digest_follows_an_edit(tmp_path, monkeypatch):
    monkeypatch.setenv("FFRF_FMU_CACHE_DIR", str(tmp_path / "cache"))
    a, b = tmp_path / "a.c", tmp_path / "b.h"
    a.write_text("int a;\n")
    b.write_text("int b;\n")
    first = build.remembered_digest([a, b], ("cc", "-O2"))
    assert first == build.file_digest([a, b], ("cc", "-O2"))
    assert build.remembered_digest([a, b], ("cc", "-O2")) == first  # from the memo
    assert build.remembered_digest([a, b], ("cc", "-O3")) == build.file_digest([a, b], ("cc", "-O3")) != first
    st = os.stat(a)
    a.write_text("int c;\n")  # same size: the modification time tells
    os.utime(a, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert build.remembered_digest([a, b], ("cc", "-O2")) == build.file_digest([a, b], ("cc", "-O2")) != first


def test_source_digest_is_the_runtime_sources():
    """The key of the compiled runtime is the sha256 of its sources and headers as before the memo."""
    names = build.SOURCES + build.HEADERS
    assert build.source_digest(("cc",)) == build.file_digest([build.HERE / n for n in names], ("cc",))
