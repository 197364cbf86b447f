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
    names = [v.name for v in _variables(fmu_path) if v.causality == "input"]
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
    names = {v.name for v in _variables(fmu_path)}
    sv = {"solver.step": scene.step, "solver.rho_inf": scene.rho_inf, "solver.terms": TERM_SETS.index(scene.terms)}
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


def run_fmu(fmu_path, scene, inputs: Callable | None = None, comm_step: float | None = None,
            record: Sequence[str] | None = None) -> FmuRun:
    """Run the FMU through `scene` under fmpy.simulate_fmu.

    inputs: t -> {port: PortValues} (default: the scene's drives and loads on the FMU's own body);
    comm_step: communication step H (default: the scene's internal step); record: the variables to
    record (default: every input and output). fmpy records after doStep(t_c, H), when the inputs
    still hold the values set for t_c, and repeats the last sample after a discard: the run keeps
    strictly increasing times and takes the input columns from the signal at the recorded times."""
    import fmpy

    H = float(comm_step) if comm_step else scene.step
    if inputs is None:  # a load window's mean over the communication step its value is held for
        from ..simulate import scene_inputs

        inputs = scene_inputs(fmu_body(fmu_path), scene, load_interval=(0.0, H))
    if record is None:
        record = [v.name for v in _variables(fmu_path) if v.causality in ("input", "output")]
    n = int(round(scene.duration / H))
    times = np.arange(n + 1) * H
    if times[-1] < scene.duration * (1 - 1e-12):
        times = np.append(times, scene.duration)
    table = fmu_input_table(fmu_path, inputs, times)
    start_values = scene_start_values(scene, fmu_path)
    log: list[str] = []

    def logger(component, instance, status, category, message):
        dec = lambda b: b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b)
        log.append(f"[{dec(category)}] {dec(message)}")

    t0, c0 = time.perf_counter(), time.process_time()
    res = fmpy.simulate_fmu(str(fmu_path), start_time=0.0, stop_time=scene.duration, output_interval=H,
                            input=table, output=list(record), start_values=start_values, debug_logging=True,
                            logger=logger)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    t = np.asarray(res["time"], dtype=float)
    keep = np.concatenate([np.diff(t) > 0, [True]])
    t = t[keep]
    columns = {n: np.asarray(res[n], dtype=float)[keep] for n in res.dtype.names if n != "time"}
    recorded_inputs = [n for n in table.dtype.names[1:] if n in columns]
    if recorded_inputs:
        exact = fmu_input_table(fmu_path, inputs, t)
        columns.update({n: np.asarray(exact[n], dtype=float) for n in recorded_inputs})
    reached = bool(abs(t[-1] - scene.duration) <= 1e-9 * max(1.0, scene.duration))
    return FmuRun(t, columns, reached, wall, cpu, log)
