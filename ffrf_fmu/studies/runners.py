"""The runs a study is made of, one configuration each (task.py names them; a worker calls them):

- `run_configuration`: the body standalone (simulate.run) or through its FMU under fmpy, with the
  scene's metrics and the elastic tip trajectory (eq. 92): a chart or study row's source;
- `run_reference`: the full-order geometrically exact beam (ffrf_fmu.reference) on the same scene;
- `run_beam`: the standalone body stepped with the stop criteria of the stability maps (a body
  that bends by more than its length is diverging), recording the transverse tip deflection and
  the energy balance.

Each returns plain data (numbers, texts, numpy arrays) that the result store keeps: there is no
other cache of runs (a rerun of a sweep takes finished runs from the store, store.py).
"""
from __future__ import annotations

import dataclasses
import math
import time
import traceback
import warnings
from typing import Any, Sequence

import numpy as np

from ..model import Model, Scene, load_model
from ..runtime.outputs import tip_from_hub
from ..runtime.steps import whole_steps
from .grid import value_overrides


class SetupError(ValueError):
    """A run cannot be set up (reference mesh incompatible with the model, unknown runner)."""


def resolved(model: Model, scene_name: str | None) -> dict[str, Any]:
    """The configuration keys every chart row shows, as the loaded model and scene have them."""
    sc = model.scene(scene_name)
    return {"superelements": model.body.superelements, "modes": model.body.modes, "terms": sc.terms,
            "step": sc.step}


def body_data(model: Model, scene: Scene):
    """The reduced body (BodyData) of the model with the scene's port causality."""
    from ..reduction import reduce_scene_body

    return reduce_scene_body(model.body, scene).data


def transverse(d: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Norm of the part of d (..., 3) normal to the unit beam axis."""
    axial = d @ axis
    return np.linalg.norm(d - axial[..., None] * axis, axis=-1)


# ------------------------------------------------------------------------------ standalone and FMU
def run_configuration(model_path: str, scene_name: str | None, base_overrides: Sequence[str],
                      values: dict[str, str], runner: str = "standalone", backend: str = "numpy") -> dict:
    """Run one configuration. Returns a picklable dict: shown values, times and the elastic tip
    trajectory, metrics, wall and CPU time, completion. Never raises: a configuration that cannot
    run is a row with its failure."""
    from .. import simulate as sim

    out: dict[str, Any] = {"values": dict(values), "runner": runner, "completed": False, "failure": None}
    try:
        model = load_model(model_path, list(base_overrides) + value_overrides(values))
        sc = model.scene(scene_name)
        out["resolved"] = resolved(model, scene_name)
        body = body_data(model, sc)
        if runner == "standalone":
            res = sim.run(body, sc, origin=model.body.origin, progress=False, backend=backend)
            s = res.summary
            # wall and CPU of the same span (the run): CPU timed
            # around the whole call also covered the set-up and the summary, and exceeded the wall on short runs
            out |= {"wall_time_s": s["wall_time_s"], "cpu_time_s": s["cpu_time_s"], "completed": bool(s["completed"]), "failure": s["failure"],
                    "t_end_s": s["t_end"], "newton_iterations_mean": s["newton_iterations_mean"],
                    "backend": s.get("backend")}  # the one that ran (native falls back to numpy with a note)
        elif runner == "fmu":
            res, wall, cpu = run_fmu_configuration(model_path, model, sc,
                                                   list(base_overrides) + value_overrides(values), body, backend)
            reached = abs(res.t[-1] - sc.duration) <= 1e-9 * max(1.0, sc.duration)
            out |= {"wall_time_s": wall, "cpu_time_s": cpu, "completed": bool(reached),
                    "failure": None if reached else f"FMU stopped at t = {res.t[-1]:.6g} s (fmi2Discard/Error)",
                    "t_end_s": float(res.t[-1])}
        else:
            raise SetupError(f"unknown runner {runner!r}")
        out["metrics"] = sim.metrics(res, sc)
        out["t"] = np.asarray(res.t)
        out["d"] = sim.tip_trajectory(res, sc)
    except Exception as e:  # noqa: BLE001 - a configuration that cannot run is a row, not a crash
        out["failure"] = f"{type(e).__name__}: {e}"
        out["traceback"] = traceback.format_exc(limit=4)
    return out


def run_fmu_configuration(model_path, model: Model, sc: Scene, overrides, body, backend="numpy"):
    """Build the configuration's FMU (into a temporary directory) and run it under fmpy with
    communication step = internal step (fmu/run.py); (SimulationResult, wall time, CPU time)."""
    import tempfile
    from pathlib import Path

    from ..fmu.builder import build_fmu
    from ..fmu.run import run_fmu
    from ..simulate import scene_inputs

    with tempfile.TemporaryDirectory(prefix="ffrf_chart_fmu_") as tmp:
        fmu = build_fmu(model_path, Path(tmp) / f"{model.body.name}.fmu", scene=sc.name, overrides=overrides,
                               backend=backend)
        run = run_fmu(fmu, sc, scene_inputs(body, sc, load_interval=(0.0, sc.step)))  # held over (t, t + H]
    return run.result(body), run.wall_time_s, run.cpu_time_s


# ------------------------------------------------------------------------------ reference
def reference_elements(model: Model, scene: Scene, n_elements: int | None) -> int:
    """The reference mesh: n_elements, default the scene's [reference] elements, else max(16, 4 x
    superelements) (the reference's own default); a multiple of the model's superelements (its ports
    sit on their boundary nodes)."""
    n_se = model.body.superelements
    n_el = int(n_elements or scene.reference.elements or max(16, 4 * n_se))
    if n_el % n_se:
        raise SetupError(f"--reference-elements {n_el}: must be a multiple of the model's {n_se} superelements "
                         "(the ports sit on superelement boundary nodes)")
    return n_el


def run_reference(model_path: str, scene_name: str | None, base_overrides: Sequence[str], n_elements: int | None,
                  step: float | None) -> dict:
    """The reference run of the scene (full-order beam, `reference_elements` elements, step h, else
    the scene's [reference] step, else the scene's step). Returns {"t", "d" (tip_trajectory), "metrics", "wall_time_s",
    "n_elements", "step", "energy_error", "warning"}; the solver's energy warning is returned in
    "warning" (in a worker process a Python warning would be lost)."""
    from ..simulate import run_reference as reference_result, tip_trajectory

    model = load_model(model_path, base_overrides)
    sc = model.scene(scene_name)
    n_el = reference_elements(model, sc, n_elements)
    h = float(step or sc.reference.step or sc.step)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="reference: energy error", category=RuntimeWarning)
        result = reference_result(model, sc, n_elements=n_el, step=h)
    energy_error = result.summary["energy_error"]
    return {"t": result.t, "d": tip_trajectory(result, sc), "metrics": result.summary["metrics"],
            "wall_time_s": result.summary["wall_time_s"], "n_elements": n_el, "step": h, "energy_error": energy_error,
            "warning": reference_warning(energy_error, h)}


def reference_warning(energy_error: float | None, step: float) -> str:
    """The reference solver's energy warning (reference/solver.py), or "" when the run is trusted."""
    from ..reference.solver import ENERGY_ERROR_SUSPECT

    if energy_error is None or energy_error <= ENERGY_ERROR_SUSPECT:
        return ""
    return (f"reference suspect: energy error {100 * energy_error:.2g} % of the energy level > "
            f"{100 * ENERGY_ERROR_SUSPECT:g} % (h = {step:g} s): its step is probably too large, errors against it "
            "are not trustworthy; halve --reference-step and compare")


# ------------------------------------------------------------------------------ the stability maps' run
@dataclasses.dataclass(frozen=True)
class BeamRun:
    """A standalone beam run reduced to what the maps need."""

    t: np.ndarray
    deflection: np.ndarray  # transverse elastic tip deflection (eq. 92) [m]
    completed: bool
    unstable: bool
    failure: str
    wall_time_s: float
    energy_gap: np.ndarray  # E(t) - E(0) - W_ext(t) [J]
    energy_level: float = 0.0  # max of the total energy and of |W_ext| [J]

    @property
    def max_deflection(self) -> float:
        return float(np.max(self.deflection)) if len(self.deflection) else float("nan")

    @property
    def energy_growth(self) -> float:
        """Largest energy the integrator created, max_t (E(t) - E(0) - W_ext(t)), over the energy level."""
        return float(max(np.max(self.energy_gap), 0.0) / self.energy_level) if self.energy_level > 0 else 0.0

    def as_result(self) -> dict:
        """The run as a task result (task.py): arrays and scalars."""
        return {"t": self.t, "deflection": self.deflection, "energy_gap": self.energy_gap,
                "completed": self.completed, "unstable": self.unstable, "failure": self.failure,
                "wall_time_s": self.wall_time_s, "energy_level": self.energy_level,
                "max_deflection": self.max_deflection, "energy_growth": self.energy_growth,
                "t_end": float(self.t[-1]) if len(self.t) else 0.0}


def run_beam(model: Model, scene: Scene, *, stop_deflection: float | None = None, record_every: int = 1,
             perturbation: float = 0.0) -> BeamRun:
    """Step the standalone body through `scene` (simulate.build_system), recording the transverse
    elastic tip deflection of eq. (92) between the first and the last boundary node and the energy
    gap. Stops at a StepFailure, a non-finite value or when the deflection exceeds
    `stop_deflection` (default: the beam length): those runs are unstable. perturbation: the initial
    node positions scaled by 1 +- perturbation, alternately per coordinate (the margin check of the
    stability maps, stability/margin.py)."""
    from ..runtime.ports import StepFailure
    from ..simulate import build_system, end_ports

    start = time.perf_counter()
    body = body_data(model, scene)
    system, inputs = build_system(body, scene, model.body.origin)
    if perturbation:
        for name in ("xN", "x0"):
            x = getattr(system, name)
            sign = np.where(np.arange(x.size) % 2 == 0, 1.0, -1.0).reshape(x.shape)
            x *= 1.0 + perturbation * sign
    hub, tip = end_ports(body)
    n_hub, n_tip = body.port(hub).node, body.port(tip).node
    X = body.node_positions[n_tip] - body.node_positions[n_hub]
    axis = X / np.linalg.norm(X)
    limit = model.body.length if stop_deflection is None else stop_deflection
    n_steps = whole_steps(scene.duration, scene.step).n

    def sample():
        o = system.outputs()
        d = tip_from_hub(o[hub].R, o[hub].r, o[tip].r, X)
        e = system.energies()
        tot = e["kinetic_rigid"] + e["kinetic_elastic"] + e["strain"]
        return float(transverse(d, axis)), tot, e["work_external"]

    ts, samples = [system.t], [sample()]
    failure, unstable = "", False
    for k in range(1, n_steps + 1):
        try:
            system.step(scene.step, inputs)
        except StepFailure as exc:
            failure, unstable = f"StepFailure: {exc}", True
            break
        s = sample()
        if not all(math.isfinite(x) for x in s):
            failure, unstable = f"non-finite state at t = {system.t:.4g} s", True
            break
        if s[0] > limit:
            ts.append(system.t)
            samples.append(s)
            failure, unstable = f"tip deflection {s[0]:.3g} m > {limit:g} m at t = {system.t:.4g} s", True
            break
        if k % record_every == 0 or k == n_steps:
            ts.append(system.t)
            samples.append(s)
    d, tot, work = (np.array(c) for c in zip(*samples))
    return BeamRun(t=np.array(ts), deflection=d, completed=not unstable, unstable=unstable, failure=failure,
                   wall_time_s=time.perf_counter() - start, energy_gap=tot - tot[0] - work,
                   energy_level=float(max(np.max(np.abs(tot)), np.max(np.abs(work)))))


def beam_run_of(result: dict) -> BeamRun:
    """The BeamRun back from its task result (as_result)."""
    return BeamRun(t=np.asarray(result["t"]), deflection=np.asarray(result["deflection"]),
                   completed=bool(result["completed"]), unstable=bool(result["unstable"]), failure=result["failure"],
                   wall_time_s=float(result["wall_time_s"]), energy_gap=np.asarray(result["energy_gap"]),
                   energy_level=float(result["energy_level"]))
