"""The FMI 3.0 body FMU (`ffrf-fmu build --fmi 3`: fmu/native/fmi3Functions.c over the model of the FMI 2.0
FMU): its modelDescription (port fields as arrays, fmpy's validation), its runs against the FMI 2.0 FMU
and the standalone C runtime (B1, B2: bit for bit), the fault table of tests/test_fmu_faults.py with FMI
3.0 statuses, state and reset, directional and adjoint derivatives, a C host written against the FMI 3.0
headers (no Python in the process), `ffrf-fmu validate` and ecos.

The FMUs are built once per module (linux64 only; the win64 check is one test, skipped without wine).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from conftest import stepping_on_is_an_error
from ffrf_fmu.fmu.builder import BuildError, build_fmu
from ffrf_fmu.fmu.run import run_fmu, scalar_names
from ffrf_fmu.model import load_model

ROOT = Path(__file__).resolve().parent.parent
NATIVE = ROOT / "ffrf_fmu" / "fmu" / "native"
OK, DISCARD, ERROR = 0, 2, 3
SCENES = """
[scenes.still]
duration = 0.2
step = 0.01
"""
# B1 and B2 as the acceptance runs of tests/test_fmu.py take them, shortened to 0.4 s of the scenes
RUNS = {
    "B1": ("haug_beam.toml", "spinup", ["superelements=2", "duration=0.4"]),
    "B2": ("spherical_beam.toml", "torque_then_tip", ["duration=0.4"]),
}


@pytest.fixture(scope="module")
def small(tmp_path_factory, beam_toml):
    """(FMI 3.0 FMU, FMI 2.0 FMU, model file) of the small beam's scene `still`."""
    d = tmp_path_factory.mktemp("fmi3")
    model = d / "fmi3_beam.toml"
    model.write_text(beam_toml(SCENES, name="fmi3_beam"))
    three = build_fmu(model, d / "still3.fmu", scene="still", platforms=("linux64",), fmi=3)
    two = build_fmu(model, d / "still2.fmu", scene="still", platforms=("linux64",))
    return three, two, model


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{B1, B2: (FMI 3.0 FMU, FMI 2.0 FMU, model, scene)}."""
    d = tmp_path_factory.mktemp("fmi3_runs")
    out = {}
    for name, (file, scene, ov) in RUNS.items():
        model = load_model(ROOT / "models" / file, ov)
        three = build_fmu(ROOT / "models" / file, d / f"{name}_3.fmu", scene=scene, overrides=ov,
                                 platforms=("linux64",), fmi=3)
        two = build_fmu(ROOT / "models" / file, d / f"{name}_2.fmu", scene=scene, overrides=ov,
                               platforms=("linux64",))
        out[name] = (three, two, model, model.scene(scene))
    return out


class Slave3:
    """An fmpy FMU3Slave of an FMI 3.0 FMU with a log of (status, category, message), references by name."""

    def __init__(self, path, tmp):
        self.md = read_model_description(str(path))
        self.dir = extract(str(path), str(tmp))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.log: list[tuple[int, str, str]] = []
        self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="body")
        self.fmu.instantiate(loggingOn=True, logMessage=self._log)

    def _log(self, env, status, category, message):
        self.log.append((status, category.decode(), message.decode()))

    def vr(self, name):
        return self.vars[name].valueReference

    def status(self, call, *args, **kw) -> int:
        try:
            call(*args, **kw)
        except FMICallException as e:
            return e.status
        return OK

    def start(self, floats=None, ints=None, stop=None):
        f = self.fmu
        f.enterInitializationMode(startTime=0.0, stopTime=stop)
        for name, value in (floats or {}).items():
            f.setFloat64([self.vr(name)], list(np.ravel(value)))
        for name, value in (ints or {}).items():
            f.setInt32([self.vr(name)], [value])
        return self.status(f.exitInitializationMode)

    def get(self, names):
        return np.concatenate([self.fmu.getFloat64([self.vr(n)], nValues=len(scalar_names(self.vars[n])))
                               for n in names])

    def step_derivative(self, unknowns, knowns, seed, n_out, adjoint=False):
        """(status, values) of ffrf3GetStepDirectionalDerivative (or ...AdjointDerivative): the derivatives of the
        last step, exported beside the fmi3 functions with their arguments (docs/fmu.md); unknowns and knowns:
        value references of arrays, n_out the scalars returned."""
        import ctypes as C

        f = getattr(self.fmu.dll, "ffrf3GetStepAdjointDerivative" if adjoint else "ffrf3GetStepDirectionalDerivative")
        f.argtypes = [C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_uint), C.c_size_t,
                      C.POINTER(C.c_double), C.c_size_t, C.POINTER(C.c_double), C.c_size_t]
        f.restype = C.c_int
        out = (C.c_double * n_out)()
        status = f(self.fmu.component, (C.c_uint * len(unknowns))(*unknowns), len(unknowns),
                   (C.c_uint * len(knowns))(*knowns), len(knowns), (C.c_double * len(seed))(*seed), len(seed), out, n_out)
        return status, np.array(out[:])

    def close(self):
        self.fmu.freeInstance()
        self.fmu.freeLibrary()


# ------------------------------------------------------------------ the model description


def test_fmpy_validates_the_fmi3_fmu_and_ports_are_arrays_with_2_0s_units(small):
    three, two, _ = small
    assert validate_fmu(str(three)) == []
    md3, md2 = read_model_description(str(three)), read_model_description(str(two))
    assert md3.fmiVersion == "3.0" and md3.guid == md2.guid  # instantiationToken: the same body, the same token
    cs = md3.coSimulation
    import zipfile
    from xml.etree.ElementTree import fromstring

    attrs = fromstring(zipfile.ZipFile(three).read("modelDescription.xml")).find("CoSimulation").attrib
    for key, value in (("providesDirectionalDerivatives", "true"), ("providesAdjointDerivatives", "true"),
                       ("canGetAndSetFMUState", "true"), ("canSerializeFMUState", "true"), ("hasEventMode", "false"),
                       ("providesIntermediateUpdate", "false")):
        assert attrs[key] == value, key
    v3 = {v.name: v for v in md3.modelVariables}
    assert v3["time"].causality == "independent" and v3["time"].valueReference == 0
    shapes = {n: [int(d.start) for d in v.dimensions] for n, v in v3.items()}
    assert shapes["hub.r"] == [3] and shapes["hub.R"] == [3, 3] and shapes["hub.v"] == [3] and shapes["hub.w"] == [3]
    assert shapes["tip.f"] == [3] and shapes["tip.t"] == [3] and shapes["hub.f"] == [3] and shapes["tip.R"] == [3, 3]
    assert shapes["energy.strain"] == [] and v3["solver.terms"].type == "Int32"
    assert v3["hub.R"].start == "1.0 0.0 0.0 0.0 1.0 0.0 0.0 0.0 1.0"  # row-major: R[1,1], R[1,2], ...
    # every FMI 2.0 scalar is one element of one FMI 3.0 variable, with its unit, causality and description
    by2 = {v.name: v for v in md2.modelVariables}
    flat = {s: v for v in md3.modelVariables if v.name != "time" for s in scalar_names(v)}
    assert sorted(flat) == sorted(by2)
    for name, v in flat.items():
        w = by2[name]
        assert (v.unit, v.causality, v.variability) == (w.unit, w.causality, w.variability), name
        if not name.startswith("probe."):
            assert v.description == w.description, name
    binaries = [n for n in zipfile.ZipFile(three).namelist() if n.startswith("binaries/")]
    assert binaries == [f"binaries/x86_64-linux/{cs.modelIdentifier}.so"]


def test_the_binary_exports_the_fmi3_functions_only(small):
    three, _, _ = small
    d = Path(extract(str(three)))
    md = read_model_description(str(three))
    so = d / "binaries" / "x86_64-linux" / f"{md.coSimulation.modelIdentifier}.so"
    text = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True, check=True).stdout
    names = [ln.split()[-1] for ln in text.splitlines() if " T " in ln]
    declared = [ln.split("(")[0].split()[-1] for ln in (NATIVE / "fmi3FunctionTypes.h").read_text().splitlines()
                if ln.startswith("typedef") and "TYPE" in ln]
    declared = {n.removesuffix("TYPE").lstrip("*") for n in declared}
    step = {"ffrf3GetStepDirectionalDerivative", "ffrf3GetStepAdjointDerivative"}  # not FMI: docs/fmu.md
    assert names and all(n.startswith("fmi3") or n in step for n in names), names
    assert step <= set(names)
    assert declared <= set(names), declared - set(names)  # every function of the standard: hosts look each up
    shutil.rmtree(d)


def test_fmi3_is_native_only():
    with pytest.raises(BuildError, match="3 with the native runtime only"):
        build_fmu(ROOT / "models" / "haug_beam.toml", "/nonexistent/x.fmu", runtime="python", fmi=3)


# ------------------------------------------------------------------ runs


@pytest.mark.parametrize("name", sorted(RUNS))
def test_b1_b2_fmi3_equal_fmi2_and_the_standalone_runtime_bit_for_bit(runs, name, tmp_path):
    """The scene through both FMUs at H = h (fmu/run.py: fmpy's simulate_fmu for 2.0, the same input table
    and order of calls for 3.0): every column equal. Then the standalone C runtime (runtime/native/binding.py)
    from the FMI 3.0 FMU's initial state (its serialized state), stepped with the FMU's input rule (point
    values at each t_c, one EXTRAPOLATED advance per step): every output equal, bit for bit."""
    from ffrf_fmu.fmu.native.resource import images
    from ffrf_fmu.runtime import input_rule
    from ffrf_fmu.runtime.native.binding import EXTRAPOLATED, NativeBody
    from ffrf_fmu.simulate.inputs import scene_inputs
    from ffrf_fmu.simulate.results import column_names
    from ffrf_fmu.fmu.run import fmu_body, fmu_input_table

    three, two, model, sc = runs[name]
    a, b = run_fmu(two, sc), run_fmu(three, sc)
    assert a.reached and b.reached and np.array_equal(a.t, b.t)
    assert sorted(a.columns) == sorted(b.columns)
    for col in a.columns:
        assert np.array_equal(a.columns[col], b.columns[col]), col
    moved = max(np.abs(b.columns[f"tip.r[{i}]"] - b.columns[f"tip.r[{i}]"][0]).max() for i in (1, 2, 3))
    assert moved > 1e-6  # the body moved (B1: 2e-5 m in 0.4 s of the spin-up), 1e9 times the round-off of 8 m

    # the standalone C runtime from the FMU's state after initialization with the inputs at t = 0
    body_data = fmu_body(three)
    inputs = scene_inputs(body_data, sc, load_interval=(0.0, sc.step))
    table = fmu_input_table(three, inputs, b.t[:1])
    s = Slave3(three, tmp_path / "u")
    try:
        s.fmu.enterInitializationMode(startTime=0.0)
        for v in s.md.modelVariables:
            if v.causality == "input":
                s.fmu.setFloat64([v.valueReference], [float(table[n][0]) for n in scalar_names(v)])
        s.fmu.exitInitializationMode()
        state = s.fmu.getFMUState()
        raw = bytes(s.fmu.serializeFMUState(state))
        s.fmu.freeFMUState(state)
    finally:
        s.close()
    n_body = int.from_bytes(raw[16:24], "little")  # model.c: the serialized state's layout
    body = NativeBody(images((Path(s.dir) / "resources" / "body.bin").read_bytes())[sc.terms])
    body.set_state(np.frombuffer(raw[len(raw) - 8 * n_body:], dtype="<f8"))
    names = column_names(body_data)
    outputs = {n for v in read_model_description(str(three)).modelVariables if v.causality == "output"
               for n in scalar_names(v)} - {"solver.newton_iterations"}
    point = body.array("point_values").reshape(len(body_data.ports), input_rule.WIDTH)
    row = np.empty(len(names))
    compared = 0
    given = {n for v in read_model_description(str(three)).modelVariables if v.causality == "input"
             for n in scalar_names(v)}
    mask = np.zeros_like(point)  # an FMU holds its input variables only (a port's other fields stay 0)
    for j, p in enumerate(body_data.ports):
        for f, cols in input_rule.COLUMNS.items():
            names_f = [n for n in given if n.startswith(f"{p.name}.{f}[")]
            mask[j, cols] = 1.0 if names_f else 0.0
    for k in range(len(b.t) - 1):
        # the communication points and steps the host gave: t_k = k h and H_k = t_(k+1) - t_k, which differs
        # from h in the last bits (fmpy steps so, and the FMU takes one internal step of H_k)
        t_c, H_k = b.t[k], b.t[k + 1] - b.t[k]
        point[...] = input_rule.point_values(body_data.ports, inputs(t_c)) * mask
        done, status, _ = body.advance(EXTRAPOLATED, 1, H_k, t_c, row, None)
        assert (done, status) == (1, 0)
        for j, n in enumerate(names):
            if n in outputs:
                assert row[j] == b.columns[n][k + 1], (k, n, row[j], b.columns[n][k + 1])
                compared += 1
    assert compared > 10 * len(b.t)


# ------------------------------------------------------------------ faults, as tests/test_fmu_faults.py for 2.0


@pytest.mark.parametrize("floats, ints, stop, cause", [
    ({"solver.rho_inf": 2.0}, {}, None, "solver.rho_inf must be in [0, 1], got 2.0"),
    ({"solver.step": 0.0}, {}, None, "solver.step must be positive and finite, got 0.0"),
    ({}, {"solver.terms": 7}, None, "solver.terms must be 0 (linear), 1 (gyroscopic) or 2 (full), got 7"),
    ({"solver.step": 1e9}, {}, 0.2, "solver.step = 1e+09 s is longer than the experiment"),
    ({"initial.v": [0.5, 0.0, 0.0]}, {}, None, "initial.v = [0.5, 0.0, 0.0] is set, but the translation of port hub is motion-driven"),
    ({"initial.w": [0.0, 0.0, 1.0]}, {}, None, "initial.w = [0.0, 0.0, 1.0] is set, but the rotation of port hub is motion-driven"),
    ({"initial.tip.d": [0.0, math.nan, 0.0]}, {}, None, "initial.tip.d is not finite"),
])
def test_invalid_parameters_make_exit_initialization_an_error(small, floats, ints, stop, cause, tmp_path):
    s = Slave3(small[0], tmp_path)
    try:
        assert s.start(floats, ints, stop) == ERROR
        assert any(st == ERROR and cause in msg and "fmi3Error" in msg for st, _, msg in s.log), s.log
        for _ in range(2):  # every doStep is then an error naming the cause
            s.log.clear()
            assert s.status(s.fmu.doStep, 0.0, 0.01) == ERROR
            assert any(st == ERROR and cause in msg for st, _, msg in s.log), s.log
    finally:
        s.close()


def test_bad_calls_are_errors_twice_naming_the_cause(small, tmp_path):
    s = Slave3(small[0], tmp_path)
    n = len(s.md.modelVariables) - 1  # the highest value reference
    cases = [
        (lambda: s.fmu.getFloat64([n + 5], nValues=1), f"fmi3GetFloat64: unknown value reference(s) [{n + 5}] (this FMU has 0..{n})"),
        (lambda: s.fmu.getFloat64([s.vr("solver.terms")], nValues=1), "(solver.terms: Int32) are not Float64"),
        (lambda: s.fmu.getInt32([s.vr("tip.r")], nValues=3), "(tip.r: Float64) are not Int32"),
        (lambda: s.fmu.getFloat64([s.vr("tip.r")], nValues=2), "nValues = 2, but the 1 value reference(s) hold 3 value(s)"),
        (lambda: s.fmu.setFloat64([0], [1.0]), "(time: the independent variable) are not Float64 variables this call takes"),
        (lambda: s.fmu.setFloat64([s.vr("tip.r")], [0.0, 0.0, 0.0]), "fmi3SetFloat64: tip.r[1] is an output: it cannot be set"),
        (lambda: s.fmu.getBoolean([s.vr("tip.r")]), "are not Boolean (this FMU has Float64 and Int32 variables only)"),
    ]
    try:
        assert s.start() == OK
        for call, cause in cases:
            for _ in range(2):
                s.log.clear()
                assert s.status(call) == ERROR, cause
                assert any(st == ERROR and cause in msg for st, _, msg in s.log), (cause, s.log)
        s.fmu.doStep(0.0, 0.01)  # the instance survives
    finally:
        s.close()


def test_calls_in_the_wrong_state_wrong_token_and_no_event_mode(small, tmp_path):
    three = small[0]
    s = Slave3(three, tmp_path / "a")
    try:
        assert s.status(s.fmu.doStep, 0.0, 0.01) == ERROR
        assert "fmi3DoStep is not allowed when the FMU is instantiated (before fmi3EnterInitializationMode)" in s.log[-1][2]
        assert s.status(s.fmu.getFloat64, [s.vr("tip.r")], nValues=3) == ERROR
        assert s.start() == OK
        assert s.status(s.fmu.enterInitializationMode) == ERROR
        assert s.step_derivative([s.vr("tip.r")], [s.vr("tip.f")], [0, 0, 1.0], 3)[0] == ERROR
        assert "no communication step to differentiate" in s.log[-1][2] and "fmi3SetFMUState" in s.log[-1][2]
        assert s.status(s.fmu.enterEventMode) == ERROR and "hasEventMode=false" in s.log[-1][2]
        s.fmu.doStep(0.0, 0.01)
        s.fmu.terminate()
        for _ in range(2):
            assert s.status(s.fmu.doStep, 0.01, 0.01) == ERROR
            assert "fmi3DoStep after fmi3Terminate" in s.log[-1][2] and s.log[-1][1] == "logStatusError"
    finally:
        s.close()
    md = read_model_description(str(three))
    d = extract(str(three), str(tmp_path / "b"))
    log = []
    for token, event_mode, cause in [("{00000000-0000-4000-8000-000000000000}", False, "wrong instantiation token"),
                                     (md.guid, True, "eventModeUsed must be false")]:
        f = FMU3Slave(guid=token, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier)
        with pytest.raises(Exception):
            f.instantiate(eventModeUsed=event_mode, logMessage=lambda e, st, cat, msg: log.append(msg.decode()))
        assert cause in log[-1], log
        f.freeLibrary()


def test_a_discard_names_its_cause_and_stepping_on_is_an_error(small, tmp_path):
    s = Slave3(small[0], tmp_path)
    try:
        assert s.start() == OK
        s.fmu.doStep(0.0, 0.01)
        s.fmu.setFloat64([s.vr("tip.f")], [0.0, math.nan, 0.0])
        assert s.status(s.fmu.doStep, 0.01, 0.01) == DISCARD
        stepping_on_is_an_error(s, 0.02, 0.01, "tip.f[2] not finite", 0.01)
        s.fmu.setFloat64([s.vr("tip.f")], [0.0, 0.0, 0.0])
        s.fmu.doStep(0.01, 0.01)  # the recovery the discard allows still works
        s.fmu.setFloat64([s.vr("hub.R")], [1.0, 0, 0, 0, 1.0, 0, 0, 0, -1.0])  # diag(1, 1, -1)
        assert s.status(s.fmu.doStep, 0.02, 0.01) == DISCARD
        assert any(st == DISCARD and "hub.R is not a rotation matrix (a reflection" in msg for st, _, msg in s.log)
    finally:
        s.close()


# ------------------------------------------------------------------ state, reset, derivatives


def test_state_round_trips_reset_and_a_damaged_state(small, tmp_path):
    s = Slave3(small[0], tmp_path)
    out = ["tip.r", "tip.v", "hub.f", "hub.t", "energy.strain"]
    try:
        assert s.start({"tip.f": [0.0, 0.0, 2.0]}) == OK
        for k in range(5):
            s.fmu.doStep(k * 0.01, 0.01)
        state = s.fmu.getFMUState()
        raw = s.fmu.serializeFMUState(state)
        for k in range(5, 10):
            s.fmu.doStep(k * 0.01, 0.01)
        first = s.get(out)
        s.fmu.setFMUState(state)
        for k in range(5, 10):
            s.fmu.doStep(k * 0.01, 0.01)
        assert np.array_equal(s.get(out), first)
        restored = s.fmu.deserializeFMUState(raw)
        s.fmu.setFMUState(restored)
        for k in range(5, 10):
            s.fmu.doStep(k * 0.01, 0.01)
        assert np.array_equal(s.get(out), first) and abs(first[2]) > 1e-5
        damaged = bytearray(raw)
        damaged[len(damaged) // 2] ^= 1
        assert s.status(s.fmu.deserializeFMUState, bytes(damaged)) == ERROR
        assert "cannot be restored" in s.log[-1][2] or "checksum" in s.log[-1][2], s.log[-1]
        s.fmu.freeFMUState(state)
        s.fmu.freeFMUState(restored)
        s.fmu.reset()  # and the same run again from the start
        assert s.start({"tip.f": [0.0, 0.0, 2.0]}) == OK
        for k in range(10):
            s.fmu.doStep(k * 0.01, 0.01)
        assert np.array_equal(s.get(out), first)
    finally:
        s.close()


def test_directional_derivatives_equal_fmi2s_and_the_adjoint_is_their_transpose(small, tmp_path):
    """FMI's meaning: fmi3GetDirectionalDerivative and fmi3GetAdjointDerivative give the partial derivatives at the
    communication point, zero (no direct feedthrough). The step's: ffrf3GetStepDirectionalDerivative of tip.r with
    respect to tip.f equals FMI 2.0's ffrf2GetStepDerivative (the same model function over the scalars, bit for
    bit); ffrf3GetStepAdjointDerivative with seed v is v^T J, J built column by column from unit seeds of the step's
    directional derivative (bit for bit: the adjoint computes those columns)."""
    import ctypes as C

    from fmpy.fmi2 import FMU2Slave

    three, two, _ = small
    s = Slave3(three, tmp_path / "3")
    md2 = read_model_description(str(two))
    vr2 = {v.name: v.valueReference for v in md2.modelVariables}
    f2 = FMU2Slave(guid=md2.guid, unzipDirectory=extract(str(two), str(tmp_path / "2")),
                   modelIdentifier=md2.coSimulation.modelIdentifier)
    try:
        f2.instantiate()
        f2.setupExperiment(startTime=0.0)
        f2.enterInitializationMode()
        f2.setReal([vr2["tip.f[3]"]], [2.0])
        f2.exitInitializationMode()
        assert s.start({"tip.f": [0.0, 0.0, 2.0]}) == OK
        for k in range(3):
            f2.doStep(k * 0.01, 0.01)
            s.fmu.doStep(k * 0.01, 0.01)
        seed = [0.3, -0.2, 1.0]
        fmi = np.array(s.fmu.getDirectionalDerivative([s.vr("tip.r")], [s.vr("tip.f")], seed, nSensitivity=3))
        fmi_adj = np.array(s.fmu.getAdjointDerivative([s.vr("tip.r")], [s.vr("tip.f")], seed, nSensitivity=3))
        assert np.array_equal(fmi, np.zeros(3)) and np.array_equal(fmi_adj, np.zeros(3))
        status, d3 = s.step_derivative([s.vr("tip.r")], [s.vr("tip.f")], seed, 3)
        step2 = f2.dll.ffrf2GetStepDerivative
        step2.argtypes = [C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_uint), C.c_size_t,
                          C.POINTER(C.c_double), C.POINTER(C.c_double)]
        d2 = (C.c_double * 3)()
        assert step2(f2.component, (C.c_uint * 3)(*[vr2[f"tip.r[{i}]"] for i in (1, 2, 3)]), 3,
                     (C.c_uint * 3)(*[vr2[f"tip.f[{i}]"] for i in (1, 2, 3)]), 3, (C.c_double * 3)(*seed), d2) == OK
        assert status == OK and np.array_equal(d3, d2[:]) and np.abs(d3).max() > 1e-8
        J = np.column_stack([s.step_derivative([s.vr("tip.r"), s.vr("tip.v")], [s.vr("tip.f")], list(np.eye(3)[j]), 6)[1]
                             for j in range(3)])
        v = np.array([1.0, -2.0, 0.5, 0.25, 0.0, -1.0])
        status, adj = s.step_derivative([s.vr("tip.r"), s.vr("tip.v")], [s.vr("tip.f")], list(v), 3, adjoint=True)
        expected = [sum(v[i] * J[i, j] for i in range(6)) for j in range(3)]
        assert status == OK and np.array_equal(adj, expected), (adj, expected)
        assert s.step_derivative([s.vr("tip.r")], [s.vr("tip.f")], [1.0, 2.0], 3, adjoint=True)[0] == ERROR
        assert "nSeed = 2" in s.log[-1][2]
    finally:
        s.close()
        f2.terminate()
        f2.freeInstance()


# ------------------------------------------------------------------ hosts


def _host_binary(tmp: Path, target: str | None = None) -> Path:
    """tests/fmi3_host.c compiled by zig (for `target`, default this machine)."""
    out = tmp / ("fmi3_host.exe" if target and "windows" in target else "fmi3_host")
    cmd = [sys.executable, "-m", "ziglang", "cc", *(["-target", target] if target else []), "-std=c11", "-O1",
           "-Wall", "-Wextra", "-Werror", f"-I{NATIVE}", "-o", str(out), str(ROOT / "tests" / "fmi3_host.c")]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return out


def _host_args(md, steps, H):
    vr = {v.name: v for v in md.modelVariables}
    outs = ["tip.r", "tip.v", "hub.f", "energy.strain"]
    return ([str(steps), str(H), str(vr["tip.f"].valueReference), "3", "0.0", "0.0", "1.0", "--",
             *[f"{vr[n].valueReference}:{len(scalar_names(vr[n]))}" for n in outs]], outs)


def _fmpy_reference(path, tmp, steps, H, outs):
    s = Slave3(path, tmp)
    try:
        assert s.start({"tip.f": [0.0, 0.0, 1.0]}) == OK
        for k in range(steps):
            s.fmu.doStep(k * H, H)
        return s.get(outs)
    finally:
        s.close()


def test_b1_in_a_c_host_without_python_equals_fmpy(runs, tmp_path):
    """tests/fmi3_host.c (the FMI 3.0 headers' function types, dlopen) started with an empty environment:
    B1 under a tip load, 100 steps of H = h; then a state round trip and a reset in the same process."""
    three = runs["B1"][0]
    md = read_model_description(str(three))
    unzip = Path(extract(str(three), str(tmp_path / "u")))
    host = _host_binary(tmp_path)
    H = runs["B1"][3].step
    args, outs = _host_args(md, 100, H)
    so = unzip / "binaries" / "x86_64-linux" / f"{md.coSimulation.modelIdentifier}.so"
    done = subprocess.run(["env", "-i", "PATH=/usr/bin:/bin", str(host), str(so), str(unzip / "resources") + "/",
                           md.guid, *args], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    got = np.array([float(x) for x in lines[0].split()])
    assert lines[1:] == ["replay 1", "reset 0", "faults 12"], lines
    ref = _fmpy_reference(three, tmp_path / "f", 100, H, outs)
    assert abs(got[2]) > 1e-4 and np.array_equal(got, ref), (got, ref)


SANITIZE = ["-std=c11", "-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined",
            "-fno-omit-frame-pointer", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror"]


@pytest.fixture(scope="module")
def sanitized(tmp_path_factory):
    """The FMI 3.0 layer, the model and the C runtime compiled once under ASan and UBSan (objects), and a function
    linking a test main with them."""
    from ffrf_fmu.fmu.native import build as native_build

    d = tmp_path_factory.mktemp("asan3")
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    done = subprocess.run([cc, *SANITIZE, "-c", f"-I{native_build.RUNTIME}", f"-I{NATIVE}",
                           *map(str, native_build.sources(3))], capture_output=True, text=True, timeout=900, cwd=d)
    assert done.returncode == 0, done.stderr[-3000:]
    objects = sorted(map(str, d.glob("*.o")))

    def link(main: str, out: Path, *extra) -> Path:
        done = subprocess.run([cc, *SANITIZE, *extra, f"-I{NATIVE}", *objects, str(ROOT / "tests" / main), "-lm",
                               "-ldl", "-o", str(out)], capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr[-3000:]
        return out

    return link


def test_the_c_host_under_the_sanitizers(small, sanitized, tmp_path):
    """tests/fmi3_host.c linked with the FMI 3.0 layer, the model and the C runtime, all under AddressSanitizer and
    UndefinedBehaviorSanitizer (as tests/test_native_fuzz.py builds the FMI 2.0 FMU): the good path, state bytes,
    reset and the bad calls twice, with no report and no leak."""
    three = small[0]
    md = read_model_description(str(three))
    unzip = Path(extract(str(three), str(tmp_path / "u")))
    exe = sanitized("fmi3_host.c", tmp_path / "fmi3_host_asan", "-rdynamic")
    args, _ = _host_args(md, 10, 0.01)
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"}
    done = subprocess.run([str(exe), "-", str(unzip / "resources") + "/", md.guid, *args], capture_output=True,
                          text=True, timeout=900, env=env)
    assert done.returncode == 0, done.stderr[-4000:]
    assert "runtime error" not in done.stderr and "Sanitizer" not in done.stderr, done.stderr[-4000:]
    assert done.stdout.splitlines()[1:] == ["replay 1", "reset 0", "faults 12"], done.stdout


def test_random_fmi3_call_sequences_under_the_sanitizers(small, sanitized, tmp_path):
    """tests/fmi3_fuzz.c (the FMI 3.0 twin of tests/fmi2_fuzz.c) with the FMI 3.0 layer, the model and the runtime
    under ASan and UBSan: no report, no leak, no crash, no status outside fmi3OK..fmi3Error; and the sequences
    reach stepping, state restores, derivatives and adjoints (the counts say so, or the fuzzing proved nothing)."""
    three = small[0]
    md = read_model_description(str(three))
    unzip = Path(extract(str(three), str(tmp_path / "u")))
    exe = sanitized("fmi3_fuzz.c", tmp_path / "fmi3_fuzz")

    def arrays(causality):
        return ",".join(f"{v.valueReference}:{len(scalar_names(v))}" for v in md.modelVariables
                        if v.causality == causality and v.type == "Float64")

    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0", "UBSAN_OPTIONS": "print_stacktrace=1"}
    totals = {}
    for seed in range(1, 5):
        done = subprocess.run([str(exe), str(unzip / "resources") + "/", md.guid, str(seed), "1500", arrays("input"),
                               arrays("output")], capture_output=True, text=True, timeout=900, env=env)
        assert done.returncode == 0, f"seed {seed}: exit {done.returncode}\n{done.stderr[-4000:]}"
        assert "runtime error" not in done.stderr and "Sanitizer" not in done.stderr, done.stderr[-4000:]
        words = done.stdout.split()
        for key, value in zip(words[::2], words[1::2]):
            totals[key] = totals.get(key, 0) + int(value)
    assert totals["steps_ok"] > 100 and totals["restored_ok"] > 10, totals
    assert totals["derivatives_ok"] > 0 and totals["adjoints_ok"] > 0, totals
    assert totals["discard"] > 0 and totals["error"] > 0, totals


WINE = shutil.which("wine64") or shutil.which("wine")


def test_win64_fmi3_fmu_in_wine_equals_linux(small, tmp_path):
    """The x86_64-windows binary (zig) in tests/fmi3_host.c cross-compiled for Windows, run in wine: the numbers
    of the x86_64-linux binary under fmpy, bit for bit (the FMI 2.0 FMU's win64 test: same C, same bits).
    Without wine it fails, as that test does (README: no test skips for a tool .ci/run installs)."""
    assert WINE, "wine64 is not installed (apt-get install wine64; .ci/run installs it)"
    _, _, model = small
    fmu = build_fmu(model, tmp_path / "w.fmu", scene="still", platforms=("linux64", "win64"), fmi=3)
    md = read_model_description(str(fmu))
    unzip = Path(extract(str(fmu), str(tmp_path / "u")))
    host = _host_binary(tmp_path, "x86_64-windows-gnu")
    args, outs = _host_args(md, 20, 0.01)
    dll = unzip / "binaries" / "x86_64-windows" / f"{md.coSimulation.modelIdentifier}.dll"
    env = {**os.environ, "WINEDEBUG": "-all"}
    done = subprocess.run([WINE, str(host), str(dll), str(unzip / "resources") + "/", md.guid, *args],
                          capture_output=True, text=True, timeout=900, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.replace("\r", "").splitlines()
    got = np.array([float(x) for x in lines[0].split()])
    assert lines[1:] == ["replay 1", "reset 0", "faults 12"], lines
    assert np.array_equal(got, _fmpy_reference(fmu, tmp_path / "f", 20, 0.01, outs))


@pytest.mark.parametrize("given", ["fmu", "model"])
def test_validate_takes_an_fmi3_fmu(small, tmp_path, given):
    """`ffrf-fmu validate` on the FMI 3.0 FMU (given, or built from the model with --fmi 3) against the standalone
    run of its model: every output group compared and passing."""
    three, _, model = small
    source = [str(three), "--model", str(model)] if given == "fmu" else [str(model), "--fmi", "3"]
    done = subprocess.run([sys.executable, "-m", "ffrf_fmu", "validate", *source, "--scene", "still", "--report",
                           str(tmp_path / "rep")], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    rep = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert rep["passed"] and rep["fmu_reached_stop_time"]
    assert {"tip.r", "tip.v", "hub.f", "hub.t", "energies"} <= set(rep["groups"])
    if given == "model":
        assert read_model_description(str(next((tmp_path / "rep").glob("*.fmu")))).fmiVersion == "3.0"


ECOS_RUN = """
import json, sys
from ffrf_fmu.engines import import_ecospy  # loads the tbb package's libtbb.so.12 first
ecospy = import_ecospy()
with ecospy.EcosSimulationStructure() as ss:
    ss.add_model("body", sys.argv[1])
    with ecospy.EcosSimulation(structure=ss, step_size=float(sys.argv[2])) as sim:
        sim.init()
        sim.step(int(sys.argv[3]))
        out = {"t": sim.get_time(), "solver.step": sim.get_real("body::solver.step"),
               "tip.r": sim.get_real("body::tip.r")}
        sim.terminate()
print(json.dumps(out))
"""


def test_ecos_runs_the_fmi3_fmu_but_reads_no_array(runs, tmp_path):
    """How far ecos (ecospy, in process: its FMI 3.0 loader) reaches with the FMI 3.0 FMU: it loads, instantiates,
    initializes and steps it (100 steps to t = 100 h) and reads a scalar (solver.step) right; an array it reads as
    one real: `tip.r`, whose value is [8, 0, 0] (fmpy and the C host read it), comes back without an error as the
    last value ecos read before (here solver.step's; 0.0 when it is the first read), and `tip.r[1]` is unknown to it. So ecos can neither set nor read a port of the FMI 3.0 FMU: use the FMI
    2.0 FMU with ecos (tests/test_native_host.py)."""
    three, _, _, sc = runs["B1"]
    (tmp_path / "run.py").write_text(ECOS_RUN)
    done = subprocess.run([sys.executable, str(tmp_path / "run.py"), str(three), str(sc.step), "100"],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got["t"] == pytest.approx(100 * sc.step, abs=1e-12) and got["solver.step"] == sc.step
    assert got["tip.r"] == got["solver.step"]  # a stale value: the array's first element is 8.0
