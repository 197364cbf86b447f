"""The spin map (docs/stability.md, B3): final spin rate against (superelements, term set), each
model run's maximum transverse tip deflection against the nonlinear full-order beam's; and the
steady-spin check that separates the model error from a loss of stability.

The spin-up sweep mixes two things: the model error under the spin-up loads, and the loss of
stability of the spinning model. The second is a property of the model at constant spin: spun at
the constant rate Omega from t = 0 (hub drive "ramp" started before t = 0, the body starts with
the rigid velocity field) and kicked by a short transverse tip force, a stable model keeps a
bounded vibration, an unstable one grows exponentially (`steady_spin`).
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from ...model import Model, Scene, load_model
from ...reference.solver import ENERGY_ERROR_SUSPECT
from ..runners import beam_run_of, run_beam, transverse
from ..sweep import SweepOptions, sweep_into
from ..task import make_task
from . import margin
from .common import write_map

SPIN_RATES = (1.0, 2.0, 2.5, 3.0, 3.5, 4.0, 6.0, 8.0, 10.0, 12.0)
SPIN_MODELS = tuple((n, terms) for terms in ("linear", "gyroscopic") for n in (1, 2, 4))
GROWTH_LIMIT = 2.0  # unstable at constant spin: the vibration envelope grows more than 2x
RECORD_EVERY = 10  # the model runs keep every 10th step of their deflection history


def spin_overrides(scene: str, omega: float, *, T: float, duration: float, n_se: int | None = None,
                   terms: str | None = None, step: float | None = None, extra: Sequence[str] = ()) -> list[str]:
    """--set overrides: the scene's hub spin-up to `omega` in T, the run's duration, optionally the
    superelements, term set and step; `extra` last (they win)."""
    ov = [f"scenes.{scene}.drives.hub.rotation.angle.omega={omega!r}",
          f"scenes.{scene}.drives.hub.rotation.angle.T={T!r}", f"scenes.{scene}.duration={duration!r}"]
    if n_se is not None:
        ov.append(f"superelements={n_se}")
    if terms is not None:
        ov.append(f"scenes.{scene}.terms={terms}")
    if step is not None:
        ov.append(f"scenes.{scene}.step={step!r}")
    return [*ov, *extra]


def spin_scene(model_path, scene: str, omega: float, **kw) -> tuple[Model, Scene]:
    """The B1/B3 scene with final spin `omega` (spin_overrides' keywords)."""
    model = load_model(model_path, spin_overrides(scene, omega, **kw))
    return model, model.scene(scene)


def reference_step(omega: float) -> float:
    """Step of the nonlinear reference: its Lie-group generalized-alpha needs spin x step below
    ~0.12 rad (reference/__init__.py); we keep it at 0.05 rad and at most 10 ms."""
    return min(0.01, 0.05 / omega)


@dataclasses.dataclass
class SpinSettings:
    """The spin sweep. T and duration default to half of B1's (15 s, 20 s): the same profile in
    half the time (docs/stability.md shows the conclusions do not change)."""

    omegas: tuple[float, ...] = SPIN_RATES
    models: tuple[tuple[int, str], ...] = SPIN_MODELS
    T: float = 7.5
    duration: float = 10.0
    reference_elements: int = 16
    overrides: tuple[str, ...] = ()  # --set values for every run
    margin: bool = True  # re-run the model points whose verdict could flip (margin.py, `spin_verdict`)


def spin_model_run(model_path, scene: str, omega: float, n_se: int, terms: str, settings: SpinSettings,
                   perturbation: float = 0.0):
    """One model run of the map in this process (the map's runs are the same, through the sweep layer);
    perturbation: of the initial state (run_beam), for the margin check."""
    model, sc = spin_scene(model_path, scene, omega, T=settings.T, duration=settings.duration, n_se=n_se,
                           terms=terms, extra=settings.overrides)
    return run_beam(model, sc, record_every=RECORD_EVERY, perturbation=perturbation)


def spin_verdict(model_path, scene: str, row: dict, settings: SpinSettings, length: float) -> str:
    """The model row's verdict with a margin (margin.classify; docs/stability.md, "Marginal points"): a
    point that failed in the last 10 % of its run, or whose peak deflection of a completed run is within
    margin.BOUND_FACTOR of L, is re-run in this process with its initial state perturbed at
    margin.PERTURBATION and at the neighbour spin rate of the sweep on the side a map monotone in the
    spin must agree with (the faster spin for an unstable point, the slower for a stable one). The grid
    is the sweep's final spin rates: omega plays the step's part of the integrator map."""
    unstable = bool(row["unstable"])
    point = margin.Point(unstable=unstable, t_end=float(row.get("t_end", 0.0)), duration=settings.duration,
                         failure=row.get("failure", ""),
                         # a run stopped at L ends just past it: its time decides, not the ratio
                         bound_ratios=() if unstable else (float(row.get("max_deflection", 0.0)) / length,))
    n_se, terms = int(row["superelements"]), row["terms"]
    rerun = lambda w, eps: bool(spin_model_run(model_path, scene, w, n_se, terms, settings, eps).unstable)
    return margin.classify(point, float(row["omega"]), tuple(settings.omegas), rerun)


def spin_map(model_path, scene: str, settings: SpinSettings, out_dir, sweep: SweepOptions = SweepOptions()) -> list[dict]:
    """Sweep the final spin rate against (superelements, term set); one CSV row per run:
    max transverse tip deflection of the model and of the nonlinear reference, the relative
    error, and `unstable` (StepFailure or deflection > L). The runs go through the sweep layer
    (sweep.sweep_into): a rerun takes the finished ones from DIR's store."""
    s = settings
    ref_tasks, model_tasks, notes = {}, {}, {}
    for omega in s.omegas:
        ov = spin_overrides(scene, omega, T=s.T, duration=s.duration, extra=s.overrides)
        ref_tasks[omega] = t = make_task(model_path, ov, scene, "reference", elements=s.reference_elements,
                                         step=reference_step(omega))
        notes[t.key] = f"omega {omega:g}: reference"
        for n_se, terms in s.models:
            ov = spin_overrides(scene, omega, T=s.T, duration=s.duration, n_se=n_se, terms=terms, extra=s.overrides)
            model_tasks[omega, n_se, terms] = t = make_task(model_path, ov, scene, "beam", record_every=RECORD_EVERY)
            notes[t.key] = f"omega {omega:g}: {n_se}SE-{terms}"
    results = sweep_into(out_dir, [*ref_tasks.values(), *model_tasks.values()], f"spin map {scene}", notes, sweep).results
    from ..advise import first_frequency

    model = load_model(model_path, list(s.overrides))
    f1 = 2 * np.pi * first_frequency(model.body)  # [rad/s]: the plot marks it
    axis = np.asarray(model.body.direction, float)
    axis = axis / np.linalg.norm(axis)
    rows, series = [], {}
    for omega in s.omegas:
        r = results[ref_tasks[omega].key]
        if not r["completed"]:
            raise RuntimeError(f"omega {omega:g}: the reference failed: {r['failure']}")
        d = transverse(np.asarray(r["d"]), axis)
        peak, energy_error = float(np.max(d)), float(r["energy_error"])
        ref = {"omega": float(omega), "model": "reference", "superelements": 0, "terms": "nonlinear",
               "max_deflection": peak, "ref_max_deflection": peak, "rel_error": 0.0,
               "unstable": bool(peak > model.body.length), "failure": "", "t_end": float(r["t"][-1]),
               "T": s.T, "duration": s.duration, "step": reference_step(omega), "wall_time_s": r["wall_time_s"],
               "ref_energy_error": energy_error, "reference_suspect": energy_error > ENERGY_ERROR_SUSPECT,
               "first_frequency_rad_s": f1}
        rows.append(ref)
        series[f"reference_w{omega:g}"] = np.column_stack([r["t"], d])[:: max(1, int(round(0.02 / reference_step(omega))))]
        for n_se, terms in s.models:
            name = f"{n_se}SE-{terms}"
            res = results[model_tasks[omega, n_se, terms].key]
            if "t" not in res:  # the run could not start: a row with its cause
                rows.append({"omega": float(omega), "model": name, "superelements": n_se, "terms": terms,
                             "unstable": True, "failure": res["failure"]})
                continue
            run = beam_run_of(res)
            err = (run.max_deflection - peak) / peak
            rows.append({"omega": float(omega), "model": name, "superelements": n_se, "terms": terms,
                         "max_deflection": run.max_deflection, "ref_max_deflection": peak,
                         "rel_error": float(err), "unstable": run.unstable, "failure": run.failure,
                         "t_end": float(run.t[-1]), "T": s.T, "duration": s.duration,
                         "step": _scene_step(model_path, model_tasks[omega, n_se, terms].overrides, scene),
                         "wall_time_s": run.wall_time_s, "ref_energy_error": energy_error,
                         "reference_suspect": ref["reference_suspect"]})
            series[f"{name}_w{omega:g}"] = np.column_stack([run.t, run.deflection])
    for r in rows:
        if r["model"] == "reference":
            r["verdict"] = "reference"
        elif "t_end" not in r:
            r["verdict"] = margin.UNSTABLE
        else:
            r["verdict"] = spin_verdict(model_path, scene, r, s, model.body.length) if s.margin \
                else (margin.UNSTABLE if r["unstable"] else margin.STABLE)
    write_map(out_dir, rows, series)
    return rows


def _scene_step(model_path, overrides, scene: str) -> float:
    return load_model(model_path, list(overrides)).scene(scene).step


def steady_spin(model_path, scene: str, omega: float, *, n_se: int, terms: str, duration: float = 6.0,
                kick: float = 0.2, extra: Sequence[str] = ()) -> dict:
    """Constant spin `omega` about the hub drive axis with a 0.1 s transverse tip force `kick` [N]
    (normal to the beam, in the plane of rotation). Returns the envelope growth (max deflection
    over the last third of the run / over the second third) and the verdict."""
    ov = [f"scenes.{scene}.drives.hub.rotation.angle={{ kind = \"ramp\", rate = {omega!r}, t_start = -1.0 }}",
          f"scenes.{scene}.loads=[{{ port = \"tip\", force = [0.0, {kick!r}, 0.0], t_start = 0.0, t_end = 0.1 }}]",
          f"scenes.{scene}.duration={duration!r}", f"superelements={n_se}", f"scenes.{scene}.terms={terms}", *extra]
    model = load_model(model_path, ov)
    run = run_beam(model, model.scene(scene))
    t, d = run.t, run.deflection
    third = t[-1] / 3 if len(t) else 0.0
    mid = d[(t >= third) & (t < 2 * third)]
    last = d[t >= 2 * third]
    growth = float(np.max(last) / np.max(mid)) if len(mid) and len(last) and np.max(mid) > 0 else float("inf")
    unstable = run.unstable or growth > GROWTH_LIMIT
    return {"omega": float(omega), "superelements": n_se, "terms": terms, "growth": growth,
            "max_deflection": run.max_deflection, "unstable": bool(unstable),
            "failure": run.failure or (f"envelope grows x{growth:.3g}" if unstable else ""),
            "t_end": float(t[-1]) if len(t) else 0.0, "wall_time_s": run.wall_time_s}
