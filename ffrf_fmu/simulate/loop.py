"""The standalone run loop: the body built for a scene and initialized, stepped with the scene's
constant step to the end (chunks in one call of the compiled runtime where it can), every step recorded,
the summary with the run's timings and metrics."""
from __future__ import annotations

import dataclasses
import sys
import time
import warnings
from typing import Callable, Sequence

import numpy as np

from ..model import Model, Scene, load_model
from ..runtime.body import BodySystem
from ..runtime.data import BodyData
from ..runtime.ports import StepFailure
from ..runtime.steps import divides, whole_steps
from .inputs import scene_inputs, scene_schedule
from .quantities import energy_balance, metrics
from .results import SimulationResult, column_names, free_body_columns


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


def build_system(body: BodyData, scene: Scene, origin=(0.0, 0.0, 0.0), backend: str = "native") -> tuple[BodySystem, Callable]:
    """A BodySystem for the scene, initialized at t = 0; returns it with its input function.
    backend: "native" (the C runtime; numpy with a logged note where it cannot be compiled) or "numpy"
    (the reference)."""
    system = BodySystem(body, terms=scene.terms, full_terms=scene.full_terms, rho_inf=scene.rho_inf, gravity=scene.gravity, backend=backend,
                         iteration_cap=scene.max_newton_iterations)

    inputs = scene_inputs(body, scene, load_interval=(-scene.step, 0.0))  # each window's mean over the step
    init = scene.initial
    try:
        system.initialize(
            0.0,
            scene_inputs(body, scene),  # the loads acting at t = 0: a consistent start (the initial rates see
            # what an FMU sees with its inputs set at t = 0; docs/equations.md)
            velocity=init.velocity,
            angular_velocity=init.angular_velocity,
            port_displacements=dict(init.port_displacements),
            origin=origin,
        )
        if init.state != "rest":  # (a body at rest is settled as it is: no import)
            from ..initial_state import settle  # static equilibrium or steady spin ([scenes.NAME.initial] state)

            settle(system, scene, inputs)
    except StepFailure as e:
        raise InitializationFailure(f"scene {scene.name!r} cannot start: {e.cause}") from e
    return system, inputs


def record(system: BodySystem) -> np.ndarray:
    """One row of the time series: every port's outputs (column_names order), energies, Newton iterations."""
    return system.output_row()


def free_body_state(system: BodySystem) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(CM, inertia tensor about the CM, linear momentum, angular momentum about the CM) of the body,
    world axes, as its equations hold them (BodySystem.mass_properties, momenta)."""
    _, c, J = system.mass_properties()
    p, h = system.momenta()
    return c, J, p, h - np.cross(c, p)


def run(body: BodyData, scene: Scene, *, origin=(0.0, 0.0, 0.0), progress: bool = True,
        backend: str = "native") -> SimulationResult:
    """Step the body through the scene with the scene's constant step; record every step.

    A duration that is not a whole number of steps is never rounded: the step is reduced to
    divide it (runtime/steps.py whole_steps), with a warning, and the summary gives both steps."""
    start, cpu_start = time.perf_counter(), time.process_time()
    requested = scene.step
    n_steps, h = whole_steps(scene.duration, requested)
    if not divides(scene.duration, requested):
        warnings.warn(f"scene {scene.name!r}: duration {scene.duration:g} s is not a whole number of steps of "
                      f"{requested:g} s ({scene.duration / requested:.6g}): step reduced to {h:.6g} s "
                      f"({n_steps} steps)", UserWarning, stacklevel=2)
    if h != requested:  # reduced, or the same step to round-off: the run ends at the duration
        scene = dataclasses.replace(scene, step=h)
    system, inputs = build_system(body, scene, origin, backend)
    setup = time.perf_counter() - start  # the body's equations, its image and C body, the initial state
    rows = np.empty((n_steps + 1, len(column_names(body))))
    rows[0] = record(system)
    times = np.empty(n_steps + 1)
    times[0] = 0.0
    free = scene.metrics.kind == "momentum"  # these metrics read the mass properties at every step
    masses = [free_body_state(system)] if free else []
    bar = Progress(scene.duration, f"{body.name}/{scene.name}") if progress else None
    iterations = 0
    failure = None
    # on the native backend, chunks of steps run in one call of the C runtime each, with the scene's
    # inputs and the recording inside (momenta, for a free body's
    # metrics, are recorded in Python: such scenes step one by one, as do scenes with a rotating unbalance,
    # whose force the compiled schedule does not carry)
    schedule = None if free or scene.unbalances else scene_schedule(body, scene)
    k = 0
    while k < n_steps:
        compiled = system._compiled
        if schedule is not None and compiled is not None:
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
    # (wall and CPU alike: counting its CPU but not its wall made short runs report CPU above wall)
    wall = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
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
        "setup_time_s": setup,
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
    t_metrics = time.perf_counter()
    summary["metrics"] = metrics(result, scene)
    summary["metrics_time_s"] = time.perf_counter() - t_metrics  # after wall_time_s: not part of it
    return result


def run_scene(model: Model | str, scene: str | None = None, overrides: Sequence[str] = (), progress=False,
              backend: str = "native"):
    """Load (if a path), build and reduce the body for the scene (or load it from the cache of reduced
    bodies, body_cache.py), run it standalone. overrides apply to a path as it is loaded; a Model is
    already loaded, so overrides with it are refused (load_model(path, overrides) takes them). The
    summary's load_time_s is the body's (from the cache, or reduced), before wall_time_s and not part of it."""
    from ..body_cache import scene_body_data

    if not isinstance(model, Model):
        model = load_model(model, overrides)
    elif overrides:
        raise ValueError(f"run_scene: overrides {list(overrides)} with a loaded Model would be ignored: give them to "
                         "load_model(path, overrides), or pass the model file's path")
    scene = model.scene(scene)
    start = time.perf_counter()
    body = scene_body_data(model.body, scene)
    load = time.perf_counter() - start
    result = run(body, scene, origin=model.body.origin, progress=progress, backend=backend)
    result.summary["load_time_s"] = load
    return result


def run_input_rule(body: BodyData, scene: Scene, comm_step: float, *, origin=(0.0, 0.0, 0.0),
                   backend: str = "native") -> SimulationResult:
    """The standalone body stepped as its FMU steps: the scene's inputs sampled at the communication points
    t_c of a master's grid (runtime/steps.communication_grid, step H = comm_step; loads as each window's mean
    over (t_c, t_c + H], fmu/run.py) and between them the FMU's input rule (runtime/input_rule.py: motions
    extrapolated to second order, loads held), each communication step n equal internal steps of at most the
    scene's step (BodySystem.run_extrapolated, as fmu/core.py `do_step`). Recorded at the communication
    points: the FMU's outputs under fmpy, to the Newton tolerance (validate.py compares the two); against
    `run`, which evaluates the exact inputs at every step's end, it differs by the sampling (docs/fmu.md)."""
    from ..runtime.input_rule import point_values
    from ..runtime.steps import communication_grid

    start = time.perf_counter()
    system, _ = build_system(body, scene, origin, backend)
    sampled = scene_inputs(body, scene, load_interval=(0.0, comm_step))
    grid = communication_grid(scene.duration, comm_step)
    rows = np.empty((len(grid), len(column_names(body))))
    rows[0] = record(system)
    free = scene.metrics.kind == "momentum"
    masses = [free_body_state(system)] if free else []
    failure, k = None, 0
    for k in range(len(grid) - 1):
        t_c, t_end = grid[k], grid[k + 1]
        n, h = whole_steps(t_end - t_c, scene.step)
        try:
            system.run_extrapolated(h, n, t_c, point_values(body.ports, sampled(t_c)), rows[k + 1])
        except StepFailure as exc:
            failure = str(exc)
            break
        system.t = t_end  # the master's clock, as the FMU keeps it
        if free:
            masses.append(free_body_state(system))
    else:
        k = len(grid) - 1
    columns = dict(zip(column_names(body), rows[: k + 1].T))
    if free:
        columns |= free_body_columns(*(np.array(x) for x in zip(*masses)))
    times = np.asarray(grid[: k + 1], dtype=float)
    summary = {"body": body.name, "scene": scene.name, "terms": scene.terms, "step": scene.step,
               "comm_step": comm_step, "backend": system.backend, "completed": failure is None, "failure": failure,
               "t_end": float(times[-1]), "wall_time_s": time.perf_counter() - start,
               "inputs": "the FMU's input rule: sampled at the communication points, extrapolated between them"}
    return SimulationResult(times, columns, summary, body)
