"""One way to run a body FMU under fmpy through a scene: validate, chart, the tests and the
benchmarks call `run_fmu`.

The scene's port inputs (simulate.scene_inputs; a load window as its mean over (t_k, t_k + H], the
communication step its value is held for, so its impulse is exact) are sampled on the communication grid t_k = k H
and given to fmpy.simulate_fmu as an input table with output_interval = H: fmpy sets the values at
t_k before each doStep(t_k, H), so the FMU sees the exact signal values at the communication
points and applies its own rule in between (docs/fmu.md). The scene's solver and initial values
are the FMU's parameter start values. simulate_fmu stops early on fmi2Discard without raising:
`FmuRun.reached` says whether the run got to the scene's duration.
"""
from __future__ import annotations

import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..runtime.steps import communication_grid
from ..runtime.terms import TERM_SETS
from .variables import component_name, parse_port_variable


class FmuRunError(RuntimeError):
    """The FMU cannot run the scene (not an ffrf-fmu body FMU, a missing parameter)."""


@dataclass(frozen=True)
class FmuRun:
    """An FMU run: recorded times (strictly increasing) and columns under the variable names."""

    t: np.ndarray
    columns: dict[str, np.ndarray]
    reached: bool  # the run got to the scene's duration
    wall_time_s: float
    cpu_time_s: float
    log: list[str] = field(repr=False)

    def result(self, body):
        """The run as a simulate.SimulationResult of `body` (for the scene metrics and plots)."""
        from ..simulate import SimulationResult

        return SimulationResult(self.t, dict(self.columns), {}, body)


NATIVE_RESOURCE = "resources/body.bin"


def is_native(fmu_path) -> bool:
    """The FMU is a native one (fmu/native: resources/body.bin), not a pythonfmu one (resources/body.npz)."""
    with zipfile.ZipFile(fmu_path) as z:
        return NATIVE_RESOURCE in z.namelist()


def fmu_body(fmu_path):
    """The reduced BodyData a pythonfmu FMU carries (resources/body.npz); of a native FMU, its ports and
    node positions only (fmu/native/resource.py read_body: the matrices stay in the runtime images)."""
    from ..runtime.data import BodyData

    if is_native(fmu_path):
        from .native.resource import read_body

        with zipfile.ZipFile(fmu_path) as z:
            return read_body(z.read(NATIVE_RESOURCE))
    with zipfile.ZipFile(fmu_path) as z, tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "body.npz"
        p.write_bytes(z.read("resources/body.npz"))
        return BodyData.load(p)


def _variables(fmu_path):
    from fmpy import read_model_description

    return read_model_description(str(fmu_path)).modelVariables


def input_values(values: dict, names: Sequence[str]) -> list[float]:
    """The values of the FMU input variables `names` in {port: PortValues} (one time)."""
    out = []
    for n in names:
        port, fld, idx = parse_port_variable(n)
        out.append(float(np.asarray(getattr(values[port], fld))[idx]))
    return out


def fmu_input_table(fmu_path, inputs: Callable, times) -> np.ndarray:
    """fmpy input table: every FMU input sampled at `times` from inputs(t) -> {port: PortValues}."""
    names = [n for v in _variables(fmu_path) if v.causality == "input" for n in scalar_names(v)]
    table = np.zeros(len(times), dtype=[("time", np.float64)] + [(n, np.float64) for n in names])
    table["time"] = times
    # each name's (port, field) and flat index into that field (R[i,j] row-major): one gather per time
    where = []
    for n in names:
        port, fld, idx = parse_port_variable(n)
        where.append((port, fld, idx[0] * 3 + idx[1] if len(idx) == 2 else idx[0]))
    keys = list(dict.fromkeys((port, fld) for port, fld, _ in where))
    rows = np.empty((len(times), len(names)))
    flat = None
    for k, t in enumerate(times):
        values = inputs(float(t))
        parts = [np.ravel(getattr(values[port], fld)) for port, fld in keys]
        if flat is None:
            offset = dict(zip(keys, np.cumsum([0] + [part.size for part in parts])))
            flat = np.array([offset[(port, fld)] + i for port, fld, i in where], dtype=int)
        rows[k] = np.concatenate(parts)[flat]
    for j, n in enumerate(names):
        table[n] = rows[:, j]
    return table


def scene_start_values(scene, fmu_path) -> dict:
    """The scene's solver and initial values as FMU parameter start values."""
    names = {n for v in _variables(fmu_path) for n in scalar_names(v)}
    sv = {"solver.step": scene.step, "solver.rho_inf": scene.rho_inf, "solver.terms": TERM_SETS.index(scene.terms),
          "solver.max_newton_iterations": scene.max_newton_iterations}
    for i in range(3):
        sv[component_name("gravity", (i,))] = scene.gravity[i]
        sv[component_name("initial.v", (i,))] = scene.initial.velocity[i]
        sv[component_name("initial.w", (i,))] = scene.initial.angular_velocity[i]
    for port, d in scene.initial.port_displacements:
        for i in range(3):
            sv[component_name(f"initial.{port}.d", (i,))] = d[i]
    missing = [k for k in sv if k not in names]
    if missing:
        raise FmuRunError(f"{fmu_path}: the FMU has no parameter(s) {missing}: not an ffrf-fmu body FMU?")
    return sv


def fmi_version(fmu_path) -> str:
    """"2.0" or "3.0": the fmiVersion of the FMU's modelDescription.xml."""
    from fmpy import read_model_description

    return read_model_description(str(fmu_path)).fmiVersion


def scalar_names(variable) -> list[str]:
    """The FMI 2.0 scalar names of an FMI 3.0 variable (fmpy's ModelVariable): `tip.R` [3, 3] ->
    `tip.R[1,1]`, `tip.R[1,2]`, ... row-major (fmu/native `fmi3_variables`); a scalar keeps its name."""
    shape = [int(d.start) for d in variable.dimensions]
    if not shape:
        return [variable.name]
    return [component_name(variable.name, idx) for idx in np.ndindex(*shape)]


def _run_fmu3(fmu_path, scene, table: np.ndarray, start_values: dict, record: Sequence[str], H: float, log: list):
    """The FMI 3.0 FMU through the input table, as fmpy.simulate_fmu runs an FMI 2.0 co-simulation FMU
    (fmpy's simulate_fmu records an FMI 3.0 array as one column of shape (3,); this loop keeps the scalar
    columns and names of FMI 2.0): parameters and the inputs at t_0 set in initialization mode, then per communication point
    t_k the inputs at t_k, doStep(t_k, H), the outputs at t_k + H. Stops at the first doStep that is not
    OK (a discard: the run's last sample is the last successful point). Returns (times, {scalar name: values})."""
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(fmu_path))
    tmp = tempfile.TemporaryDirectory(prefix="ffrf_fmu3_")
    unzip = extract(str(fmu_path), tmp.name)
    by_name = {v.name: v for v in md.modelVariables}
    scalars = {v.name: scalar_names(v) for v in md.modelVariables}

    def groups(names, type_="Float64"):
        """(value references, scalar names in order) of the FMI 3.0 variables of `type_` holding `names`
        (whole arrays)."""
        wanted, refs, order = set(names), [], []
        for v in md.modelVariables:
            if v.causality != "independent" and v.type == type_ and wanted.intersection(scalars[v.name]):
                refs.append(v.valueReference)
                order.extend(scalars[v.name])
        return refs, order

    def log_message(env, status, category, message):
        dec = lambda b: b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b)
        log.append(f"[{dec(category)}] {dec(message)}")

    fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="ffrf")
    fmu.instantiate(loggingOn=True, logMessage=log_message)
    if not fmu.component:
        tmp.cleanup()
        raise FmuRunError(f"{fmu_path}: fmi3InstantiateCoSimulation failed: {' '.join(log[-3:])}")
    inputs = [n for n in table.dtype.names[1:]]
    in_refs, in_order = groups(inputs)
    out_refs, out_order = groups(record)
    int_refs, int_order = groups(record, "Int32")

    def sample():
        return [*fmu.getFloat64(out_refs, nValues=len(out_order)), *(fmu.getInt32(int_refs) if int_refs else [])]

    float_params = {k: v for k, v in start_values.items() if by_name.get(k.partition("[")[0]) is None or
                    by_name[k.partition("[")[0]].type == "Float64"}
    try:
        fmu.enterInitializationMode(startTime=0.0, stopTime=float(table["time"][-1]))
        for name, value in start_values.items():
            base = name.partition("[")[0]
            v = by_name[base]
            if v.type == "Int32":
                fmu.setInt32([v.valueReference], [int(value)])
        p_refs, p_order = groups([k for k in float_params])
        if p_refs:  # a parameter array is set whole: its other elements keep their start values
            current = dict(zip(p_order, fmu.getFloat64(p_refs, nValues=len(p_order))))
            current.update(float_params)
            fmu.setFloat64(p_refs, [float(current[n]) for n in p_order])
        row = {n: float(table[n][0]) for n in inputs}
        if in_refs:
            fmu.setFloat64(in_refs, [row[n] for n in in_order])
        fmu.exitInitializationMode()
        times = [0.0]
        values = [sample()]
        for k in range(len(table) - 1):
            t_c, t_next = float(table["time"][k]), float(table["time"][k + 1])
            if in_refs:
                fmu.setFloat64(in_refs, [float(table[n][k]) for n in in_order])
            try:
                fmu.doStep(t_c, t_next - t_c)
            except Exception:  # fmpy raises on a discard or an error: the message is in the log
                break
            times.append(t_next)
            values.append(sample())
        fmu.terminate()
    finally:
        fmu.freeInstance()
        fmu.freeLibrary()
        tmp.cleanup()
    data = np.array(values, dtype=float)
    return np.array(times), {n: data[:, j] for j, n in enumerate(out_order + int_order) if n in set(record)}


def run_fmu(fmu_path, scene, inputs: Callable | None = None, comm_step: float | None = None,
            record: Sequence[str] | None = None, start_values: dict | None = None) -> FmuRun:
    """Run the FMU through `scene` under fmpy.simulate_fmu.

    inputs: t -> {port: PortValues} (default: the scene's drives and loads on the FMU's own body);
    comm_step: communication step H (default: the scene's internal step); record: the variables to
    record (default: every input and output); start_values: parameters set besides the scene's (e.g.
    {"damping.ratio": 0.05}), in initialization mode. fmpy records after doStep(t_c, H), when the inputs
    still hold the values set for t_c, and repeats the last sample after a discard: the run keeps
    strictly increasing times and takes the input columns from the signal at the recorded times. An FMI
    3.0 FMU runs through the same table in `_run_fmu3`; its columns are the scalar names of FMI 2.0."""
    import fmpy

    H = float(comm_step) if comm_step else scene.step
    if inputs is None:  # a load window's mean over the communication step its value is held for
        from ..simulate import scene_inputs

        inputs = scene_inputs(fmu_body(fmu_path), scene, load_interval=(0.0, H))
    fmi3 = fmi_version(fmu_path).startswith("3")
    if record is None:
        record = [n for v in _variables(fmu_path) if v.causality in ("input", "output")
                  for n in (scalar_names(v) if fmi3 else [v.name])]
    times = np.array(communication_grid(scene.duration, H))  # the last point is the scene's end, never past it
    table = fmu_input_table(fmu_path, inputs, times)
    start_values = {**scene_start_values(scene, fmu_path), **(start_values or {})}
    log: list[str] = []

    def logger(component, instance, status, category, message):
        dec = lambda b: b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b)
        log.append(f"[{dec(category)}] {dec(message)}")

    t0, c0 = time.perf_counter(), time.process_time()

    def finish(t, columns, recorded_inputs) -> FmuRun:
        """The run of times t and columns, its recorded inputs taken from the signal at t."""
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if recorded_inputs:
            exact = fmu_input_table(fmu_path, inputs, t)
            columns.update({n: np.asarray(exact[n], dtype=float) for n in recorded_inputs})
        reached = bool(abs(t[-1] - scene.duration) <= 1e-9 * max(1.0, scene.duration))
        return FmuRun(t, columns, reached, wall, cpu, log)

    if fmi3:
        t, columns = _run_fmu3(fmu_path, scene, table, start_values, [n for n in record if n not in table.dtype.names],
                               H, log)
        return finish(t, columns, [n for n in table.dtype.names[1:] if n in record])
    res = fmpy.simulate_fmu(str(fmu_path), start_time=0.0, stop_time=scene.duration, output_interval=H,
                            input=table, output=list(record), start_values=start_values, debug_logging=True,
                            logger=logger)
    t = np.asarray(res["time"], dtype=float)
    keep = np.concatenate([np.diff(t) > 0, [True]])
    t = t[keep]
    columns = {n: np.asarray(res[n], dtype=float)[keep] for n in res.dtype.names if n != "time"}
    return finish(t, columns, [n for n in table.dtype.names[1:] if n in columns])
