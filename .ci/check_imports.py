"""CI: every package the project declares (dependencies and the test extra of pyproject.toml) must
import, so that a broken install fails the run instead of skipping the tests that need it.

Each requirement imports as its distribution name (lower case, '-' -> '_'); requirements with an
environment marker are checked only where the marker holds for the common cases (python_version).
A package whose module name differs goes in MODULE. Exit 1 naming every package that fails."""
from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli is a dependency there
    import tomli as tomllib

MODULE = {"libcosimpy": "libcosimpy.CosimExecution"}  # the package imports lazily: load its library


def requirements(pyproject: Path) -> list[str]:
    project = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]
    reqs = list(project.get("dependencies", [])) + list(project.get("optional-dependencies", {}).get("test", []))
    names = []
    for req in reqs:
        spec, _, marker = req.partition(";")
        m = re.fullmatch(r"\s*python_version\s*<\s*['\"](\d+)\.(\d+)['\"]\s*", marker) if marker else None
        if marker and not (m and sys.version_info[:2] < (int(m[1]), int(m[2]))):
            continue
        names.append(re.match(r"[A-Za-z0-9_.-]+", spec.strip())[0])
    return names


def main() -> int:
    root = Path(__file__).resolve().parent.parent
    failed = []
    for name in requirements(root / "pyproject.toml"):
        module = MODULE.get(name.lower(), name.lower().replace("-", "_"))
        try:
            importlib.import_module(module)
        except Exception as e:  # noqa: BLE001 - ImportError, or OSError of a missing shared library
            failed.append(f"{name} (import {module}): {type(e).__name__}: {e}")
    if failed:
        print("ci: declared packages that do not import:\n  " + "\n  ".join(failed), file=sys.stderr)
        return 1
    print(f"ci: all {len(requirements(root / 'pyproject.toml'))} declared packages import")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
