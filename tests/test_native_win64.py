"""The native FMU's win64 binary, built on Linux by zig: what it exports and imports (objdump -p), and a
run in wine (Debian's wine64; .ci/run installs it) through tests/fmi2_host.c cross-compiled for Windows
by the same zig, against the linux64 binary in the same host on Linux.

The two binaries are the same C compiled for two targets with -ffp-contract=off semantics of the runtime
(no fused multiply-adds): measured bit-identical over 100 steps of B1 (2026-11-27), so the test asks for
equality; a libm of another platform that rounded a sine or a square root differently would show here
first (then the tolerance would be the argued one, not silence).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description

from ffrf_fmu.fmu.builder import build_fmu

ROOT = Path(__file__).resolve().parent.parent
OUTPUTS = ["tip.r[1]", "tip.r[2]", "tip.r[3]", "tip.v[3]", "hub.f[3]", "energy.strain"]
WINE = shutil.which("wine64") or shutil.which("wine")
FMI2_CS = ("fmi2Instantiate", "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
           "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal", "fmi2SetReal", "fmi2DoStep",
           "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
           "fmi2GetDirectionalDerivative", "fmi2GetTypesPlatform", "fmi2GetVersion")


@pytest.fixture(scope="module")
def b1(tmp_path_factory):
    d = tmp_path_factory.mktemp("win64")
    fmu = build_fmu(ROOT / "models" / "haug_beam.toml", d / "B1.fmu", scene="spinup",
                           platforms=("linux64", "win64"))
    unzip = Path(extract(str(fmu), str(d / "B1")))
    md = read_model_description(str(fmu))
    return unzip, md, d


def _dll(b1) -> Path:
    unzip, md, _ = b1
    return unzip / "binaries" / "win64" / f"{md.coSimulation.modelIdentifier}.dll"


def test_the_dll_exports_fmi2_only_and_imports_the_windows_c_runtime_only(b1):
    """objdump -p: the exports are the fmi2 functions (every co-simulation one) and ffrf2GetStepDerivative, nothing of the runtime or
    the body; the imports are KERNEL32 and the Universal C Runtime's api sets (Windows 10 and newer ship
    them; older Windows need Microsoft's UCRT update), no libstdc++, no libgcc, no Python."""
    text = subprocess.run(["objdump", "-p", str(_dll(b1))], capture_output=True, text=True, check=True).stdout
    table = text.split("[Ordinal/Name Pointer] Table", 1)[1].split("\n\n", 1)[0]
    exports = re.findall(r"\]\s+(\S+)", table)
    # fmi2* and the one documented non-FMI function (docs/fmu.md, "Directional derivatives")
    assert exports and all(name.startswith("fmi2") or name == "ffrf2GetStepDerivative" for name in exports), exports
    assert set(FMI2_CS) | {"ffrf2GetStepDerivative"} <= set(exports)
    imports = re.findall(r"DLL Name: (\S+)", text)
    assert "KERNEL32.dll" in imports
    assert all(d == "KERNEL32.dll" or d.startswith("api-ms-win-crt-") for d in imports), imports


def _run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900, **kw)


def test_win64_fmu_in_wine_equals_linux64(b1):
    """B1 under a 1 N tip load, 100 steps of 2 ms in fmi2_host.exe (wine) and fmi2_host (Linux): the same
    numbers, and the Windows process exits 0 after FreeLibrary."""
    assert WINE, "wine64 is not installed (apt-get install wine64; .ci/run installs it)"
    unzip, md, d = b1
    by = {v.name: v.valueReference for v in md.modelVariables}
    host_exe, host = d / "fmi2_host.exe", d / "fmi2_host"
    include = f"-I{ROOT / 'ffrf_fmu' / 'fmu' / 'native'}"  # the standard's FMI 2.0 types
    done = _run([sys.executable, "-m", "ziglang", "cc", "-target", "x86_64-windows-gnu", "-O1", include, "-o",
                 str(host_exe), str(ROOT / "tests" / "fmi2_host.c")])
    assert done.returncode == 0, done.stderr
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    done = _run([cc, "-O1", include, "-o", str(host), str(ROOT / "tests" / "fmi2_host.c"), "-ldl"])
    assert done.returncode == 0, done.stderr
    args = ["100", "0.002", "1", "1", str(by["tip.f[3]"]), "1.0", *[str(by[n]) for n in OUTPUTS]]
    env = {**os.environ, "WINEDEBUG": "-all", "WINEPREFIX": str(d / "wineprefix")}
    res = (unzip / "resources").as_posix()
    win = _run([WINE, str(host_exe), "run", f"Z:{_dll(b1)}", f"file:///Z:{res}", md.guid, *args], env=env)
    assert win.returncode == 0, win.stdout + win.stderr[-3000:]
    linux = _run([str(host), "run", str(unzip / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"),
                  (unzip / "resources").as_uri(), md.guid, *args])
    assert linux.returncode == 0, linux.stderr
    parse = lambda out: np.array([float(x) for x in out.split()[2:]])  # noqa: E731
    w, lx = parse(win.stdout), parse(linux.stdout)
    assert lx[2] > 1e-3  # the tip moved under the load
    assert np.array_equal(w, lx), (w, lx)
