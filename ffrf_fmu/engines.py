"""Established co-simulation engines that cross-check ours, loaded the same way everywhere
(tests, .ci/check_imports.py, stability maps).

ecospy's engine library (libecosc.so) links against TBB's libtbb.so.12, which its wheel does not
ship. The PyPI package `tbb` (in the test extra) installs that library into <prefix>/lib, which the
dynamic loader does not search; loading it by path with RTLD_GLOBAL first lets libecosc.so find
it already loaded (by its soname), so no system package is needed.
"""
from __future__ import annotations

import ctypes
import importlib
import importlib.metadata
from types import ModuleType

TBB_LIBRARY = "libtbb.so.12"


def load_tbb() -> str | None:
    """Load the `tbb` package's libtbb.so.12 globally; its path, or None when that package is not
    installed (the system's TBB, if any, is then left to the loader)."""
    try:
        files = importlib.metadata.files("tbb") or []
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files:
        if f.name == TBB_LIBRARY:
            path = str(f.locate().resolve())
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            return path
    return None


def import_ecospy() -> ModuleType:
    """`import ecospy` with its TBB dependency loaded first (module doc)."""
    load_tbb()
    return importlib.import_module("ecospy")
