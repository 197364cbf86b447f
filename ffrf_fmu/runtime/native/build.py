"""Compiling the C runtime: on first use, in seconds, into the user cache, keyed by its sources.

Why on first use and not at install: `pip install -e .` must work without a compiler in the path of the
build backend (an editable install runs no build step of ours), and a key by content means an edited
source, a second checkout or an upgrade compiles its own library once (about 2 s with gcc -O2) and later
processes load it (milliseconds). The compiler is $FFRF_FMU_CC, else the system's `cc`, else zig's
(the `ziglang` package, a dependency: a machine without a C compiler still runs).

Flags that decide the numbers: -O2 without fast-math and -ffp-contract=off (no fused multiply-adds), so
the floating-point operations are those written, in that order, whatever the compiler: the standalone
run and an FMU built by another compiler for the same machine then compute the same bits (glibc's libm
is the same at run time). The cache is $FFRF_FMU_CACHE_DIR, else $XDG_CACHE_HOME/ffrf-fmu, else
~/.cache/ffrf-fmu; a temporary directory if none can be written.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import sys
from contextlib import contextmanager
from pathlib import Path

HERE = Path(__file__).resolve().parent
HERE_STR = str(HERE)
SOURCES = ("so3.c", "lu.c", "superelement.c", "factor.c", "step.c", "accel.c", "advance.c", "body.c", "initial.c")
HEADERS = ("ffrf_runtime.h", "layout.h", "bytes.h", "so3.h", "lu.h", "superelement.h", "factor.h", "step.h", "accel.h", "advance.h", "body.h", "initial.h")
# -ffp-contract=off: the operations as written on every compiler (gcc contracts in GNU mode, clang/zig
# within expressions); -fvisibility=hidden with the public API marked by FFRF_API (ffrf_runtime.h)
FLAGS = ("-std=c11", "-O2", "-ffp-contract=off", "-fno-fast-math", "-Wall", "-Wextra", "-Werror", "-pedantic")
# $FFRF_FMU_EXTRA_CFLAGS (split on spaces) goes after FLAGS and into the cache key: the round-off check of
# .ci/run compiles the runtime with -ffp-contract=fast, as another compiler or CPU would round
EXTRA_CFLAGS_ENV = "FFRF_FMU_EXTRA_CFLAGS"
SANITIZE = ("-fsanitize=address,undefined", "-fno-sanitize-recover=undefined", "-fno-omit-frame-pointer", "-g")


class BuildError(RuntimeError):
    """The runtime could not be compiled: the message names the compiler, the command and its errors."""


def cache_root() -> Path:
    return Path(cache_dir())


def cache_dir() -> str:
    """cache_root() as a plain string (pathlib's first calls in a process cost more than a run's lookups)."""
    env = os.environ.get("FFRF_FMU_CACHE_DIR")
    if env:
        return env
    xdg = os.environ.get("XDG_CACHE_HOME")
    return os.path.join(xdg or os.path.join(os.path.expanduser("~"), ".cache"), "ffrf-fmu")


def sources() -> list[Path]:
    return [HERE / s for s in SOURCES]


_KEYED = tuple(os.path.join(HERE_STR, name) for name in SOURCES + HEADERS)  # the files of the cache key


def source_digest(extra: tuple[str, ...] = ()) -> str:
    """sha256 of the runtime's sources and headers (and the compile command's words): the cache key."""
    return remembered_digest(_KEYED, extra)


def file_digest(paths, extra: tuple[str, ...] = ()) -> str:
    """sha256 over each file's name and contents, then the words of `extra`: 16 hex digits."""
    h = hashlib.sha256()
    for path in paths:
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    for word in extra:
        h.update(word.encode() + b"\0")
    return h.hexdigest()[:16]


def remembered_digest(paths, extra: tuple[str, ...] = ()) -> str:
    """file_digest(paths, extra), remembered in the cache (<cache>/digests/) under the files' stat
    signature (path, size, modification time in ns) and `extra`: a process whose files did not change
    since the last one reads one small file, not every source (a run's set-up would pay reading and
    hashing them, about 0.7 ms for the runtime's). An edited file changes its signature and is read
    afresh; without a writable cache the digest is computed each time. (Plain strings and os: pathlib's
    first calls in a process cost more than the memo saves.)"""
    return remembered(paths, extra, lambda names: file_digest([Path(q) for q in names], extra))


def remembered(paths, extra: tuple[str, ...], compute) -> str:
    """compute(names) (a short ASCII word, the names the paths' strings), remembered in <cache>/digests/
    under the files' stat signature and the words of `extra` (remembered_digest); computed each time
    when a file cannot be stat'ed or the cache cannot be written."""
    names = [os.fspath(q) for q in paths]
    try:
        words = [f"{q}\0{st.st_size}\0{st.st_mtime_ns}" for q, st in ((q, os.stat(q)) for q in names)]
    except OSError:
        return compute(names)
    signature = hashlib.sha256("\0\0".join([*words, *extra]).encode()).hexdigest()[:32]
    folder = os.path.join(cache_dir(), "digests")
    memo = os.path.join(folder, signature)
    try:
        with open(memo, "rb") as fh:
            value = fh.read(65).decode("ascii")
        if 0 < len(value) <= 64:
            return value
    except (OSError, UnicodeDecodeError):
        pass
    value = compute(names)
    try:
        os.makedirs(folder, exist_ok=True)
        tmp = os.path.join(folder, f".{signature}.{os.getpid()}.tmp")
        with open(tmp, "w", encoding="ascii") as fh:
            fh.write(value)
        os.replace(tmp, memo)
    except OSError:  # a read-only cache: computed again next time
        pass
    return value


def extra_cflags() -> tuple[str, ...]:
    """The words of $FFRF_FMU_EXTRA_CFLAGS (none when unset)."""
    return tuple(os.environ.get(EXTRA_CFLAGS_ENV, "").split())


def compiler() -> list[str]:
    """The command of the C compiler: $FFRF_FMU_CC (split on spaces), cc / gcc / clang on the PATH, else
    zig's from the ziglang package (`python -m ziglang cc`)."""
    env = os.environ.get("FFRF_FMU_CC")
    if env:
        return env.split()
    for name in ("cc", "gcc", "clang"):
        path = _which(name)
        if path:
            return [path]
    try:
        import ziglang  # noqa: F401
    except ImportError:
        raise BuildError("no C compiler: none of cc, gcc, clang on the PATH, and the ziglang package is not "
                         "installed (pip install ziglang), or set FFRF_FMU_CC") from None
    return [sys.executable, "-m", "ziglang", "cc"]


def _which(name: str) -> str | None:
    """shutil.which(name) on POSIX as a plain scan of $PATH (a third of its cost: every run looks up the
    compiler, whose path is part of the cache key); shutil.which itself on Windows (PATHEXT)."""
    if sys.platform == "win32":
        return shutil.which(name)
    for folder in os.environ.get("PATH", os.defpath).split(os.pathsep):
        path = os.path.join(folder, name)
        if os.access(path, os.X_OK) and not os.path.isdir(path):
            return path
    return None


def _library_name() -> str:
    return "ffrf_runtime.dll" if sys.platform == "win32" else "libffrf_runtime.so"


def compile_library(out: Path, cc: list[str] | None = None, extra: tuple[str, ...] = ()) -> None:
    """Compile the runtime into the shared library `out`; raises BuildError with the compiler's words."""
    import subprocess  # (here: a run that finds its library compiled does not import it)

    cc = cc or compiler()
    cmd = [*cc, *FLAGS, *extra, "-shared", "-fPIC", "-o", str(out), *map(str, sources()), "-lm"]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise BuildError(f"{' '.join(cmd)}: {e}") from None
    if done.returncode != 0:
        raise BuildError(f"{' '.join(cmd)} failed:\n{done.stderr.strip()[:4000]}")


@contextmanager
def build_lock(folder: Path):
    """Hold an exclusive lock on `folder`/.lock (fcntl.flock) while a build into `folder` runs: concurrent
    processes sharing a cache (pytest-xdist's workers, a sweep's pool) build each key once, the others wait
    and find the file. Where flock is missing (Windows) or the lock file cannot be made: no lock (the builds
    still land atomically, os.replace, so a race only costs a second build)."""
    try:
        import fcntl
        fh = open(folder / ".lock", "a")
    except (ImportError, OSError):
        yield
        return
    try:
        fcntl.flock(fh, fcntl.LOCK_EX)
        yield
    finally:
        fh.close()  # releases the lock


PREBUILT = "prebuilt"  # a compiled runtime shipped beside these modules (a pythonfmu FMU's private copy: `ship`)


def library(sanitize: bool = False) -> Path:
    """The compiled runtime for this machine, compiled into the cache on first use (atomically: a
    process that loses a race uses the winner's file). sanitize: the address and undefined-behaviour
    sanitizer build (tests; its process needs libasan preloaded: `sanitizer_preload`). A copy of this
    package shipped in a pythonfmu FMU carries its library in prebuilt/ (`ship`): no compiler on the host."""
    return Path(library_path(sanitize))


def library_path(sanitize: bool = False) -> str:
    """`library` as a plain string (what ctypes loads; a Path costs more than the lookup's stat)."""
    name = _library_name()
    flags = extra_cflags()
    shipped = os.path.join(HERE_STR, PREBUILT, name)
    if not sanitize and not flags and os.path.exists(shipped):  # extra flags: built here, never the shipped one
        return shipped
    extra = (*flags, *(SANITIZE if sanitize else ()))
    suffix = "-sanitize" if sanitize else ""
    # the folder of the last process with these sources and the same compiler request ($FFRF_FMU_CC, $PATH),
    # remembered (`remembered`): a run that finds its library neither scans $PATH for the compiler nor hashes
    # the key; a missing library (or a cache without the memo) computes the key afresh
    request = ("library", os.environ.get("FFRF_FMU_CC", ""), os.environ.get("PATH", os.defpath), *FLAGS, *extra, suffix)
    folder = remembered(_KEYED, request, lambda _: library_key(compiler(), extra) + suffix)
    if os.path.exists(found := os.path.join(cache_dir(), "native", folder, name)):  # (one stat: the usual case)
        return found
    cc = compiler()
    folder = library_key(cc, extra) + suffix
    for root in _cache_roots():
        if os.path.exists(found := os.path.join(root, "native", folder, name)):
            return found
        d = Path(root, "native", folder)
        lib = d / name
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        with build_lock(d):
            if not lib.exists():  # another process may have built it while this one waited
                tmp = d / f".{lib.name}.{os.getpid()}.tmp"
                compile_library(tmp, cc, extra)
                os.replace(tmp, lib)
        return str(lib)
    raise BuildError("no writable cache directory for the compiled runtime (set FFRF_FMU_CACHE_DIR)")


def library_key(cc: list[str], extra: tuple[str, ...] = ()) -> str:
    """The compiled runtime's folder in the cache: the digest of the sources and headers, the compiler's
    path, FLAGS and the extra flags; any change of them compiles afresh."""
    return source_digest((*cc[-1:], *FLAGS, *extra))


def _cache_roots():
    """The cache, then a temporary directory (asked for only when the cache cannot be written:
    tempfile.gettempdir's first call writes a probe file)."""
    yield cache_dir()
    import tempfile  # (after the first: a run with a writable cache does not import it)

    yield os.path.join(tempfile.gettempdir(), f"ffrf-fmu-{os.getuid() if hasattr(os, 'getuid') else 0}")


def ship(dest: Path) -> None:
    """This package's Python modules and the runtime compiled here (`library`) into dest, dest/prebuilt: the
    C runtime of a pythonfmu FMU's private package (fmu/builder.py), loaded there without a compiler."""
    (dest / PREBUILT).mkdir(parents=True, exist_ok=True)
    for f in sorted(HERE.glob("*.py")):
        shutil.copy(f, dest / f.name)
    shutil.copy(library(), dest / PREBUILT / _library_name())


def sanitizer_preload() -> str:
    """The path of the compiler's libasan, for LD_PRELOAD of a process that loads the sanitizer build."""
    import subprocess

    cc = compiler()
    out = subprocess.run([*cc, "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    return out
