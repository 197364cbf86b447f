"""The integrator map (docs/stability.md): generalized-alpha step size against rho_inf on one
scene, each run's tip deflection against a converged (small-step) run; unstable = Newton failure,
a non-finite state, deflection > L, or energy created by the integrator (`ENERGY_GROWTH`)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ...model import Model, load_model
from ..runners import BeamRun, beam_run_of, run_beam
from ..sweep import SweepOptions, sweep_into
from ..task import make_task
from . import margin
from .common import write_map

RHO_INFS = (0.0, 0.5, 0.8, 1.0)
ENERGY_GROWTH = 0.05  # unstable: the integrator created more than 5 % of the energy level


@dataclasses.dataclass
class IntegratorSettings:
    """Step sizes against rho_inf for one scene; the converged run uses `converged_step`."""

    steps: tuple[float, ...]
    rhos: tuple[float, ...] = RHO_INFS
    converged_step: float = 5e-4
    converged_rho: float = 0.8
    duration: float | None = None  # None: the scene's
    overrides: tuple[str, ...] = ()
    margin: bool = True  # re-run the points whose verdict could flip (margin.py)


def integrator_overrides(scene: str, step: float, rho: float, settings: IntegratorSettings) -> list[str]:
    ov = [*settings.overrides, f"scenes.{scene}.step={step!r}", f"scenes.{scene}.rho_inf={rho!r}"]
    if settings.duration is not None:
        ov.append(f"scenes.{scene}.duration={settings.duration!r}")
    return ov


def integrator_run(model_path, scene: str, step: float, rho: float, settings: IntegratorSettings,
                   perturbation: float = 0.0) -> tuple[BeamRun, Model]:
    """One run of the map in this process (the map's runs are the same, through the sweep layer);
    perturbation: of the initial state (run_beam), for the margin check."""
    model = load_model(model_path, integrator_overrides(scene, step, rho, settings))
    return run_beam(model, model.scene(scene), perturbation=perturbation), model


def run_unstable(run: BeamRun) -> bool:
    """The map's instability criterion: a failed run or energy growth beyond ENERGY_GROWTH."""
    return bool(run.unstable or run.energy_growth > ENERGY_GROWTH)


def margin_verdict(model_path, scene: str, row: dict, settings: IntegratorSettings, length: float,
                   duration: float) -> str:
    """The row's verdict with a margin (margin.classify): re-runs, in this process, of a point whose
    verdict could flip."""
    point = margin.Point(unstable=bool(row["unstable"]), t_end=float(row.get("t_end", 0.0)), duration=duration,
                         failure=row.get("failure", ""),
                         # a run stopped at the deflection bound ends just past it: its time decides, not the ratio
                         bound_ratios=(row.get("energy_growth", 0.0) / ENERGY_GROWTH,
                                       *(() if row["unstable"] else (row.get("max_deflection", 0.0) / length,))))
    rerun = lambda h, eps: run_unstable(integrator_run(model_path, scene, h, row["rho_inf"], settings, eps)[0])
    return margin.classify(point, row["step"], settings.steps, rerun)


def integrator_map(model_path, scene: str, settings: IntegratorSettings, out_dir,
                   sweep: SweepOptions = SweepOptions()) -> list[dict]:
    """Step size against rho_inf on one scene: error of the maximum transverse tip deflection
    (`peak_rel_error`, signed) and of its history (`rel_error`: max over time of the difference,
    over the converged run's peak), energy growth, stability."""
    s = settings
    name = Path(model_path).stem
    conv_task = make_task(model_path, integrator_overrides(scene, s.converged_step, s.converged_rho, s), scene, "beam")
    tasks = {(rho, h): make_task(model_path, integrator_overrides(scene, h, rho, s), scene, "beam")
             for rho in s.rhos for h in s.steps}
    notes = {conv_task.key: f"{name}/{scene}: converged run h = {s.converged_step:g} s",
             **{t.key: f"{name}/{scene} h = {h:g} s rho_inf {rho:g}" for (rho, h), t in tasks.items()}}
    results = sweep_into(out_dir, [conv_task, *tasks.values()], f"integrator map {name}/{scene}", notes, sweep).results
    c = results[conv_task.key]
    if not c.get("completed"):
        raise RuntimeError(f"{name}/{scene}: the converged run failed: {c['failure']}")
    conv = beam_run_of(c)
    t_c, d_c = conv.t, conv.deflection
    rows = [{"benchmark": name, "scene": scene, "step": s.converged_step, "rho_inf": s.converged_rho,
             "converged": True, "peak_rel_error": 0.0, "rel_error": 0.0, "energy_growth": conv.energy_growth,
             "unstable": False, "failure": "", "t_end": float(t_c[-1]), "wall_time_s": conv.wall_time_s}]
    series = {f"{name}_{scene}_converged": np.column_stack([t_c, d_c])}
    peak = float(np.max(np.abs(d_c)))
    for (rho, h), task in tasks.items():
        res = results[task.key]
        if "t" not in res:  # the run could not start: a row with its cause
            rows.append({"benchmark": name, "scene": scene, "step": float(h), "rho_inf": float(rho),
                         "converged": False, "unstable": True, "failure": res["failure"]})
            continue
        run = beam_run_of(res)
        n = len(run.t)
        err = float(np.max(np.abs(run.deflection - np.interp(run.t, t_c, d_c))) / peak) if n else float("nan")
        growth = run.energy_growth
        failure = run.failure
        if not run.unstable and growth > ENERGY_GROWTH:
            failure = f"energy growth {growth:.3g} > {ENERGY_GROWTH:g} of the energy level"
        rows.append({"benchmark": name, "scene": scene, "step": float(h), "rho_inf": float(rho), "converged": False,
                     "peak_rel_error": float((run.max_deflection - peak) / peak), "rel_error": err,
                     "energy_growth": growth, "max_deflection": run.max_deflection, "unstable": bool(failure), "failure": failure,
                     "t_end": float(run.t[-1]), "wall_time_s": run.wall_time_s})
        series[f"{name}_{scene}_h{h:g}_rho{rho:g}"] = np.column_stack([run.t, run.deflection])
    model = load_model(model_path, integrator_overrides(scene, s.converged_step, s.converged_rho, s))
    duration = model.scene(scene).duration
    for r in rows:
        if r["converged"]:
            r["verdict"] = "reference"
        elif "t_end" not in r:
            r["verdict"] = margin.UNSTABLE
        else:
            r["verdict"] = margin_verdict(model_path, scene, r, s, model.body.length, duration) if s.margin \
                else (margin.UNSTABLE if r["unstable"] else margin.STABLE)
    write_map(out_dir, rows, series)
    return rows
