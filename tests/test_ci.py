"""The CI's dependency check (.ci/check_imports.py, run by .ci/run before the tests): a declared
package that does not import fails the run; no test that needs it is silently skipped."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CHECK = ROOT / ".ci" / "check_imports.py"


def _check(env_extra: dict) -> subprocess.CompletedProcess:
    env = {**os.environ, **env_extra}
    return subprocess.run([sys.executable, str(CHECK)], capture_output=True, text=True, timeout=300, env=env)


def test_declared_packages_are_checked(tmp_path):
    """The engines and FMU tools the tests need are declared, so the check covers them; with all of
    them installed the check passes; with libcosimpy unimportable (a shadow package that raises, as a
    missing install or shared library does) it fails and names it."""
    sys.path.insert(0, str(CHECK.parent))
    try:
        import check_imports
    finally:
        sys.path.pop(0)
    names = check_imports.requirements(ROOT / "pyproject.toml")
    assert {"fmpy", "pythonfmu", "libcosimpy", "tbb", "ecospy", "numpy", "scipy", "pytest",
            "dask[distributed]"} <= set(names)
    ok = _check({})
    assert ok.returncode == 0, ok.stderr
    # dask[distributed] is checked by importing distributed (dask alone would import without it)
    for name in ("libcosimpy", "distributed"):
        shadow = tmp_path / name
        shadow.mkdir()
        (shadow / "__init__.py").write_text(f"raise ImportError('{name}: not installed (shadowed by the test)')\n")
    bad = _check({"PYTHONPATH": str(tmp_path) + os.pathsep + os.environ.get("PYTHONPATH", "")})
    assert bad.returncode == 1 and "not installed" in bad.stderr
    assert "libcosimpy: " in bad.stderr and "dask[distributed]: " in bad.stderr


def test_ecospy_loads_with_the_tbb_package():
    """ecospy's library needs libtbb.so.12, which only the PyPI package tbb provides here (no system
    TBB needed): import_ecospy loads it from that package, in a fresh interpreter, and ecospy's
    engine library is then mapped next to that very file."""
    code = ("from ffrf_fmu.engines import import_ecospy, load_tbb; import_ecospy(); "
            "maps = open('/proc/self/maps').read(); print(load_tbb() in maps, 'libecosc' in maps)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")})
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "True"]
