"""Standalone runs: a scene's drives and loads as port inputs, the body stepped to the end,
time series under the FMU's variable names, the benchmark metrics and a summary.

Over 400 lines: the run, its result type and what is computed from a result (metrics, plot,
the reference run as a result) belong to one idea, the standalone run."""
from __future__ import annotations

import dataclasses
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .model import Model, Scene, load_model, scene_body
from .runtime import drives
from .runtime.data import BodyData
from .runtime.held import port_codes
from .runtime.ports import PortValues, StepFailure
from .runtime.rotation import expm, logm
from .runtime.body import BodySystem
from .fmu.variables import ENERGIES as VARIABLE_ENERGIES, field_shape, port_variables

ENERGIES = tuple(VARIABLE_ENERGIES)
assert ENERGIES == BodySystem.ENERGY_FIELDS  # the energies of BodySystem.output_row, in the variables' order


def variable_names(port: str) -> list[str]:
    """FMU variable names of one port's outputs (ports.md), in the columns order of
    BodySystem.port_array."""
    return [name for fld in BodySystem.OUTPUT_FIELDS for name in port_variables(port, fld)]


def _tf(fn, t):
    return drives.evaluate(fn.kind, dict(fn.params), t)


def scene_inputs(body: BodyData, scene: Scene) -> Callable[[float], dict[str, PortValues]]:
    """Port inputs of a scene as a function of time: drives on motion parts, loads on force parts."""
    drive_of = {d.port: d for d in scene.drives}
    loads = scene.loads

    def inputs(t: float) -> dict[str, PortValues]:
        out = {}
        for p in body.ports:
            pv = PortValues()
            d = drive_of.get(p.name)
            if p.translation in ("motion", "compliant"):  # compliant: the far end of the spring
                r0 = body.node_positions[p.node]
                if d is not None and d.translation is not None:
                    u, du, ddu = _tf(d.translation.displacement, t)
                    e = np.asarray(d.translation.direction, float)
                    pv.r, pv.v, pv.a = r0 + u * e, du * e, ddu * e
                else:
                    pv.r, pv.v, pv.a = r0.copy(), np.zeros(3), np.zeros(3)
            if p.rotation in ("motion", "compliant"):
                if d is not None and d.rotation is not None:
                    phi, dphi, ddphi = _tf(d.rotation.angle, t)
                    axis = np.asarray(d.rotation.axis, float)
                    pv.R, pv.w, pv.dw = expm(phi * axis), dphi * axis, ddphi * axis
                else:
                    pv.R, pv.w, pv.dw = np.eye(3), np.zeros(3), np.zeros(3)
            f, m = np.zeros(3), np.zeros(3)
            for ld in loads:
                if ld.port == p.name and ld.t_start <= t < ld.t_end:
                    f += ld.force
                    m += ld.moment
            if p.translation == "force":
                pv.f = f
            if p.rotation == "force":
                pv.t = m
            out[p.name] = pv
        return out

    return inputs


def scene_schedule(body: BodyData, scene: Scene) -> tuple:
    """The inputs of `scene_inputs` as arrays, for the compiled run (runtime/kernel.py `advance`, which
    evaluates them at every step as scene_inputs does): per port its node, part causalities (0 force,
    1 motion, 2 compliant), spring index among the compliant ports (-1: none), reference position,
    drive time functions (code, parameters; -1: no drive) and direction / axis; per load its port,
    time window, force and moment."""
    drive_of = {d.port: d for d in scene.drives}
    P = len(body.ports)
    node, mode, spring = port_codes(body.ports)
    kind = np.full((P, 2), -1, dtype=np.int64)
    r0, prm, axis = np.zeros((P, 3)), np.zeros((P, 2, 3)), np.zeros((P, 2, 3))
    for j, p in enumerate(body.ports):
        r0[j] = body.node_positions[p.node]
        d = drive_of.get(p.name)
        for part, drive in ((0, d and d.translation), (1, d and d.rotation)):
            if drive:
                fn = drive.displacement if part == 0 else drive.angle
                kind[j, part], prm[j, part] = drives.encode(fn.kind, dict(fn.params))
                axis[j, part] = drive.direction if part == 0 else drive.axis
    port_index = {p.name: j for j, p in enumerate(body.ports)}
    loads = [ld for ld in scene.loads if ld.port in port_index]
    load_port = np.array([port_index[ld.port] for ld in loads], dtype=np.int64)
    load_window = np.array([[ld.t_start, ld.t_end] for ld in loads], dtype=float).reshape(-1, 2)
    load_fm = np.array([[ld.force, ld.moment] for ld in loads], dtype=float).reshape(-1, 2, 3)
    return node, mode, spring, r0, kind, prm, axis, load_port, load_window, load_fm


@dataclass
class SimulationResult:
    t: np.ndarray
    columns: dict[str, np.ndarray]
    summary: dict
    body: BodyData = field(repr=False)

    def port(self, name: str, fld: str) -> np.ndarray:
        """(nt, 3) or (nt, 3, 3) series of one port field."""
        series = np.stack([self.columns[n] for n in port_variables(name, fld)], -1)
        return series.reshape(series.shape[:-1] + field_shape(fld))

    def write_csv(self, path) -> None:
        names = ["time"] + list(self.columns)
        data = np.column_stack([self.t] + [self.columns[k] for k in self.columns])
        # names like hub.R[1,1] hold the delimiter: quoted (RFC 4180), a CSV reader sees one field each
        header = ",".join(f'"{n}"' if "," in n else n for n in names)
        np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")

    def write_summary(self, path) -> None:
        with open(path, "w") as fh:
            json.dump(self.summary, fh, indent=2)
            fh.write("\n")


class Progress:
    """A one-line progress bar on a terminal; silent otherwise (CI logs stay clean)."""

    def __init__(self, total: float, label: str, stream=None):
        self.total, self.label = total, label
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty()
        self.shown = -1
        self.start = time.perf_counter()

    def update(self, done: float) -> None:
        if not self.enabled:
            return
        pct = int(100 * done / self.total) if self.total > 0 else 100
        if pct != self.shown:
            self.shown = pct
            bar = "#" * (pct // 4) + "." * (25 - pct // 4)
            el = time.perf_counter() - self.start
            self.stream.write(f"\r{self.label} [{bar}] {pct:3d}% t={done:.3g}s wall={el:.1f}s")
            self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()


class InitializationFailure(RuntimeError):
    """The scene's initial state cannot be built (e.g. port displacements without a static equilibrium)."""


def build_system(body: BodyData, scene: Scene, origin=(0.0, 0.0, 0.0), backend: str = "numpy") -> tuple[BodySystem, Callable]:
    """A BodySystem for the scene, initialized at t = 0; returns it with its input function.
    backend: "numpy" (reference) or "numba" (compiled step; falls back to numpy with a logged note)."""
    system = BodySystem(body, terms=scene.terms, full_terms=scene.full_terms, rho_inf=scene.rho_inf, gravity=scene.gravity, backend=backend)

    inputs = scene_inputs(body, scene)
    init = scene.initial
    try:
        system.initialize(
            0.0,
            inputs,
            velocity=init.velocity,
            angular_velocity=init.angular_velocity,
            port_displacements=dict(init.port_displacements),
            origin=origin,
        )
    except StepFailure as e:
        raise InitializationFailure(f"scene {scene.name!r} cannot start: {e.cause}") from e
    return system, inputs


def record(system: BodySystem) -> np.ndarray:
    """One row of the time series: every port's outputs (column_names order), energies, Newton iterations."""
    return system.output_row()


def column_names(body: BodyData) -> list[str]:
    names = [n for p in body.ports for n in variable_names(p.name)]
    return names + [f"energy.{k}" for k in ENERGIES] + ["solver.newton_iterations"]


def whole_steps(duration: float, step: float) -> tuple[int, float]:
    """(n, h): n steps of h = duration / n, the largest h <= step that divides the duration (as the
    reference solver does); a duration within 1e-9 relative of a whole number of steps keeps the step."""
    ratio = duration / step
    n = round(ratio)
    if n >= 1 and abs(ratio - n) <= 1e-9 * ratio:
        return int(n), step
    n = max(1, math.ceil(ratio))
    return n, duration / n


def run(body: BodyData, scene: Scene, *, origin=(0.0, 0.0, 0.0), progress: bool = True,
        backend: str = "numpy") -> SimulationResult:
    """Step the body through the scene with the scene's constant step; record every step.

    A duration that is not a whole number of steps is never rounded: the step is reduced to
    divide it (whole_steps), with a warning, and the summary gives both steps."""
    start, cpu_start = time.perf_counter(), time.process_time()
    requested = scene.step
    n_steps, h = whole_steps(scene.duration, scene.step)
    if h != requested:
        warnings.warn(f"scene {scene.name!r}: duration {scene.duration:g} s is not a whole number of steps of "
                      f"{requested:g} s ({scene.duration / requested:.6g}): step reduced to {h:.6g} s "
                      f"({n_steps} steps)", UserWarning, stacklevel=2)
        scene = dataclasses.replace(scene, step=h)
    system, inputs = build_system(body, scene, origin, backend)
    rows = np.empty((n_steps + 1, len(column_names(body))))
    rows[0] = record(system)
    times = np.empty(n_steps + 1)
    times[0] = 0.0
    free = scene.metrics.kind == "momentum"  # these metrics read the mass properties at every step
    masses = [free_body_state(system)] if free else []
    bar = Progress(scene.duration, f"{body.name}/{scene.name}") if progress else None
    iterations = 0
    failure = None
    # on the numba backend, after its first step (checked against numpy), chunks of steps run in one
    # kernel call each with the scene's inputs and the recording inside (momenta, for a free body's
    # metrics, are recorded in Python: such scenes step one by one)
    schedule = None if free else scene_schedule(body, scene)
    k = 0
    while k < n_steps:
        compiled = system._compiled
        if schedule is not None and compiled is not None and compiled.verified:
            m = min(n_steps - k, 500)  # a chunk: progress updates and a prompt return on failure
            done, exc = system.run_schedule(scene.step, schedule, rows[k + 1 : k + 1 + m], times[k + 1 : k + 1 + m])
            iterations += int(rows[k + 1 : k + 1 + done, -1].sum())
            k += done
            if exc is not None:
                failure = str(exc)
                break
            if bar is not None:
                bar.update(system.t)
            continue
        try:
            iterations += system.step(scene.step, inputs)
        except StepFailure as exc:
            failure = str(exc)
            break
        k += 1
        rows[k] = record(system)
        times[k] = system.t
        if free:
            masses.append(free_body_state(system))
        if bar is not None:
            bar.update(system.t)
    if bar is not None:
        bar.close()
    rows, times = rows[: k + 1], times[: k + 1]
    # the one-time compilation (or disk-cache load) of the numba kernel is reported apart, not as run time
    # (wall and CPU alike: counting its CPU but not its wall made short runs report CPU above wall)
    kernel = system._compiled
    compile_s = kernel.compile_seconds if kernel is not None else None
    wall = time.perf_counter() - start - (compile_s or 0.0)
    cpu = time.process_time() - cpu_start - ((kernel.compile_cpu_seconds or 0.0) if kernel is not None else 0.0)
    columns = dict(zip(column_names(body), rows.T))
    if free:
        columns |= free_body_columns(*(np.array(x) for x in zip(*masses)))
    summary = {
        "body": body.name,
        "scene": scene.name,
        "terms": scene.terms,
        "superelements": len(body.superelements),
        "step": scene.step,
        "step_requested": requested,
        "rho_inf": scene.rho_inf,
        "backend": system.backend,
        "backend_note": system.backend_note,
        "compile_time_s": compile_s,
        "kernel_compiled": kernel.compiled if kernel is not None else None,  # False: loaded from the disk cache
        "completed": failure is None,
        "failure": failure,
        "t_end": float(times[-1]),
        "wall_time_s": wall,
        "cpu_time_s": cpu,
        "steps": int(k),
        "real_time_factor": float(times[-1] / wall) if wall > 0 else None,
        "newton_iterations_mean": iterations / max(k, 1),
        "energy_balance_max_rel": energy_balance(columns),
    }
    result = SimulationResult(times, columns, summary, body)
    summary["metrics"] = metrics(result, scene)
    return result


def energy_balance(columns: dict[str, np.ndarray]) -> float:
    """max |E(t) - E(0) - W_ext(t)| over the peak of E = rigid + elastic kinetic + strain energy."""
    if "energy.kinetic" in columns:  # the full-order reference has no rigid/elastic split
        total = columns["energy.kinetic"] + columns["energy.strain"]
    else:
        total = columns["energy.kinetic_rigid"] + columns["energy.kinetic_elastic"] + columns["energy.strain"]
    gap = total - total[0] - columns["energy.work_external"]
    peak = max(np.max(np.abs(total)), np.max(np.abs(columns["energy.work_external"])))
    return float(np.max(np.abs(gap)) / peak) if peak > 0 else 0.0


def run_scene(model: Model | str, scene_name: str | None = None, overrides: Sequence[str] = (), progress=False,
              backend: str = "numpy"):
    """Load (if a path), build and reduce the body for the scene, run it standalone."""
    from .reduction import build_scene_body

    if not isinstance(model, Model):
        model = load_model(model, overrides)
    scene = model.scene(scene_name)
    body, _ = build_scene_body(model.body, scene)
    return run(body, scene, origin=model.body.origin, progress=progress, backend=backend)


# ----------------------------------------------------------------------------------- metrics
def end_ports(body: BodyData) -> tuple[str, str]:
    """The ports at the first and the last boundary node (hub/root and tip of a beam)."""
    by_node = sorted(body.ports, key=lambda p: p.node)
    return by_node[0].name, by_node[-1].name


def elastic_tip(result: SimulationResult, hub: str, tip: str) -> np.ndarray:
    """Eq. (92): d = R_hub^T (x_tip - x_hub) - X_tip, X_tip the tip seen from the hub at rest."""
    body = result.body
    X = body.node_positions[body.port(tip).node] - body.node_positions[body.port(hub).node]
    R = result.port(hub, "R")
    return np.einsum("nji,nj->ni", R, result.port(tip, "r") - result.port(hub, "r")) - X


def dominant_frequency(t: np.ndarray, y: np.ndarray, f_min: float, f_max: float) -> float:
    """Frequency of the best-fitting sinusoid (plus a linear trend) to y(t), searched in [f_min, f_max].

    A least-squares fit resolves a frequency from a couple of periods, where an FFT could not."""
    from scipy.optimize import minimize_scalar

    def misfit(f):
        w = 2 * np.pi * f
        A = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t), t - t[0]])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        return float(np.sum((A @ coef - y) ** 2))

    grid = np.linspace(f_min, f_max, 400)
    i = int(np.argmin([misfit(f) for f in grid]))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    return float(minimize_scalar(misfit, bounds=(lo, hi), method="bounded").x)


# a free body's state beyond its ports (metrics kind "momentum"): CM, inertia about it, momenta; the
# runtime (free_body_state) and the full-order reference (reference.solver.mass_properties) record it
FREE_BODY_FIELDS = {"cm": (3,), "J_cm": (3, 3), "p": (3,), "h_cm": (3,)}


def free_body_state(system: BodySystem) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(CM, inertia tensor about the CM, linear momentum, angular momentum about the CM) of the body,
    world axes, as its equations hold them (BodySystem.mass_properties, momenta)."""
    _, c, J = system.mass_properties()
    p, h = system.momenta()
    return c, J, p, h - np.cross(c, p)


def free_body_keys(name: str) -> list[str]:
    """Column names of one FREE_BODY_FIELDS series: body.cm[1..3], body.J_cm[1,1..3,3], ..."""
    if FREE_BODY_FIELDS[name] == (3,):
        return [f"body.{name}[{i + 1}]" for i in range(3)]
    return [f"body.{name}[{i + 1},{j + 1}]" for i in range(3) for j in range(3)]


def free_body_columns(cm, J_cm, p, h_cm) -> dict[str, np.ndarray]:
    """The columns of the series cm, J_cm, p, h_cm ((nt, 3) or (nt, 3, 3)), named by free_body_keys."""
    out = {}
    for name, series in zip(FREE_BODY_FIELDS, (cm, J_cm, p, h_cm)):
        out |= dict(zip(free_body_keys(name), np.asarray(series).reshape(len(series), -1).T))
    return out


def free_body_series(result: SimulationResult, name: str) -> np.ndarray:
    """One FREE_BODY_FIELDS series of a result, (nt, 3) or (nt, 3, 3); a clear error when the run did
    not record it (standalone runs of scenes with metrics kind 'momentum' and the reference do; an FMU
    has no such outputs)."""
    keys = free_body_keys(name)
    if any(k not in result.columns for k in keys):
        raise KeyError(f"the free-body metrics need body.{name}, which this run did not record (standalone runs "
                       "of scenes with metrics kind 'momentum' and the reference record it; an FMU does not)")
    return np.stack([result.columns[k] for k in keys], -1).reshape((len(result.t),) + FREE_BODY_FIELDS[name])


def tip_from_cm(result: SimulationResult) -> np.ndarray:
    """The elastic deflection of the tip (the port at the last boundary node) seen from the body's CM frame,
    (nt, 3) = (0, along e2, along e3): e1 the body's axis of least inertia about its CM (for a beam, the
    line that fits its mass best; turned towards the tip), e3 the part of the angular momentum direction
    n = h_cm(0)/|h_cm(0)| normal to e1, e2 = e3 x e1 (for a tumbling beam: e2 in the plane the axis sweeps,
    e3 out of it). The frame comes from the whole mass (CM and inertia), not from one section: the bending
    modes' slopes at an end, which the reduced body truncates, do not turn it. The axial part (stretch,
    the axial modes) is left out (0): it is not bending. Same definition for every model; each computes CM,
    inertia and momenta from its own mass (runtime: free_body_state; reference: mass_properties)."""
    _, tip = end_ports(result.body)
    c, J, h = (free_body_series(result, k) for k in ("cm", "J_cm", "h_cm"))
    _, vec = np.linalg.eigh(J)
    e1 = vec[:, :, 0]  # eigh sorts ascending: the axis of least inertia
    r = result.port(tip, "r") - c
    e1 = e1 * np.sign(np.einsum("ni,ni->n", e1, r))[:, None]
    n = h[0] / np.linalg.norm(h[0])
    e3 = n - (e1 @ n)[:, None] * e1
    e3 = e3 / np.linalg.norm(e3, axis=1)[:, None]
    e2 = np.cross(e3, e1)
    return np.column_stack([np.zeros(len(r)), np.einsum("ni,ni->n", r, e2), np.einsum("ni,ni->n", r, e3)])


def metrics(result: SimulationResult, scene: Scene) -> dict:
    """The scene's summary metrics, by its [scenes.NAME.metrics] table (model.Metrics; the windows
    and bands are the benchmark's, from the model file):

    - tip_deflection: the maximum transverse elastic tip deflection (eq. 92, end ports), the axial
      part and the time there; with band_hz, the tip's vibration frequency after the end of the
      rotation drive's spin-up (its T), when the run lasts min_window_s longer;
    - hub_rates: with coast_end_s, the mean Omega_z of the root from the end of its torque load to
      coast_end_s; when the run lasts min_window_s past the end of the tip load: the mean Omega_y
      after it and, with band_hz, the tip's vibration frequency; the root's final rotation vector;
    - momentum (a free body): drifts of the linear and angular momentum (about the CM) and of the total
      energy; the tip's deflection seen from the CM frame (tip_from_cm): its maximum, its RMS over the run
      and, with band_hz, its dominant frequency out of the plane the axis sweeps (e3), when the run lasts
      min_window_s.
    """
    t, m = result.t, scene.metrics
    if m.kind == "tip_deflection":
        hub, tip = end_ports(result.body)
        d = elastic_tip(result, hub, tip)
        axis = result.body.node_positions[-1] - result.body.node_positions[0]
        axis = axis / np.linalg.norm(axis)
        axial = d @ axis
        transverse = np.linalg.norm(d - axial[:, None] * axis, axis=1)
        i = int(np.argmax(transverse))
        out = {"tip_deflection_max_m": float(transverse[i]), "tip_axial_at_max_m": float(axial[i]), "t_at_max_s": float(t[i])}
        T_spin = next((dict(dr.rotation.angle.params).get("T") for dr in scene.drives if dr.rotation), None)
        if m.band_hz and T_spin is not None and t[-1] > T_spin + m.min_window_s:
            after = t > T_spin
            signed = d[after] @ np.cross([0, 0, 1.0], axis) if abs(axis[2]) < 0.9 else d[after, 0]
            out["oscillation_frequency_hz"] = dominant_frequency(t[after], signed, *m.band_hz)
        return out
    if m.kind == "hub_rates":
        root, tip = end_ports(result.body)
        w = result.port(root, "w")
        out = {}
        t_torque_end = max((ld.t_end for ld in scene.loads if ld.port == root), default=None)
        if m.coast_end_s is not None and t_torque_end is not None and t[-1] >= m.coast_end_s > t_torque_end:
            coast = (t >= t_torque_end) & (t <= m.coast_end_s)
            out[f"omega_z_at_{m.coast_end_s:g}s"] = float(np.mean(w[coast, 2]))
        t_load_end = max((ld.t_end for ld in scene.loads if ld.port == tip), default=None)
        if t_load_end is not None and t[-1] > t_load_end + m.min_window_s:
            after = t >= t_load_end
            out["omega_y_mean_after_load"] = float(np.mean(w[after, 1]))
            if m.band_hz:
                d = elastic_tip(result, root, tip)
                out["tip_frequency_hz"] = dominant_frequency(t[after], d[after, 2], *m.band_hz)
        R_end = result.port(root, "R")[-1]
        out["hub_rotation_vector_end"] = [float(x) for x in logm(R_end)]
        out["t_end_s"] = float(t[-1])
        return out
    if m.kind == "momentum":
        if free_body_keys("p")[0] not in result.columns:  # an FMU's run: no free-body state recorded
            return {}
        p, h = free_body_series(result, "p"), free_body_series(result, "h_cm")
        d = tip_from_cm(result)
        transverse = np.linalg.norm(d, axis=1)
        out = {
            "linear_momentum_drift_rel": float(np.max(np.linalg.norm(p - p[0], axis=1)) / max(np.linalg.norm(p[0]), 1e-300)),
            "angular_momentum_drift_rel": float(np.max(np.linalg.norm(h - h[0], axis=1)) / max(np.linalg.norm(h[0]), 1e-300)),
            "total_energy_drift_rel": energy_balance(result.columns),
            "tip_from_cm_max_m": float(np.max(transverse)),
            "tip_from_cm_rms_m": float(np.sqrt(np.mean(transverse**2))),
        }
        if m.band_hz and t[-1] - t[0] >= m.min_window_s:
            out["tip_from_cm_frequency_hz"] = dominant_frequency(t, d[:, 2], *m.band_hz)
        return out
    return {}


# ------------------------------------------------------------------------------------ plots
def plot(result: SimulationResult, scene: Scene, path) -> None:
    """Energies, and the benchmark's quantity of interest (tip deflection or port angular velocity)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    t = result.t
    hub, tip = end_ports(result.body)
    if scene.metrics.kind == "hub_rates":
        w = result.port(hub, "w")
        for i, c in enumerate("xyz"):
            ax1.plot(t, w[:, i], label=f"{hub} omega_{c}")
        ax1.set_ylabel("angular velocity [rad/s]")
    else:
        d = elastic_tip(result, hub, tip)
        for i, c in enumerate("xyz"):
            ax1.plot(t, d[:, i], label=f"{tip} elastic d_{c} (eq. 92)")
        ax1.set_ylabel("elastic tip displacement [m]")
    ax1.legend(loc="best")
    ax1.grid(True, alpha=0.3)
    c = result.columns
    energies = [k.removeprefix("energy.") for k in c if k.startswith("energy.")]
    total = sum(c[f"energy.{k}"] for k in energies if k != "work_external")
    for k in energies:
        ax2.plot(t, c[f"energy.{k}"], label=k.replace("_", " "))
    ax2.plot(t, total, "k--", lw=1, label="total")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("energy [J]")
    ax2.legend(loc="best")
    ax2.grid(True, alpha=0.3)
    model = (f"reference beam, {result.summary['elements']} elements" if result.summary.get("solver") == "reference"
             else f"{len(result.body.superelements)} SE, terms {scene.terms}")
    fig.suptitle(f"{result.body.name} / {scene.name}: {model}, h = {result.summary['step']:g} s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_reference(model: Model, scene: Scene, n_elements: int | None = None, step: float | None = None) -> SimulationResult:
    """The scene on the full-order geometrically exact beam (ffrf_fmu/reference), as a SimulationResult
    with the same port columns and metrics. Default mesh: the FE mesh the superelements are reduced
    from (superelements x elements per superelement), unreduced."""
    from .reference import simulate_reference
    from .runtime.data import BodyData, PortData

    body = scene_body(model.body, scene)
    n = n_elements or body.superelements * body.elements_per_superelement
    ref = simulate_reference(body, scene, n_elements=n, step=step)
    L, e = body.length, np.asarray(body.direction, float) / np.linalg.norm(body.direction)
    nodes = np.asarray(body.origin, float) + np.outer(np.arange(body.superelements + 1) * L / body.superelements, e)
    ports = tuple(PortData(p.name, p.node, p.translation, p.rotation) for p in body.ports)
    shell = BodyData(name=body.name, superelements=(), node_positions=nodes, ports=ports)
    columns = {}
    for p in ports:
        for fld in BodySystem.OUTPUT_FIELDS:
            arr = ref.ports[p.name][fld].reshape(len(ref.t), -1)
            columns.update(zip(port_variables(p.name, fld), arr.T))
    for k in ("kinetic", "strain", "work_external"):
        columns[f"energy.{k}"] = ref.energy[k]
    columns |= free_body_columns(*(ref.mass[k] for k in FREE_BODY_FIELDS))
    summary = {
        "body": body.name, "scene": scene.name, "solver": "reference", "elements": n,
        "step": (ref.info or {}).get("step", step or scene.step), "completed": bool(ref.t[-1] >= scene.duration - 1e-9),
        "failure": None, "t_end": float(ref.t[-1]), "wall_time_s": ref.wall_time_s, "steps": len(ref.t) - 1,
        "real_time_factor": float(ref.t[-1] / ref.wall_time_s) if ref.wall_time_s > 0 else None,
        "newton_iterations_mean": ref.newton_iterations_mean, "energy_balance_max_rel": energy_balance(columns),
        "energy_error": float((ref.info or {}).get("energy_error", np.nan)),
    }
    result = SimulationResult(ref.t, columns, summary, shell)
    summary["metrics"] = metrics(result, scene)
    return result
