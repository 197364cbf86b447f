"""What a run's set-up looks up instead of recomputing: the digest of the runtime's sources
(runtime/native/build.py remembered_digest) and the compiled runtime's folder it keys (library_key);
and the body image's checksum, by the C runtime in the process that creates the body
(ffrf_image_checksum). A looked-up value must be the computed one, and an edit must not be hidden."""
from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from ffrf_fmu.runtime.native import binding, build, image


def test_c_checksum_is_the_python_checksum():
    """The image's checksum by the C runtime (binding.py's images) is image.checksum, bit for bit, and
    an image packed with it reads back (unpack checks it in Python); one flipped bit changes it."""
    lib = binding.load()
    payload = np.random.default_rng(0).integers(0, 2**62, 500).astype("<u8").tobytes()
    assert lib.ffrf_image_checksum(payload, len(payload)) == image.checksum(payload)
    other = payload[:-8] + bytes([payload[-8] ^ 1]) + payload[-7:]
    assert lib.ffrf_image_checksum(other, len(other)) == image.checksum(other) != image.checksum(payload)
    entries = {"a": np.arange(6.0).reshape(2, 3), "n": np.array([3]), "s": 2.5}
    packed = image.pack(entries, lambda p: lib.ffrf_image_checksum(p, len(p)))
    assert packed == image.pack(entries)
    back = image.unpack(packed)
    assert np.array_equal(back["a"], entries["a"]) and back["n"][0] == 3 and back["s"] == 2.5
    # a Python scalar's entry (packed in one struct) is that of the array of its one value
    assert image.pack({"s": 2.5, "n": 3, "b": True}) == image.pack({"s": np.array([2.5]), "n": np.array([3]),
                                                                   "b": np.array([1])})


def test_library_key_follows_sources_flags_and_compiler(tmp_path, monkeypatch):
    """The compiled runtime's folder changes with any source's contents, the compiler's path, FLAGS and
    the extra flags, and library() finds a library there without compiling, or compiles into a new one
    after an edit (compile_library stubbed: the key is under test, not the compiler)."""
    monkeypatch.setenv("FFRF_FMU_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv(build.EXTRA_CFLAGS_ENV, raising=False)
    src = tmp_path / "src"
    src.mkdir()
    for name in build.SOURCES + build.HEADERS:
        shutil.copy(build.HERE / name, src / name)
    monkeypatch.setattr(build, "_KEYED", tuple(str(src / n) for n in build.SOURCES + build.HEADERS))
    cc = ["/usr/bin/cc"]
    key = build.library_key(cc)
    assert key == build.file_digest([build.HERE / n for n in build.SOURCES + build.HEADERS], (*cc, *build.FLAGS))
    assert build.library_key(["/opt/other/cc"]) != key
    assert build.library_key(cc, ("-ffp-contract=fast",)) != key
    monkeypatch.setenv("FFRF_FMU_CC", cc[0])
    compiled = []
    monkeypatch.setattr(build, "compile_library", lambda out, cc, extra: (compiled.append(out), out.write_bytes(b"lib")))
    first = build.library()
    assert compiled and first.parent.name == key and first.read_bytes() == b"lib"
    assert build.library() == first and len(compiled) == 1  # found: not compiled again
    real_compiler = build.compiler
    monkeypatch.setattr(build, "compiler", lambda: pytest.fail("the compiler looked up for a library in the cache"))
    assert build.library() == first  # the remembered folder: no scan of $PATH, no key hashed
    monkeypatch.setattr(build, "compiler", real_compiler)
    first.unlink()  # a library gone from its folder: the key computed afresh, compiled again
    assert build.library() == first and len(compiled) == 2 and first.read_bytes() == b"lib"
    compiled.pop()
    st = os.stat(src / "step.c")
    (src / "step.c").write_text((src / "step.c").read_text() + "\n")  # an edit the key must see
    os.utime(src / "step.c", ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    second = build.library()
    assert len(compiled) == 2 and second.parent.name != key
    monkeypatch.setenv(build.EXTRA_CFLAGS_ENV, "-ffp-contract=fast")
    assert build.library().parent.name not in (key, second.parent.name) and len(compiled) == 3
    monkeypatch.setattr(build, "FLAGS", (*build.FLAGS, "-O3"))
    assert build.library_key(cc) != key


@pytest.mark.parametrize("name", ["cc", "sh", "no-such-program-here"])
def test_which_is_shutil_which(name):
    """The compiler's lookup on $PATH (build._which) finds what shutil.which finds."""
    assert build._which(name) == shutil.which(name)


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
