"""Accuracy against cost: sweep model configurations, measure each run's wall time and its error
against the full-order reference, chart error over wall time with the Pareto front.

    ffrf-fmu chart MODEL --scene NAME --sweep superelements=1,2,4 modes=2,4,6 [--sweep ...] \
        [--fmu] [--reference-elements N] [--reference-step H] [--workers K] [--cost wall|cpu] [-o DIR]

A configuration is one value for every swept key (cartesian product of the lists; keys are the
`--set` keys of model.py: superelements, modes, terms, step, elements, ...; several --sweep
groups run the union of their products); unswept keys keep the model's values (plus any --set
override). docs/accuracy.md explains the chart and shows the one of B1. Each configuration runs standalone
(simulate.run) and, with --fmu, also through its FMU under fmpy with communication step =
internal step (runners.run_configuration).

Errors, both against the reference (ffrf_fmu.reference: the full-order geometrically exact beam,
an independent code) run on the same scene:
- metric_error_rel = |m - m_ref| / |m_ref| of the scene's primary metric (`primary_metric`);
- rms_error_rel = sqrt(mean_t |d(t) - d_ref(t)|^2) / max_t |d_ref(t)|, d the elastic tip
  displacement seen from the hub (eq. 92, simulate.elastic_tip), the reference interpolated
  (linearly) onto the configuration's time grid.
Both are computed with the same code for the configuration and the reference (simulate.metrics
on port histories), so they differ only through the models.

Cost: wall_time_s of the time stepping only (no reduction, no FMU build), measured inside the
worker process, with its CPU time (cpu_time_s). With K concurrent workers on fewer than K free
cores the wall times grow; the CPU time does not (the chart's x axis is wall time, as asked;
run with --workers 1 on a quiet machine for publishable wall times).

Every run, the reference included, is a task of the sweep layer (task.py, sweep.py): its result
is kept in DIR's result store (store.py), so re-running a chart repeats no finished run. The runs
themselves are runners.py's; the figure is chart_plot.py's.
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..model import Model, load_model
from .chart_plot import COSTS, PEER_NAMES, plot_chart
from .errors import errors, primary_metric  # noqa: F401 (chart.errors, chart.primary_metric: their callers)
from .grid import GridError, combinations, value_overrides
from .runners import resolved
from .sweep import Scheduler, SweepOptions, parse_scheduler, sweep_into
from .table import read_rows, write_rows
from .task import code_version, make_task

# the keys every row shows (resolved from the model when not swept), in label order
SHOWN_KEYS = ("superelements", "modes", "terms", "step")


class ChartError(GridError):
    """A chart cannot be set up (bad sweep, reference mesh incompatible with the model)."""


def fmt_step(h: float) -> str:
    ms = 1e3 * h
    return f"{ms:g}ms" if ms >= 0.1 else f"{h:g}s"


def label(values: dict[str, Any], extra: dict[str, Any] | None = None) -> str:
    """Short configuration label, e.g. 4SE/6m/lin/2ms (+ other swept keys as key=value)."""
    terms = {"linear": "lin", "gyroscopic": "gyr"}.get(str(values["terms"]), str(values["terms"]))
    text = f"{values['superelements']}SE/{values['modes']}m/{terms}/{fmt_step(float(values['step']))}"
    for k, v in (extra or {}).items():
        text += f"/{k}={v}"
    return text


def _failed_reference(failure: str, n_elements, step, scene) -> dict:
    return {"metrics": {}, "failure": failure, "wall_time_s": None,
            "n_elements": n_elements or scene.reference.elements, "step": step or scene.reference.step or scene.step,
            "cached": False,
            "energy_error": None, "warning": ""}


# ------------------------------------------------------------------------------ errors, front
def pareto_front(cost: Sequence[float], error: Sequence[float], same_error_rel: float = 0.0) -> list[int]:
    """Indices of the non-dominated points (no other point is both cheaper and more accurate),
    ordered by cost. NaN entries never belong to the front. same_error_rel: errors within this
    relative difference count as equal, so the dearer of two such points is dominated (default 0:
    any lower error counts)."""
    idx = [i for i in range(len(cost)) if np.isfinite(cost[i]) and np.isfinite(error[i])]
    idx.sort(key=lambda i: (cost[i], error[i]))
    front, best = [], math.inf
    for i in idx:
        if error[i] < best * (1.0 - same_error_rel):
            front.append(i)
            best = error[i]
    return front


def front_cost_at(cost: Sequence[float], error: Sequence[float], target: float) -> float | None:
    """Cost at which a Pareto front (points given by cost and error, e.g. those pareto_front picks)
    reaches the error `target`: linear interpolation in log-log between the two front points around
    it; the cheapest point's cost when that already meets the target (no extrapolation towards
    cheaper); None when no point reaches it."""
    pts = sorted((c, e) for c, e in zip(cost, error) if np.isfinite(c) and np.isfinite(e) and c > 0 and e > 0)
    for k, (c1, e1) in enumerate(pts):  # on a front the error falls as the cost rises
        if e1 <= target:
            if k == 0:
                return c1
            c0, e0 = pts[k - 1]
            s = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(c0) + s * (math.log(c1) - math.log(c0)))
    return None


# ------------------------------------------------------------------------------ peers
# the peer's default sweep (Exudyn's 3D beam over these meshes and steps)
PEER_SWEEP = {"elements": ["2", "3", "4", "6", "8", "16"], "step": ["0.002", "0.005", "0.01", "0.02", "0.04"]}


def _peer_configurations(peer: str | None, sweep) -> list[dict[str, str]]:
    if not peer:
        return []
    from ..peers import available

    ok, why = available(peer)
    if not ok:
        raise ChartError(f"--peer {peer}: {why}")
    configs = combinations(sweep or PEER_SWEEP)
    bad = [c for c in configs if set(c) - {"elements", "step"} or "elements" not in c]
    if bad:
        raise ChartError(f"--peer-sweep: the peer takes elements=... [step=...] only, got {bad[0]}")
    return configs


def _peer_cost(values: dict, scene) -> float:
    return int(values["elements"]) / float(values.get("step") or scene.step)


def peer_label(peer: str, values: dict, scene) -> str:
    """e.g. Exudyn 16el/2ms"""
    return f"{PEER_NAMES.get(peer, peer)} {int(values['elements'])}el/{fmt_step(float(values.get('step') or scene.step))}"


# ------------------------------------------------------------------------------ the chart
def _jobs_order(configs: list[dict], model: Model, scene_name) -> list[int]:
    """Longest first (cost ~ superelements x (12 + modes) / step) for a better load balance."""
    base = resolved(model, scene_name)

    def cost(c):
        v = {**base, **c}
        try:
            return int(v["superelements"]) * (12 + int(v["modes"])) / float(v["step"])
        except (TypeError, ValueError):
            return 0.0

    return sorted(range(len(configs)), key=lambda i: -cost(configs[i]))


def chart(model_path, scene_name: str | None = None, sweep=None, *,
          overrides: Sequence[str] = (), fmu: bool = False, reference_elements: int | None = None,
          reference_step: float | None = None, workers: int | None = None, out_dir="chart",
          progress: bool = True, plot: bool = True, cost: str = "wall", peer: str | None = None,
          peer_sweep=None, backend: str = "numpy", scheduler=None, fresh: bool = False,
          resolve: float | None = None) -> dict:
    """Run the sweep and the reference; write DIR/chart.csv, DIR/chart.json and DIR/chart.png.

    sweep: {key: [value texts]} or a list of such groups (union of their cartesian products;
    configurations that resolve to the same values run once). cost: "wall" (default) or "cpu":
    the time that the plot's x axis and the Pareto front use. peer: also run a peer code
    (ffrf_fmu.peers: "exudyn") over peer_sweep ({"elements": [...], "step": [...]}, default
    PEER_SWEEP) on the scene with the model's overrides; its rows (runner = the peer) get their
    own Pareto front, measured against the same reference. scheduler: where the runs go
    (studies/sweep.py: None = a local pool of `workers` processes, "local:N", a dask scheduler
    address); the results are stored in DIR/runs.jsonl and a rerun skips the finished ones
    (fresh: discard them first).

    resolve: a tolerance; the reference is first refined (resolve.py) until the primary metric moves by
    less than a tenth of it, and the chart measures against the refined one; chart.json holds the
    refinement table, and every row says whether the reference was resolved (`reference_resolved`).

    Returns {"rows": [...], "reference": {...}, "csv", "png", "json", "meta", "tasks"}; tasks[j] is the
    run (task.Task) of rows[j], for a caller that runs it again (benchmarks/peers.py times it N times).
    """
    model_path = str(model_path)
    if cost not in COSTS:
        raise ChartError(f"cost must be one of {', '.join(COSTS)}, got {cost!r}")
    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    groups = ([sweep] if isinstance(sweep, dict) else list(sweep)) if sweep else [{}]
    configs, seen = [], set()
    for c in combinations(groups):  # every configuration must load (ModelError on a bad value); no repeats
        m = load_model(model_path, list(overrides) + value_overrides(c))
        key = tuple(sorted({**resolved(m, scene.name), **{k: v for k, v in c.items() if k not in SHOWN_KEYS}}.items()))
        if key not in seen:
            seen.add(key)
            configs.append(c)
    out_dir = Path(out_dir)
    runners = ["standalone"] + (["fmu"] if fmu else [])
    jobs = [(i, r) for i in _jobs_order(configs, model, scene.name) for r in runners]
    peer_cfgs = _peer_configurations(peer, peer_sweep)
    jobs += [(k, peer) for k in sorted(range(len(peer_cfgs)), key=lambda k: -_peer_cost(peer_cfgs[k], scene))]

    def task(i: int, r: str):
        """The run as data (studies/task.py): ours (standalone/FMU) or the peer's."""
        if r == peer:
            return make_task(model_path, overrides, scene.name, f"peer:{peer}", **peer_cfgs[i])
        return make_task(model_path, list(overrides) + value_overrides(configs[i]), scene.name, r, backend)

    def note_of(i: int, r: str) -> str:
        return peer_label(peer, peer_cfgs[i], scene) if r == peer else label({**resolved(model, scene.name), **configs[i]})
    sched = scheduler if isinstance(scheduler, Scheduler) else parse_scheduler(scheduler, workers)
    tasks = {job: task(*job) for job in jobs}
    ref_task = make_task(model_path, overrides, scene.name, "reference", elements=reference_elements,
                         step=reference_step)
    notes = {ref_task.key: "reference", **{t.key: f"{note_of(*job)} ({job[1]})" for job, t in tasks.items()}}
    t0 = time.perf_counter()
    outcome = sweep_into(out_dir, [ref_task, *tasks.values()], f"chart {model.body.name}/{scene.name}", notes,
                         SweepOptions(sched, fresh, progress))
    ref = outcome.results[ref_task.key]
    if not ref["completed"]:
        if ref.get("error_type") == "SetupError":  # a set-up error (mesh incompatible with the model)
            raise ChartError(ref["failure"].partition(": ")[2])
        ref = _failed_reference(ref["failure"], reference_elements, reference_step, scene)  # runs keep their costs
    else:
        ref["cached"] = ref_task.key in outcome.from_store  # not run by this chart
    results = {job: outcome.results[t.key] for job, t in tasks.items()}
    resolution = None
    if resolve is not None and ref["completed"]:
        from .resolve import resolve_reference

        resolution, refined = resolve_reference(model_path, scene.name, resolve, overrides=overrides,
                                                n_elements=reference_elements, step=reference_step, out_dir=out_dir,
                                                sweep=SweepOptions(sched, False, progress))
        if refined.get("completed"):
            ref = {**refined, "cached": False}

    metric_name = primary_metric(scene)
    extra_keys = list(dict.fromkeys(k for c in configs for k in c if k not in SHOWN_KEYS))
    rows, row_keys = [], []

    def measured(run: dict) -> dict:
        out = {"wall_time_s": run.get("wall_time_s"), "cpu_time_s": run.get("cpu_time_s"),
               "real_time_factor": None, "metric_name": metric_name or "", **errors(run, ref, metric_name),
               "metric_reference": ref["metrics"].get(metric_name) if metric_name else None,
               "completed": bool(run["completed"]), "failure": run["failure"] or "",
               "t_end_s": run.get("t_end_s"), "reference_suspect": bool(ref.get("warning")),
               "newton_iterations_mean": run.get("newton_iterations_mean"), "backend": run.get("backend"),
               "reference_resolved": None if resolution is None else resolution.resolved}
        if not out["completed"]:
            # the metric of a run that stopped early is not the scene's metric: no error against the
            # reference's (rms_error_rel stays: it compares the trajectory over the run's own span)
            out["metric_error_rel"] = None
        if out["wall_time_s"] and out["t_end_s"] is not None:
            out["real_time_factor"] = out["t_end_s"] / out["wall_time_s"]
        return out

    for i, c in enumerate(configs):
        for r in runners:
            run = results[(i, r)]
            vals = run.get("resolved") or {**resolved(model, scene.name), **c}
            rows.append({"label": label(vals, {k: c[k] for k in extra_keys if k in c}), "runner": r,
                         **{k: vals[k] for k in SHOWN_KEYS}, **{k: c.get(k) for k in extra_keys}, **measured(run)})
            row_keys.append((i, r))
    for k, c in enumerate(peer_cfgs):  # the peer: no superelements, modes or term set; its mesh instead
        rows.append({"label": note_of(k, peer), "runner": peer, **{key: None for key in SHOWN_KEYS},
                     "step": float(c.get("step") or scene.step), "elements": int(c["elements"]),
                     **measured(results[(k, peer)])})
        row_keys.append((k, peer))
    mark_pareto(rows, cost, bool(metric_name))

    csv_path, png_path, json_path = out_dir / "chart.csv", out_dir / "chart.png", out_dir / "chart.json"
    write_csv(csv_path, rows)
    meta = {
        "model": model_path, "scene": scene.name, "overrides": list(overrides), "sweep": groups,
        "metric": metric_name, "cost": cost, "backend": backend, "peer": peer, "peer_sweep": peer_sweep, "workers": sched.workers, "cpu_count": os.cpu_count(),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "chart_wall_time_s": time.perf_counter() - t0,
        "reference": {k: ref.get(k) for k in ("n_elements", "step", "wall_time_s", "cached", "failure",
                                              "energy_error", "warning")}
        | {"metrics": ref["metrics"]},
        "reference_resolution": None if resolution is None else resolution.as_dict(),
        "code_version": code_version(), "scheduler": outcome.where,
        "runs_stored": outcome.stored, "runs_ran": outcome.ran, "runs_retried": outcome.retried,
        "failures": {f"{rows[j]['label']} ({r})": results[(i, r)].get("traceback") or rows[j]["failure"]
                     for j, (i, r) in enumerate(row_keys) if not rows[j]["completed"]},
    }
    json_path.write_text(json.dumps(meta, indent=2, default=float) + "\n", encoding="utf-8")
    if plot:
        plot_chart(rows, png_path, title=f"{model.body.name} / {scene.name}: error against {'CPU' if cost == 'cpu' else 'wall'} time "
                   f"(reference: full-order beam, {ref['n_elements']} elements, h = {fmt_step(ref['step'])})"
                   + (f"\nREFERENCE SUSPECT: energy error {100 * ref['energy_error']:.2g} %" if ref.get("warning") else ""),
                   metric_name=metric_name, cost=cost)
    return {"rows": rows, "reference": ref, "csv": str(csv_path), "png": str(png_path), "json": str(json_path),
            "meta": meta, "tasks": [tasks[job] for job in row_keys]}


CSV_FIRST = ("label", "runner", *SHOWN_KEYS)
CSV_LAST = ("wall_time_s", "cpu_time_s", "real_time_factor", "metric_name", "metric", "metric_reference",
            "metric_error_rel", "rms_error_rel", "completed", "failure", "t_end_s", "pareto", "reference_suspect")


def _extra_columns(rows: list[dict]) -> list[str]:
    return list(dict.fromkeys(k for row in rows for k in row if k not in CSV_FIRST + CSV_LAST))


def write_csv(path, rows: list[dict]) -> None:
    """chart.csv: the CSV_FIRST columns, the swept and runner-specific ones, then CSV_LAST."""
    write_rows(path, rows, CSV_FIRST + tuple(_extra_columns(rows)) + CSV_LAST)


def mark_pareto(rows: list[dict], cost: str = "wall", primary: bool = True, same_error_rel: float = 0.0) -> None:
    """Set every row's "pareto": on its runner's Pareto front of error against cost (COSTS[cost]),
    the error being the primary metric's (the trajectory's, rms_error_rel, when `primary` is False;
    same_error_rel as pareto_front's). Rows that did not complete are never on it."""
    err_key = "metric_error_rel" if primary else "rms_error_rel"
    for r in dict.fromkeys(row["runner"] for row in rows):
        sel = [j for j, row in enumerate(rows) if row["runner"] == r and row["completed"]]
        front = {sel[k] for k in pareto_front([rows[j][COSTS[cost]] or math.nan for j in sel],
                                               [rows[j][err_key] if rows[j][err_key] is not None else math.nan
                                                for j in sel], same_error_rel)}
        for j, row in enumerate(rows):
            if row["runner"] == r:
                row["pareto"] = j in front


def read_csv(path) -> list[dict]:
    """chart.csv rows with numbers and booleans parsed (empty -> None)."""
    rows = read_rows(path, text=("label", "runner", "terms", "metric_name", "failure", "backend"))
    for r in rows:  # a float column whose values happen to be whole
        for k in ("step", "wall_time_s", "cpu_time_s", "metric", "metric_reference", "metric_error_rel",
                  "rms_error_rel", "t_end_s", "real_time_factor", "newton_iterations_mean"):
            if isinstance(r.get(k), int) and not isinstance(r[k], bool):
                r[k] = float(r[k])
    return rows


def replot(out_dir, cost: str | None = None, same_error_rel: float = 0.0) -> Path:
    """Redraw DIR/chart.png from DIR/chart.csv and DIR/chart.json (Pareto front recomputed for `cost`,
    same_error_rel as pareto_front's)."""
    out_dir = Path(out_dir)
    rows = read_csv(out_dir / "chart.csv")
    meta = json.loads((out_dir / "chart.json").read_text(encoding="utf-8"))
    cost = cost or meta.get("cost", "wall")
    mark_pareto(rows, cost, bool(meta.get("metric")), same_error_rel)
    ref = meta["reference"]
    png = out_dir / "chart.png"
    plot_chart(rows, png, title=f"{Path(meta['model']).stem} / {meta['scene']}: error against {'CPU' if cost == 'cpu' else 'wall'} time (reference: "
               f"full-order beam, {ref['n_elements']} elements, h = {fmt_step(ref['step'])})"
               + (f"\nREFERENCE SUSPECT: energy error {100 * ref['energy_error']:.2g} %" if ref.get("warning") else ""),
               metric_name=meta.get("metric"), cost=cost)
    return png


# ------------------------------------------------------------------------------ text output
def format_table(rows: list[dict]) -> str:
    """The chart rows as a fixed-width text table (the CLI prints it)."""
    head = f"{'configuration':<22} {'runner':<10} {'wall [s]':>9} {'cpu [s]':>8} {'RTF':>6} {'metric':>10} " \
           f"{'err metric':>10} {'err rms':>9}  front  status"
    lines = [head]
    for r in rows:
        f = lambda v, fmt: format(v, fmt) if v is not None else "-"  # noqa: E731
        lines.append(f"{r['label']:<22} {r['runner']:<10} {f(r['wall_time_s'], '9.2f')} {f(r['cpu_time_s'], '8.2f')} "
                     f"{f(r['real_time_factor'], '6.2f')} {f(r['metric'], '10.5f')} "
                     f"{f(r['metric_error_rel'], '10.2%')} {f(r['rms_error_rel'], '9.2%')}  "
                     f"{'*' if r.get('pareto') else ' ':^5}  {'ok' if r['completed'] else 'FAILED: ' + r['failure']}")
    return "\n".join(lines)
