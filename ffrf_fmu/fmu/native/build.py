"""The native FMU's binaries: the C runtime (runtime/native) and the FMI layer (fmu/native) compiled into
one shared library per target, body-independent, built once per source version and target into the user
cache (`~/.cache/ffrf-fmu/fmu-binaries`, or under $FFRF_FMU_CACHE_DIR).

Targets: linux64 (x86_64-linux-gnu.2.17: glibc 2.17 or newer, no libstdc++) and win64
(x86_64-windows-gnu), both with `zig cc` of the PyPI package ziglang (it cross-compiles), or linux64 with
the system C compiler when asked (compiler="system"). One binary per FMI version (fmi=2: fmi2Functions.c,
fmi=3: fmi3Functions.c, over the same model and runtime). zig builds a target's C library once per machine
(the first build of a target takes long: README, "Set up"); the build prints its progress meanwhile.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from ...runtime.native.build import FLAGS as RUNTIME_FLAGS, build_lock

HERE = Path(__file__).resolve().parent  # ffrf_fmu/fmu/native
RUNTIME = HERE.parent.parent / "runtime" / "native"
# the runtime's own flags (runtime/native/build.py: -ffp-contract=off, no fast-math: the floating-point
# operations as written, so the FMU computes the standalone run's bits), and only the fmi2 functions exported
FLAGS = [*RUNTIME_FLAGS, "-fvisibility=hidden"]


@dataclass(frozen=True)
class Target:
    """One FMI platform: its binaries/ folder, zig's target triple, the library suffix."""

    platform: str  # FMI 2.0 binaries/<platform>
    zig: str
    suffix: str
    platform3: str  # FMI 3.0 binaries/<platform tuple>


TARGETS = {
    "linux64": Target("linux64", "x86_64-linux-gnu.2.17", ".so", "x86_64-linux"),
    "win64": Target("win64", "x86_64-windows-gnu", ".dll", "x86_64-windows"),
}


class NativeBuildError(RuntimeError):
    """The native binary cannot be built (the message says why)."""


FMI_VERSIONS = (2, 3)


def sources(fmi: int = 2) -> list[Path]:
    """The C sources compiled into an FMU binary (runtime first, then the model and the FMI layer of version
    `fmi`: fmi2Functions.c or fmi3Functions.c, one per binary)."""
    if fmi not in FMI_VERSIONS:
        raise NativeBuildError(f"FMI version must be one of {FMI_VERSIONS}, got {fmi!r}")
    layer = [f for f in sorted(HERE.glob("*.c")) if not (f.name.startswith("fmi") and f.name != f"fmi{fmi}Functions.c")]
    return sorted(RUNTIME.glob("*.c")) + layer


def headers() -> list[Path]:
    return sorted(RUNTIME.glob("*.h")) + sorted(HERE.glob("*.h"))


def source_digest() -> str:
    """A digest of every source, header and flag: the cache key of the binaries (with target and compiler)."""
    h = hashlib.sha256(" ".join(FLAGS).encode())
    for f in sorted(RUNTIME.glob("*.c")) + sorted(HERE.glob("*.c")) + headers():
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


def cache_dir() -> Path:
    root = os.environ.get("FFRF_FMU_CACHE_DIR")
    base = Path(root) if root else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "ffrf-fmu"
    return base / "fmu-binaries"


def _compiler(target: Target, compiler: str) -> list[str]:
    if compiler == "zig":
        try:
            import ziglang  # noqa: F401 - only to say clearly when it is missing
        except ImportError:
            raise NativeBuildError("the PyPI package ziglang is not installed (pip install ziglang), or build with "
                                   "the system compiler (--compiler system, linux64 only)") from None
        return [sys.executable, "-m", "ziglang", "cc", "-target", target.zig]
    if compiler == "system":
        if target.platform != "linux64" or not sys.platform.startswith("linux"):
            raise NativeBuildError(f"the system compiler builds linux64 on Linux only (asked: {target.platform}); "
                                   "use zig for other targets")
        cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
        if not cc:
            raise NativeBuildError("no system C compiler found (set CC or install gcc), or build with zig")
        return [cc]
    raise NativeBuildError(f"compiler must be 'zig' or 'system', got {compiler!r}")


def _run_with_progress(cmd: list[str], what: str, log, zig: bool) -> subprocess.CompletedProcess:
    """Run cmd; after 3 s without an answer, tell `log` what is happening and every 10 s how long it took
    so far (zig's first build of a target's C library takes one to two minutes)."""
    done = threading.Event()

    def report():
        start = time.monotonic()
        if done.wait(3.0):
            return
        log(f"{what}: compiling" + (" (zig builds this target's C library once per machine: 1-2 minutes the first time)"
                                    if zig else "") + " ...")
        while not done.wait(10.0):
            log(f"{what}: {time.monotonic() - start:.0f} s")

    thread = threading.Thread(target=report, daemon=True)
    thread.start()
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    finally:
        done.set()
        thread.join()


def binary(platform: str = "linux64", compiler: str = "zig", log=None, extra_flags=(), fmi: int = 2) -> Path:
    """The cached shared library of the native FMU for `platform` and FMI version `fmi` (built now if missing)
    and its path."""
    if platform not in TARGETS:
        raise NativeBuildError(f"unknown platform {platform!r}; choose from {sorted(TARGETS)}")
    target = TARGETS[platform]
    log = log or (lambda text: print(text, file=sys.stderr, flush=True))
    flags = [*FLAGS, *extra_flags]
    layer = "" if fmi == 2 else f" fmi{fmi}"  # FMI 2.0's key as before: its cached binaries stay valid
    key = hashlib.sha256(f"{source_digest()} {platform} {compiler} {' '.join(flags)}{layer}".encode()).hexdigest()[:16]
    out = cache_dir() / key / f"ffrf_fmu{target.suffix}"
    if out.exists():
        return out
    cmd = _compiler(target, compiler)
    out.parent.mkdir(parents=True, exist_ok=True)
    with build_lock(out.parent):  # one build per key among processes sharing the cache
        if not out.exists():
            _build(cmd, target, flags, fmi, layer, out, log, compiler)
    return out


def _build(cmd, target: Target, flags, fmi: int, layer: str, out: Path, log, compiler: str) -> None:
    """Compile the binary of `target` into `out` (through a temporary file: atomic)."""
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        tmp_out = Path(tmp) / out.name
        link = ["-shared", "-s", "-o", str(tmp_out)]  # stripped: no symbol but the exported fmi2 (or fmi3) functions
        if target.platform == "linux64":
            link = ["-fPIC", *link, "-lm", "-Wl,--no-undefined"]
        full = [*cmd, *flags, f"-I{RUNTIME}", f"-I{HERE}", *map(str, sources(fmi)), *link]
        t0 = time.monotonic()
        done = _run_with_progress(full, f"native FMU binary {target.platform}{layer}", log, compiler == "zig")
        if done.returncode != 0:
            raise NativeBuildError(f"{' '.join(full)} failed:\n{done.stderr.strip()[:4000]}")
        os.replace(tmp_out, out)  # atomic: a concurrent build of the same key writes the same bytes
        elapsed = time.monotonic() - t0
        if elapsed > 3.0:
            log(f"native FMU binary {target.platform}{layer}: built in {elapsed:.1f} s (cached in {out.parent})")
