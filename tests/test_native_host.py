"""A body FMU in a host with no Python in it: tests/fmi2_host.c, compiled here
with the system C compiler, dlopens the FMU's binary without LD_PRELOAD, steps it, frees it,
dlcloses it and exits. The native FMU (fmu/native) runs so in a host started with `env -i` (the
system PATH only). For the pythonfmu FMU: pythonfmu's binary alone has undefined Py* symbols (PythonFMU issue #202)
and corrupts the heap at exit (PythonFMU issue #228); the FMU's native loader
(ffrf_fmu/fmu/native_loader.c) handles both. The numbers must be bit-identical to fmpy's run of the
same FMU with the same calls.
"""
from __future__ import annotations

import ctypes as C

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from ffrf_fmu.fmu.builder import build_fmu

ROOT = Path(__file__).resolve().parent.parent
CC = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the native loader is built on Linux only"),
    pytest.mark.skipif(CC is None, reason="no C compiler: the C host cannot be built (the FMU builder also needs one "
                                          "for the native loader)"),
]
OUTPUTS = ["tip.r[1]", "tip.r[2]", "tip.r[3]", "tip.v[3]", "hub.f[3]", "hub.t[2]", "energy.strain"]
FORCE = 1.0  # N on tip.f[3] from initialization on: the B1 beam bends under it while the hub holds still


_BUILT: dict = {}


def _b1(runtime, tmp_path_factory):
    """The B1 FMU of a runtime (models/haug_beam.toml, spinup: 4 superelements, 6 modes, h = 2 ms), unzipped,
    and the compiled host; built once per runtime."""
    if runtime not in _BUILT:
        d = tmp_path_factory.mktemp(f"host_{runtime}")
        fmu = build_fmu(ROOT / "models" / "haug_beam.toml", d / "B1.fmu", scene="spinup", runtime=runtime,
                               platforms=("linux64",))
        unzip = Path(extract(str(fmu), str(d / "B1")))
        host = d / "fmi2_host"
        done = subprocess.run([CC, "-O1", f"-I{ROOT / 'ffrf_fmu' / 'fmu' / 'native'}", "-o", str(host),
                               str(ROOT / "tests" / "fmi2_host.c"), "-ldl"],
                              capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        _BUILT[runtime] = (fmu, unzip, host, read_model_description(str(fmu)))
    return _BUILT[runtime]


@pytest.fixture(scope="module", params=["native", "python"])
def b1(request, tmp_path_factory):
    """The B1 FMU of each runtime: the native one runs in a host started with an empty environment (env -i,
    the system PATH only: no Python anywhere in the process), the pythonfmu one with the test's environment."""
    return _b1(request.param, tmp_path_factory)


@pytest.fixture(scope="module")
def b1_python(tmp_path_factory):
    return _b1("python", tmp_path_factory)


def _host(b1, *args, env_extra=None):
    fmu, unzip, host, md = b1
    binary = unzip / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    cmd = [str(host), args[0], str(binary), (unzip / "resources").as_uri(), md.guid, *map(str, args[1:])]
    if (unzip / "resources" / "body.bin").exists():  # native: nothing of this process's environment
        return subprocess.run(["env", "-i", "PATH=/usr/bin:/bin", *cmd], capture_output=True, text=True, timeout=600)
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONPATH", "PYTHONHOME",
                                                            "FFRF_FMU_LIBPYTHON")}
    env.update(env_extra or {})
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)


def _vr(md, names):
    by = {v.name: v.valueReference for v in md.modelVariables}
    return [by[n] for n in names]


def _fmpy_run(b1, steps, H):
    return _fmpy_run_outputs(b1, steps, H, OUTPUTS)


def _fmpy_run_outputs(b1, steps, H, outputs):
    fmu, unzip, host, md = b1
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unzip), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="fmpy")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal(_vr(md, ["tip.f[3]"]), [FORCE])
    s.exitInitializationMode()
    for k in range(steps):
        s.doStep(k * H, H)
    out = s.getReal(_vr(md, outputs))
    s.terminate()
    s.freeInstance()
    return np.array(out)


def _parse(stdout):
    return {(int(c), int(k)): np.array([float(x) for x in rest]) for c, k, *rest in (ln.split() for ln in stdout.splitlines())}


def test_b1_runs_1s_in_a_c_host_bit_identical_to_fmpy(b1):
    fmu, unzip, host, md = b1
    H, steps = 2e-3, 500  # 1 s at the scene's step
    done = _host(b1, "run", steps, H, 1, 1, _vr(md, ["tip.f[3]"])[0], FORCE, *_vr(md, OUTPUTS))
    assert done.returncode == 0, f"exit status {done.returncode}\n{done.stderr[-3000:]}"  # 134 before: heap corruption
    got = _parse(done.stdout)[(0, 0)]
    ref = _fmpy_run(b1, steps, H)
    assert got[2] > 1e-3  # the tip moved under the load: the comparison means something
    assert np.array_equal(got, ref), (got, ref)


def test_two_instances_and_instantiate_free_instantiate_in_a_c_host(b1):
    """Two instances side by side, freed and instantiated again (3 cycles) in one process: every
    instance gives fmpy's numbers, and the process exits with status 0 after dlclose."""
    fmu, unzip, host, md = b1
    H, steps = 2e-3, 25
    done = _host(b1, "run", steps, H, 2, 3, _vr(md, ["tip.f[3]"])[0], FORCE, *_vr(md, OUTPUTS))
    assert done.returncode == 0, f"exit status {done.returncode}\n{done.stderr[-3000:]}"
    got = _parse(done.stdout)
    ref = _fmpy_run(b1, steps, H)
    assert sorted(got) == [(c, k) for c in range(3) for k in range(2)]
    for key, values in got.items():
        assert np.array_equal(values, ref), key


def test_directional_derivatives_in_a_c_host_equal_fmpys(b1):
    """The step's derivatives (ffrf2GetStepDerivative) through the native loader in a host without Python (the
    loader routes them through pythonfmu's own SetReal/GetReal of the instance, docs/fmu.md): two instances,
    each gives what the same call gives under fmpy bit for bit, and the process exits 0."""
    fmu, unzip, host, md = b1
    H, steps = 2e-3, 10
    vr_in = _vr(md, ["tip.f[3]"])[0]
    done = _host(b1, "derivative", steps, H, 2, 1, vr_in, FORCE, *_vr(md, OUTPUTS))
    assert done.returncode == 0, f"exit status {done.returncode}\n{done.stderr[-3000:]}"
    got = [np.array([float(x) for x in ln.split()[3:]]) for ln in done.stdout.splitlines() if ln.startswith("d ")]
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unzip), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="fmpy")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([vr_in], [FORCE])
    s.exitInitializationMode()
    for k in range(steps):
        s.doStep(k * H, H)
    step = s.dll.ffrf2GetStepDerivative
    step.argtypes = [C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_uint), C.c_size_t,
                     C.POINTER(C.c_double), C.POINTER(C.c_double)]
    outs = _vr(md, OUTPUTS)
    out = (C.c_double * len(outs))()
    assert step(s.component, (C.c_uint * len(outs))(*outs), len(outs), (C.c_uint * 1)(vr_in), 1,
                (C.c_double * 1)(1.0), out) == 0
    ref = np.array(out[:])
    s.terminate()
    s.freeInstance()
    assert len(got) == 2 and ref[2] > 0.0  # pushing the tip up moves it up
    for d in got:
        assert np.array_equal(d, ref), (d, ref)


def test_bad_calls_in_a_c_host_are_errors_and_never_crash(b1):
    """Each bad call twice, then free and unload: fmi2Error every time (3), logged with a category
    (pythonfmu alone: fmi2Fatal with a NULL category, then a segfault on the second call)."""
    fmu, unzip, host, md = b1
    real, integer, rho = _vr(md, ["tip.f[3]", "solver.terms", "solver.rho_inf"])
    done = _host(b1, "faults", real, integer, rho, 2.0)
    assert done.returncode == 0, f"exit status {done.returncode}\n{done.stderr[-3000:]}"
    lines = [ln.split() for ln in done.stdout.splitlines()]
    assert len(lines) == 12 and all(status == "3" for _, status in lines), done.stdout
    assert "(null category)" not in done.stderr
    assert "solver.rho_inf must be in [0, 1], got 2.0" in done.stderr
    assert "unknown value reference(s) [1000000]" in done.stderr


def test_libpython_override_is_used_and_a_bad_one_is_reported(b1_python):
    """FFRF_FMU_LIBPYTHON replaces the recorded libpython: a file that is not there makes
    fmi2Instantiate return NULL with the path and the loader's reason in the log (no crash)."""
    fmu, unzip, host, md = b1_python
    args = ("run", 1, 2e-3, 1, 1, _vr(md, ["tip.f[3]"])[0], FORCE, _vr(md, ["tip.r[3]"])[0])
    bad = _host(b1_python, *args, env_extra={"FFRF_FMU_LIBPYTHON": "/nonexistent/libpython3.so"})
    assert bad.returncode == 5, bad.stderr  # the host's exit code for a NULL instance
    assert "cannot load libpython (/nonexistent/libpython3.so; set FFRF_FMU_LIBPYTHON to override)" in bad.stderr
    recorded = (unzip / "resources" / "ffrf_libpython.txt").read_text().splitlines()[0]  # line 2: the Python home
    good = _host(b1_python, *args, env_extra={"FFRF_FMU_LIBPYTHON": recorded})
    assert good.returncode == 0, good.stderr
    assert np.array_equal(_parse(good.stdout)[(0, 0)], _fmpy_run_outputs(b1_python, 1, 2e-3, ["tip.r[3]"]))


ECOS_RUN = r"""
import json, sys
from ffrf_fmu.engines import import_ecospy  # loads the tbb package's libtbb.so.12 first
ecospy = import_ecospy()
EcosSimulation, EcosSimulationStructure = ecospy.EcosSimulation, ecospy.EcosSimulationStructure
fmu, steps, H, names = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4].split(",")
with EcosSimulationStructure() as ss:
    ss.add_model("body", f"proxyfmu://localhost?file={fmu}")
    ss.add_parameter_set("load", {"body::tip.f[3]": float(sys.argv[5])})
    with EcosSimulation(structure=ss, step_size=H) as sim:
        sim.init(parameter_set="load")
        sim.step(steps)
        out = [sim.get_real(f"body::{n}") for n in names]
        t = sim.get_time()
        sim.terminate()
print(json.dumps({"t": t, "out": out}))
"""


def test_b1_runs_1s_in_ecos_out_of_process_bit_identical_to_fmpy(b1, tmp_path):
    """ecos's proxyfmu (a C++ process that loads the FMU; it died with SIGSEGV unless libpython
    was in LD_PRELOAD) runs the B1 FMU 1 s: fmpy's numbers, and the proxy process exits 0."""
    from ffrf_fmu.engines import import_ecospy

    ecospy = import_ecospy()
    fmu, unzip, host, md = b1
    # ecospy 0.7.2's wheel installs its proxyfmu executable without the execute bit: run a copy
    proxy = Path(ecospy.__file__).parent / "binaries" / "proxyfmu"
    bindir = tmp_path / "bin"
    bindir.mkdir()
    shutil.copy(proxy, bindir / "proxyfmu")
    (bindir / "proxyfmu").chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONPATH")}
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    (tmp_path / "run.py").write_text(ECOS_RUN)
    H, steps = 2e-3, 500
    done = subprocess.run([sys.executable, str(tmp_path / "run.py"), str(fmu), str(steps), str(H), ",".join(OUTPUTS),
                           str(FORCE)], capture_output=True, text=True, timeout=600, env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    assert "returned with status 0" in done.stdout + done.stderr  # the proxy process's own exit status
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got["t"] == pytest.approx(1.0, abs=1e-9)
    assert np.array_equal(np.array(got["out"]), _fmpy_run(b1, steps, H))


@pytest.mark.parametrize("form", ["file:/abs", "missing folder", "empty environment"])
def test_resource_forms_and_an_empty_environment_in_a_c_host(b1, form, tmp_path):
    """Both runtimes in a C host: `file:/abs` (a form FMI 2.0 hosts use) runs; a missing resources folder
    makes fmi2Instantiate return NULL with the folder named (pythonfmu's binary segfaulted the host on
    both); and a host started with `env -i PATH=/usr/bin:/bin`, where Debian's python3 comes first on PATH,
    runs (the pythonfmu FMU's loader sets PYTHONHOME to the recorded Python's home: without it the
    embedded interpreter took its prefix from that python3 and found no standard library)."""
    fmu, unzip, host, md = b1
    binary = unzip / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    uri = {"file:/abs": f"file:{unzip / 'resources'}", "missing folder": (tmp_path / "nowhere").as_uri(),
           "empty environment": (unzip / "resources").as_uri()}[form]
    args = [str(host), "run", str(binary), uri, md.guid, "5", "0.002", "1", "1", str(_vr(md, ["tip.f[3]"])[0]),
            str(FORCE), str(_vr(md, ["tip.r[3]"])[0])]
    done = subprocess.run(["env", "-i", "PATH=/usr/bin:/bin", *args], capture_output=True, text=True, timeout=600)
    if form == "missing folder":
        assert done.returncode == 5, done.stderr  # the host's exit code for a NULL instance
        assert str(tmp_path / "nowhere") in done.stderr and "missing" in done.stderr
        return
    assert done.returncode == 0, done.stderr[-3000:]
    got, ref = _parse(done.stdout)[(0, 0)], _fmpy_run_outputs(b1, 5, 0.002, ["tip.r[3]"])
    if (unzip / "resources" / "body.bin").exists():
        assert np.array_equal(got, ref)
    else:  # numpy's BLAS in the empty environment picks its own thread count: the last bits may differ
        assert np.allclose(got, ref, rtol=1e-12, atol=0.0) and ref[0] > 1e-4
