"""CI: every package the project declares (dependencies and the test extra of pyproject.toml) must
import, so that a broken install fails the run instead of skipping the tests that need it.

Each requirement imports as its distribution name (lower case, '-' -> '_') unless MODULE (which
also names the module of a requirement with extras, e.g. dask[distributed] -> distributed) or
_import says otherwise (tbb ships a library, not a module; ecospy needs it loaded first);
requirements with a python_version marker are checked where the marker holds, other markers are
skipped. Exit 1 naming every package that fails."""
from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli is a dependency there
    import tomli as tomllib

MODULE = {"libcosimpy": "libcosimpy.CosimExecution",  # the package imports lazily: load its library
          "dask[distributed]": "distributed",  # the extra is what the project uses
          "scikit-fem": "skfem",
          "pynastran": "pyNastran",  # its module keeps the capitals
          "pytest-xdist": "xdist"}


def _import(name: str) -> None:
    """Import the distribution `name` the way the project uses it."""
    if name == "tbb":  # no Python module: the library it ships must load (ffrf_fmu/engines.py)
        from ffrf_fmu.engines import TBB_LIBRARY, load_tbb

        if load_tbb() is None:
            raise ImportError(f"{TBB_LIBRARY} is not among the files of the installed package")
    elif name == "ecospy":  # needs tbb's library loaded first (ffrf_fmu/engines.py)
        from ffrf_fmu.engines import import_ecospy

        import_ecospy()
    else:
        importlib.import_module(MODULE.get(name, name.replace("-", "_")))


def requirements(pyproject: Path) -> list[str]:
    project = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]
    reqs = list(project.get("dependencies", [])) + list(project.get("optional-dependencies", {}).get("test", []))
    names = []
    for req in reqs:
        spec, _, marker = req.partition(";")
        m = re.fullmatch(r"\s*python_version\s*<\s*['\"](\d+)\.(\d+)['\"]\s*", marker) if marker else None
        if marker and not (m and sys.version_info[:2] < (int(m[1]), int(m[2]))):
            continue
        names.append(re.match(r"[A-Za-z0-9_.-]+(\[[A-Za-z0-9_,.-]+\])?", spec.strip())[0])  # with its extras
    return names


def main() -> int:
    root = Path(__file__).resolve().parent.parent
    failed = []
    for name in requirements(root / "pyproject.toml"):
        try:
            _import(name.lower())
        except Exception as e:  # noqa: BLE001 - ImportError, or OSError of a missing shared library
            failed.append(f"{name}: {type(e).__name__}: {e}")
    if failed:
        print("ci: declared packages that do not import:\n  " + "\n  ".join(failed), file=sys.stderr)
        return 1
    print(f"ci: all {len(requirements(root / 'pyproject.toml'))} declared packages import")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
