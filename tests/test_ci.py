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
    assert {"fmpy", "pythonfmu", "libcosimpy", "ecospy", "numpy", "scipy", "pytest"} <= set(names)
    ok = _check({})
    assert ok.returncode == 0, ok.stderr
    shadow = tmp_path / "libcosimpy"
    shadow.mkdir()
    (shadow / "__init__.py").write_text("raise ImportError('libcosimpy: not installed (shadowed by the test)')\n")
    bad = _check({"PYTHONPATH": str(tmp_path) + os.pathsep + os.environ.get("PYTHONPATH", "")})
    assert bad.returncode == 1 and "libcosimpy" in bad.stderr and "not installed" in bad.stderr
