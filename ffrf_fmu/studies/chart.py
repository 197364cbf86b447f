"""Accuracy against cost: sweep model configurations, measure each run's wall time and its error
against the full-order reference, chart error over wall time with the Pareto front.

    ffrf-fmu chart MODEL --scene NAME --sweep superelements=1,2,4 modes=2,4,6 [--sweep ...] \
        [--fmu] [--reference-elements N] [--reference-step H] [--workers K] [--cost wall|cpu] [-o DIR]

A configuration is one value for every swept key (cartesian product of the lists; keys are the
`--set` keys of model.py: superelements, modes, terms, step, elements, ...; several --sweep
groups run the union of their products); unswept keys keep the model's values (plus any --set
override). docs/accuracy.md explains the chart and shows the one of B1. Each configuration runs standalone
(simulate.run) and, with --fmu, also through its FMU under fmpy with communication step =
internal step (validate.run_fmu).

Errors, both against the reference (ffrf_fmu.reference: the full-order geometrically exact beam,
an independent code) run on the same scene:
- metric_error_rel = |m - m_ref| / |m_ref| of the scene's primary metric (PRIMARY_METRIC: B1
  `haug` scenes: the maximum transverse tip deflection; B2 `spherical` scenes: the mean hub
  Omega_y after the tip load);
- rms_error_rel = sqrt(mean_t |d(t) - d_ref(t)|^2) / max_t |d_ref(t)|, d the elastic tip
  displacement seen from the hub (eq. 92, simulate.elastic_tip), the reference interpolated
  (linearly) onto the configuration's time grid.
Both are computed with the same code for the configuration and the reference (simulate.metrics
on port histories), so they differ only through the models.

Cost: wall_time_s of the time stepping only (no reduction, no FMU build), measured inside the
worker process, with its CPU time (cpu_time_s). With K concurrent workers on fewer than K free
cores the wall times grow; the CPU time does not (the chart's x axis is wall time, as asked;
run with --workers 1 on a quiet machine for publishable wall times).

The reference run is cached in DIR as an npz keyed by model file contents, overrides, scene,
elements and step, so re-running a chart does not repeat it.
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import itertools
import json
import math
import os
import time
import traceback
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..model import Model, effective_ports, load_model
from .progress import Bar
from .sweep import Scheduler, connect, parse_scheduler, run_sweep
from .store import ResultStore
from .task import code_version, make_task

# scene.metrics -> the metric whose relative error the chart reports
PRIMARY_METRIC = {"haug": "tip_deflection_max_m", "spherical": "omega_y_mean_after_load"}
# the keys every row shows (resolved from the model when not swept), in label order
SHOWN_KEYS = ("superelements", "modes", "terms", "step")
COSTS = {"wall": "wall_time_s", "cpu": "cpu_time_s"}  # cost measure -> row column
ERROR_FLOOR = 1e-6  # errors below this are drawn at the floor of the log axis


class ChartError(ValueError):
    """A chart cannot be set up (bad sweep, reference mesh incompatible with the model)."""


# ------------------------------------------------------------------------------ configurations
def parse_sweep(items: Sequence[str], option: str = "--sweep") -> dict[str, list[str]]:
    """["superelements=1,2,4", "terms=linear,gyroscopic"] -> {key: [value texts]} (order kept);
    errors name `option` (the command line option the items came from)."""
    sweep: dict[str, list[str]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        key = key.strip()
        vals = [v.strip() for v in values.split(",") if v.strip()]
        if not sep or not key or not vals:
            raise ChartError(f"{option} {item!r}: expected key=v1,v2,... e.g. superelements=1,2,4")
        if key in sweep:
            raise ChartError(f"{option} {item!r}: key {key!r} given twice")
        sweep[key] = vals
    return sweep


def configurations(sweep) -> list[dict[str, str]]:
    """Cartesian product of the swept lists, as {key: value text} dicts. `sweep` is one
    {key: [values]} dict or a list of them (the union of their products, in order)."""
    groups = [sweep] if isinstance(sweep, dict) else list(sweep)
    out = []
    for g in groups:
        keys = list(g)
        out += [dict(zip(keys, combo)) for combo in itertools.product(*(g[k] for k in keys))]
    return out


def config_overrides(values: dict[str, str]) -> list[str]:
    return [f"{k}={v}" for k, v in values.items()]


def resolved(model: Model, scene_name: str | None) -> dict[str, Any]:
    """The shown keys' values of a loaded model and scene."""
    sc = model.scene(scene_name)
    return {"superelements": model.body.superelements, "modes": model.body.modes, "terms": sc.terms,
            "step": sc.step}


def _fmt_step(h: float) -> str:
    ms = 1e3 * h
    return f"{ms:g}ms" if ms >= 0.1 else f"{h:g}s"


def label(values: dict[str, Any], extra: dict[str, Any] | None = None) -> str:
    """Short configuration label, e.g. 4SE/6m/lin/2ms (+ other swept keys as key=value)."""
    terms = {"linear": "lin", "gyroscopic": "gyr"}.get(str(values["terms"]), str(values["terms"]))
    text = f"{values['superelements']}SE/{values['modes']}m/{terms}/{_fmt_step(float(values['step']))}"
    for k, v in (extra or {}).items():
        text += f"/{k}={v}"
    return text


# ------------------------------------------------------------------------------ runs
def _body_data(model: Model, scene):
    from ..reduction import build_body, reduction_options

    return build_body(dataclasses.replace(model.body, ports=effective_ports(model, scene)), **reduction_options(scene))[0]


def _trajectory(result) -> np.ndarray:
    from ..simulate import elastic_tip, end_ports

    hub, tip = end_ports(result.body)
    return elastic_tip(result, hub, tip)


def run_configuration(model_path: str, scene_name: str | None, base_overrides: Sequence[str],
                      values: dict[str, str], runner: str = "standalone", backend: str = "numpy") -> dict:
    """Run one configuration (in a worker process). Returns a picklable dict: shown values,
    times and the elastic tip trajectory, metrics, wall and CPU time, completion."""
    from .. import simulate as sim

    out: dict[str, Any] = {"values": dict(values), "runner": runner, "completed": False, "failure": None}
    try:
        model = load_model(model_path, list(base_overrides) + config_overrides(values))
        sc = model.scene(scene_name)
        out["resolved"] = resolved(model, scene_name)
        body = _body_data(model, sc)
        if runner == "standalone":
            c0 = time.process_time()
            res = sim.run(body, sc, origin=model.body.origin, progress=False, backend=backend)
            out["cpu_time_s"] = time.process_time() - c0
            s = res.summary
            out |= {"wall_time_s": s["wall_time_s"], "completed": bool(s["completed"]), "failure": s["failure"],
                    "t_end_s": s["t_end"], "newton_iterations_mean": s["newton_iterations_mean"],
                    "backend": s.get("backend")}  # the one that ran (numba falls back to numpy with a note)
        elif runner == "fmu":
            res, wall, cpu = _run_fmu(model_path, model, sc, list(base_overrides) + config_overrides(values), body,
                                      backend)
            reached = abs(res.t[-1] - sc.duration) <= 1e-9 * max(1.0, sc.duration)
            out |= {"wall_time_s": wall, "cpu_time_s": cpu, "completed": bool(reached),
                    "failure": None if reached else f"FMU stopped at t = {res.t[-1]:.6g} s (fmi2Discard/Error)",
                    "t_end_s": float(res.t[-1])}
        else:
            raise ChartError(f"unknown runner {runner!r}")
        out["metrics"] = sim.metrics(res, sc)
        out["t"] = np.asarray(res.t)
        out["d"] = _trajectory(res)
    except Exception as e:  # noqa: BLE001 - a configuration that cannot run is a chart row, not a crash
        out["failure"] = f"{type(e).__name__}: {e}"
        out["traceback"] = traceback.format_exc(limit=4)
    return out


def _run_fmu(model_path, model, sc, overrides, body, backend="numpy"):
    """Build the configuration's FMU (into a temporary directory) and run it under fmpy with
    communication step = internal step; (SimulationResult, wall time, CPU time)."""
    import tempfile

    from fmpy import read_model_description

    from ..fmu.builder import build_from_model
    from ..simulate import SimulationResult, scene_inputs
    from ..validate import fmu_input_table, run_fmu

    with tempfile.TemporaryDirectory(prefix="ffrf_chart_fmu_") as tmp:
        fmu = build_from_model(model_path, Path(tmp) / f"{model.body.name}.fmu", scene=sc.name, overrides=overrides,
                               backend=backend)
        md = read_model_description(str(fmu))
        names = [v.name for v in md.modelVariables if v.causality in ("input", "output")]
        inputs = scene_inputs(body, sc)
        c0 = time.process_time()
        res, wall, _ = run_fmu(fmu, sc, inputs, sc.step, record_names=names)
        cpu = time.process_time() - c0
        t = np.asarray(res["time"], dtype=float)
        keep = np.concatenate([np.diff(t) > 0, [True]])  # fmpy repeats the last sample after a discard
        t = t[keep]
        cols = {n: np.asarray(res[n], dtype=float)[keep] for n in res.dtype.names if n != "time"}
        exact = fmu_input_table(fmu, inputs, t)  # inputs as the signal gives them at the recorded times
        for n in exact.dtype.names[1:]:
            cols[n] = np.asarray(exact[n], dtype=float)
    return SimulationResult(t, cols, {}, body), wall, cpu


# ------------------------------------------------------------------------------ reference
def reference_key(model_path, scene_name: str, base_overrides: Sequence[str], n_elements: int, step: float) -> str:
    """Cache key of a reference run: the model file's bytes, the overrides, scene, elements, step and
    the reference's own source files (a change of the reference code invalidates the cache)."""
    h = hashlib.sha256(Path(model_path).read_bytes())
    h.update(json.dumps([scene_name, list(base_overrides), int(n_elements), float(step)]).encode())
    for f in sorted((Path(__file__).resolve().parents[1] / "reference").glob("*.py")):
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def reference_path(cache_dir, model: Model, scene_name: str, key: str, n_elements: int, step: float) -> Path:
    return Path(cache_dir) / f"reference_{model.body.name}_{scene_name}_{n_elements}el_{_fmt_step(step)}_{key}.npz"


def run_reference(model_path: str, scene_name: str | None, base_overrides: Sequence[str], n_elements: int | None,
                  step: float | None, cache_dir=None) -> dict:
    """The reference run of the scene (full-order beam), from the cache in cache_dir when there.

    Returns {"t", "d" (eq. 92 tip trajectory), "metrics", "wall_time_s", "n_elements", "step",
    "cached", "path"}. The mesh must place the body's ports on nodes: n_elements a multiple of
    the model's superelements (default: max(16, 4 * superelements), the reference's own default).
    """
    from ..reference import simulate_reference
    from ..simulate import SimulationResult, metrics, variable_names

    model = load_model(model_path, base_overrides)
    sc = model.scene(scene_name)
    n_se = model.body.superelements
    n_el = int(n_elements) if n_elements else max(16, 4 * n_se)
    if n_el % n_se:
        raise ChartError(f"--reference-elements {n_el}: must be a multiple of the model's {n_se} superelements "
                         "(the ports sit on superelement boundary nodes)")
    h = float(step) if step else sc.step
    key = reference_key(model_path, sc.name, base_overrides, n_el, h)
    path = reference_path(cache_dir, model, sc.name, key, n_el, h) if cache_dir else None
    body = _body_data(model, sc)
    ports = [p.name for p in body.ports]
    if path is not None and path.exists():
        z = np.load(path, allow_pickle=False)
        t, cols, wall, cached = z["t"], {n: z[f"col:{n}"] for n in json.loads(str(z["names"]))}, float(z["wall"]), True
        energy_error = float(z["energy_error"])
    else:
        ref_body = dataclasses.replace(model.body, ports=effective_ports(model, sc))
        with warnings.catch_warnings():  # the energy warning is returned (below): in a worker it would be lost
            warnings.filterwarnings("ignore", message="reference: energy error", category=RuntimeWarning)
            res = simulate_reference(ref_body, sc, n_elements=n_el, step=h)
        t, wall, cached = np.asarray(res.t), float(res.wall_time_s), False
        energy_error = float(res.info["energy_error"])
        cols = {}
        for p in ports:
            names = iter(variable_names(p))
            for fld in ("r", "R", "v", "w", "f", "t"):
                arr = np.asarray(res.ports[p][fld]).reshape(len(t), -1)
                for j in range(arr.shape[1]):
                    cols[next(names)] = arr[:, j]
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp.npz")
            np.savez_compressed(tmp, t=t, wall=wall, energy_error=energy_error, names=json.dumps(list(cols)),
                                **{f"col:{n}": v for n, v in cols.items()})
            os.replace(tmp, path)
    result = SimulationResult(t, cols, {}, body)
    return {"t": t, "d": _trajectory(result), "metrics": metrics(result, sc), "wall_time_s": wall,
            "n_elements": n_el, "step": h, "cached": cached, "path": str(path) if path else None,
            "energy_error": energy_error, "warning": reference_warning(energy_error, h)}


def reference_warning(energy_error: float | None, step: float) -> str:
    """The reference solver's energy warning (reference/solver.py), or "" when the run is trusted."""
    from ..reference.solver import ENERGY_ERROR_SUSPECT

    if energy_error is None or energy_error <= ENERGY_ERROR_SUSPECT:
        return ""
    return (f"reference suspect: energy error {100 * energy_error:.2g} % of the energy level > "
            f"{100 * ENERGY_ERROR_SUSPECT:g} % (h = {step:g} s): its step is probably too large, errors against it "
            "are not trustworthy; halve --reference-step and compare")


def _failed_reference(failure: str, n_elements, step, scene) -> dict:
    return {"metrics": {}, "failure": failure, "wall_time_s": None,
            "n_elements": n_elements, "step": step or scene.step, "cached": False, "path": None,
            "energy_error": None, "warning": ""}


# ------------------------------------------------------------------------------ errors, front
def errors(run: dict, ref: dict, metric_name: str | None) -> dict:
    """metric, metric_error_rel and rms_error_rel of one run against the reference (module doc)."""
    out = {"metric": None, "metric_error_rel": None, "rms_error_rel": None}
    if "d" not in run:
        return out
    if metric_name and metric_name in run.get("metrics", {}):
        out["metric"] = m = float(run["metrics"][metric_name])
        if metric_name in ref.get("metrics", {}):
            m_ref = ref["metrics"][metric_name]
            out["metric_error_rel"] = float(abs(m - m_ref) / abs(m_ref)) if m_ref else float(abs(m))
    if "d" not in ref:  # the reference failed: no errors to measure
        return out
    t, d = run["t"], run["d"]
    inside = t <= ref["t"][-1] * (1 + 1e-12)
    t, d = t[inside], d[inside]
    if len(t):
        dr = np.column_stack([np.interp(t, ref["t"], ref["d"][:, i]) for i in range(3)])
        scale = float(np.max(np.linalg.norm(ref["d"], axis=1)))
        rms = float(np.sqrt(np.mean(np.sum((d - dr) ** 2, axis=1))))
        out["rms_error_rel"] = rms / scale if scale > 0 else rms
    return out


def pareto_front(cost: Sequence[float], error: Sequence[float]) -> list[int]:
    """Indices of the non-dominated points (no other point is both cheaper and more accurate),
    ordered by cost. NaN entries never belong to the front."""
    idx = [i for i in range(len(cost)) if np.isfinite(cost[i]) and np.isfinite(error[i])]
    idx.sort(key=lambda i: (cost[i], error[i]))
    front, best = [], math.inf
    for i in idx:
        if error[i] < best:
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
# the peer's default sweep (issue 10: Exudyn's 3D beam over these meshes and steps)
PEER_SWEEP = {"elements": ["2", "3", "4", "6", "8", "16"], "step": ["0.002", "0.005", "0.01", "0.02", "0.04"]}
PEER_NAMES = {"exudyn": "Exudyn"}


def _peer_configurations(peer: str | None, sweep) -> list[dict[str, str]]:
    if not peer:
        return []
    from ..peers import available

    ok, why = available(peer)
    if not ok:
        raise ChartError(f"--peer {peer}: {why}")
    configs = configurations(sweep or PEER_SWEEP)
    bad = [c for c in configs if set(c) - {"elements", "step"} or "elements" not in c]
    if bad:
        raise ChartError(f"--peer-sweep: the peer takes elements=... [step=...] only, got {bad[0]}")
    return configs


def _peer_cost(values: dict, scene) -> float:
    return int(values["elements"]) / float(values.get("step") or scene.step)


def peer_label(peer: str, values: dict, scene) -> str:
    """e.g. Exudyn 16el/2ms"""
    return f"{PEER_NAMES.get(peer, peer)} {int(values['elements'])}el/{_fmt_step(float(values.get('step') or scene.step))}"


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
          peer_sweep=None, backend: str = "numpy", scheduler=None, fresh: bool = False) -> dict:
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

    Returns {"rows": [...], "reference": {...}, "csv", "png", "json"}.
    """
    model_path = str(model_path)
    if cost not in COSTS:
        raise ChartError(f"cost must be one of {', '.join(COSTS)}, got {cost!r}")
    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    groups = ([sweep] if isinstance(sweep, dict) else list(sweep)) if sweep else [{}]
    configs, seen = [], set()
    for c in configurations(groups):  # every configuration must load (ModelError on a bad value); no repeats
        m = load_model(model_path, list(overrides) + config_overrides(c))
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
        return make_task(model_path, list(overrides) + config_overrides(configs[i]), scene.name, r, backend)

    def note_of(i: int, r: str) -> str:
        return peer_label(peer, peer_cfgs[i], scene) if r == peer else label({**resolved(model, scene.name), **configs[i]})
    sched = scheduler if isinstance(scheduler, Scheduler) else parse_scheduler(scheduler, workers)
    tasks = {job: task(*job) for job in jobs}
    ref_task = make_task(model_path, overrides, scene.name, "reference", elements=reference_elements,
                         step=reference_step, cache_dir=str(out_dir.resolve()) if sched.kind == "pool" else None)
    notes = {ref_task.key: "reference", **{t.key: f"{note_of(*job)} ({job[1]})" for job, t in tasks.items()}}
    bar = Bar(len(notes), f"chart {model.body.name}/{scene.name}") if progress else None
    t0 = time.perf_counter()
    done, stored = 0, set()

    def on_result(t, result, from_store) -> None:
        nonlocal done
        done += 1
        if from_store:
            stored.add(t.key)
        if bar:
            bar.update(done, notes[t.key] + (" (stored)" if from_store else ""))
    with connect(sched) as runner:  # an unreachable scheduler fails here, before DIR is written
        out_dir.mkdir(parents=True, exist_ok=True)
        store = ResultStore(out_dir)  # DIR/runs.jsonl: a line per finished run; a rerun skips them
        if fresh:
            store.discard()
        outcome = run_sweep([ref_task, *tasks.values()], runner, store=store, on_result=on_result)
    if bar:
        bar.close()
    ref = outcome.results[ref_task.key]
    if not ref["completed"]:
        if ref.get("error_type") == "ChartError":  # a set-up error (mesh incompatible with the model)
            raise ChartError(ref["failure"].partition(": ")[2])
        ref = _failed_reference(ref["failure"], reference_elements, reference_step, scene)  # runs keep their costs
    elif ref_task.key in stored:
        ref["cached"] = True
    results = {job: outcome.results[t.key] for job, t in tasks.items()}

    metric_name = PRIMARY_METRIC.get(scene.metrics)
    extra_keys = list(dict.fromkeys(k for c in configs for k in c if k not in SHOWN_KEYS))
    rows, row_keys = [], []

    def measured(run: dict) -> dict:
        out = {"wall_time_s": run.get("wall_time_s"), "cpu_time_s": run.get("cpu_time_s"),
               "real_time_factor": None, "metric_name": metric_name or "", **errors(run, ref, metric_name),
               "metric_reference": ref["metrics"].get(metric_name) if metric_name else None,
               "completed": bool(run["completed"]), "failure": run["failure"] or "",
               "t_end_s": run.get("t_end_s"), "reference_suspect": bool(ref.get("warning")),
               "newton_iterations_mean": run.get("newton_iterations_mean"), "backend": run.get("backend")}
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
    # Pareto front per runner, on the primary metric error (the trajectory error without one)
    err_key = "metric_error_rel" if metric_name else "rms_error_rel"
    for r in runners + ([peer] if peer_cfgs else []):
        sel = [j for j, row in enumerate(rows) if row["runner"] == r and row["completed"]]
        c = [rows[j][COSTS[cost]] or math.nan for j in sel]
        err = [rows[j][err_key] if rows[j][err_key] is not None else math.nan for j in sel]
        front = {sel[k] for k in pareto_front(c, err)}
        for j in sel:
            rows[j]["pareto"] = j in front
    for row in rows:
        row.setdefault("pareto", False)

    csv_path, png_path, json_path = out_dir / "chart.csv", out_dir / "chart.png", out_dir / "chart.json"
    write_csv(rows, csv_path)
    meta = {
        "model": model_path, "scene": scene.name, "overrides": list(overrides), "sweep": groups,
        "metric": metric_name, "cost": cost, "backend": backend, "peer": peer, "peer_sweep": peer_sweep, "workers": sched.workers, "cpu_count": os.cpu_count(),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "chart_wall_time_s": time.perf_counter() - t0,
        "reference": {k: ref.get(k) for k in ("n_elements", "step", "wall_time_s", "cached", "path", "failure",
                                              "energy_error", "warning")}
        | {"metrics": ref["metrics"]},
        "code_version": code_version(), "scheduler": runner.description,
        "runs_stored": outcome.stored, "runs_ran": outcome.ran, "runs_retried": outcome.retried,
        "failures": {f"{rows[j]['label']} ({r})": results[(i, r)].get("traceback") or rows[j]["failure"]
                     for j, (i, r) in enumerate(row_keys) if not rows[j]["completed"]},
    }
    json_path.write_text(json.dumps(meta, indent=2, default=float) + "\n", encoding="utf-8")
    if plot:
        plot_chart(rows, png_path, title=f"{model.body.name} / {scene.name}: error against {'CPU' if cost == 'cpu' else 'wall'} time "
                   f"(reference: full-order beam, {ref['n_elements']} elements, h = {_fmt_step(ref['step'])})"
                   + (f"\nREFERENCE SUSPECT: energy error {100 * ref['energy_error']:.2g} %" if ref.get("warning") else ""),
                   metric_name=metric_name, cost=cost)
    return {"rows": rows, "reference": ref, "csv": str(csv_path), "png": str(png_path), "json": str(json_path),
            "meta": meta}


CSV_FIRST = ("label", "runner", *SHOWN_KEYS)
CSV_LAST = ("wall_time_s", "cpu_time_s", "real_time_factor", "metric_name", "metric", "metric_reference",
            "metric_error_rel", "rms_error_rel", "completed", "failure", "t_end_s", "pareto", "reference_suspect")


def write_csv(rows: list[dict], path) -> None:
    extra = list(dict.fromkeys(k for row in rows for k in row if k not in CSV_FIRST + CSV_LAST))
    fields = list(CSV_FIRST) + extra + list(CSV_LAST)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for row in rows:
            w.writerow({k: _csv_value(row.get(k)) for k in fields})


def _csv_value(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return v


def read_csv(path) -> list[dict]:
    """chart.csv rows with numbers and booleans parsed (empty -> None)."""
    ints, floats = {"superelements", "modes", "elements"}, {"step", "wall_time_s", "cpu_time_s", "real_time_factor", "metric",
                                                "metric_reference", "metric_error_rel", "rms_error_rel", "t_end_s",
                                                "newton_iterations_mean"}
    rows = []
    with open(path, newline="", encoding="utf-8") as fh:
        for raw in csv.DictReader(fh):
            row: dict[str, Any] = {}
            for k, v in raw.items():
                if v == "":
                    row[k] = None
                elif k in ints:
                    row[k] = int(v)
                elif k in floats:
                    row[k] = float(v)
                elif k in ("completed", "pareto", "reference_suspect"):
                    row[k] = v == "True"
                else:
                    row[k] = v
            rows.append(row)
    return rows


# ------------------------------------------------------------------------------ plot
def _place_labels(ax, xs, ys, texts, fontsize=7):
    """Put each label near its point where it overlaps the fewest labels and points placed so far
    (greedy over 12 directions at 3 distances, display coordinates); labels set off by more than a
    few pixels get a thin leader line to their point."""
    fig = ax.figure
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    pts = ax.transData.transform(np.column_stack([xs, ys])) if len(xs) else np.zeros((0, 2))
    axbb = ax.get_window_extent(renderer)
    placed = []
    cands = [(0.0, 5.0)]
    for r, n in ((7.0, 12), (20.0, 12), (35.0, 16), (55.0, 16), (80.0, 16), (110.0, 16)):
        for k in range(n):
            a = 2 * math.pi * (k + 0.5 * (r > 30)) / n
            cands.append((r * math.cos(a), r * math.sin(a)))
    # crowded points first: they have the fewest good places
    crowd = [sum(np.hypot(*(pts[j] - pts[i])) < 30 for j in range(len(pts))) for i in range(len(pts))]
    for i in sorted(range(len(pts)), key=lambda i: -crowd[i]):
        x, y, text = xs[i], ys[i], texts[i]
        best = None
        for dx, dy in cands:
            ha = "left" if dx > 2 else "right" if dx < -2 else "center"
            va = "bottom" if dy > 2 else "top" if dy < -2 else "center"
            a = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset pixels", fontsize=fontsize, ha=ha,
                            va=va, color="0.15", zorder=5)
            bb = a.get_window_extent(renderer)
            score = sum(_overlap(bb, o) for o in placed)
            # never hide a point, and sit closer to the own point than to any other
            own = _distance(bb, pts[i])
            score += sum(5000.0 if _distance(bb, q) < 3 or _distance(bb, q) < own + 8 else 0.0
                         for j, q in enumerate(pts) if j != i)
            if bb.x0 < axbb.x0 or bb.x1 > axbb.x1 or bb.y0 < axbb.y0 or bb.y1 > axbb.y1:
                score += 1e5
            score += 2.0 * math.hypot(dx, dy)  # near its point, unless crowded
            if best is None or score < best[0]:
                if best is not None:
                    best[1].remove()
                best = (score, a, bb, dx, dy)
            else:
                a.remove()
        _, a, bb, dx, dy = best
        if math.hypot(dx, dy) > 10:
            a.remove()
            ha, va = a.get_ha(), a.get_va()
            a = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset pixels", fontsize=fontsize, ha=ha,
                            va=va, color="0.15", zorder=5,
                            arrowprops=dict(arrowstyle="-", lw=0.5, color="0.55", shrinkA=0, shrinkB=3))
        placed.append(bb)


def _distance(bb, p) -> float:
    """Distance from a point to a box (0 inside)."""
    dx = max(bb.x0 - p[0], 0.0, p[0] - bb.x1)
    dy = max(bb.y0 - p[1], 0.0, p[1] - bb.y1)
    return math.hypot(dx, dy)


def _overlap(a, b) -> float:
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w * h if w > 0 and h > 0 else 0.0


def plot_chart(rows: list[dict], path, title: str = "", metric_name: str | None = None,
               tolerances: Sequence[float] = (0.01, 0.05), cost: str = "wall") -> None:
    """Error (log) against wall (or CPU) time (log): one panel per error measure; colour = number of
    superelements, marker = term set, hollow = through the FMU; the Pareto front (of the primary
    error) connected by a black line and ringed; every point labelled; failed runs in a strip above
    each panel at the time they took until they failed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter

    panels = ([("metric_error_rel", f"relative error of {metric_name}")] if metric_name else []) + [
        ("rms_error_rel", "RMS error of the elastic tip trajectory (eq. 92) / max |d_ref|")]
    # panels stacked: the full page width for the (log) time axis, where the cheap runs crowd
    fig = plt.figure(figsize=(17.0, 8.0 * len(panels)))
    gs = fig.add_gridspec(2 * len(panels), 1, height_ratios=[1, 12] * len(panels), hspace=0.06, top=0.95,
                          bottom=0.05)
    ck = COSTS[cost]
    ok = [r for r in rows if r["completed"] and r[ck]]
    bad = [r for r in rows if not r["completed"]]
    times = [r[ck] for r in rows if r[ck]]
    xlim = (min(times) / 1.8, max(times) * 1.8) if times else (0.1, 10)
    front_key = "metric_error_rel" if metric_name else "rms_error_rel"
    counts = sorted({int(r["superelements"]) for r in rows if r["runner"] not in PEER_NAMES})
    peer_style = dict(marker="D", color="C3")  # a peer's runs: red diamonds, its front dash-dotted
    cmap = plt.get_cmap("viridis")
    colour = {n: cmap(0.9 * k / max(len(counts) - 1, 1)) for k, n in enumerate(counts)}
    shape = {"linear": "o", "gyroscopic": "^"}
    for p, (key, name) in enumerate(panels):
        ax = fig.add_subplot(gs[2 * p + 1, 0])
        top = fig.add_subplot(gs[2 * p, 0], sharex=ax)
        pts = [r for r in ok if r[key] is not None]
        x = np.array([r[ck] for r in pts])
        y = np.maximum([r[key] for r in pts], ERROR_FLOOR) if pts else np.zeros(0)
        for r, xi, yi in zip(pts, x, y):
            if r["runner"] in PEER_NAMES:
                ax.scatter([xi], [yi], s=30, marker=peer_style["marker"], facecolors=peer_style["color"], zorder=3)
                continue
            c = colour[int(r["superelements"])]
            hollow = r["runner"] == "fmu"
            ax.scatter([xi], [yi], s=34, marker=shape.get(r["terms"], "s"), facecolors="none" if hollow else [c],
                       edgecolors=[c], lw=1.4 if hollow else 0.5, zorder=3)
        for runner, ls in (("standalone", "-"), ("fmu", "--"), *((p, "-.") for p in PEER_NAMES)):
            on = [(r[ck], max(r[key], ERROR_FLOOR)) for r in pts if r["runner"] == runner and r.get("pareto")]
            if on:
                fx, fy = zip(*sorted(on))
                fc = peer_style["color"] if runner in PEER_NAMES else "k"
                ax.plot(fx, fy, ls, color=fc, lw=1.2, alpha=0.8, zorder=2)
                ax.scatter(fx, fy, s=120, facecolors="none", edgecolors=fc, lw=1.0, zorder=4)
        for tol in tolerances:
            ax.axhline(tol, color="0.5", lw=0.8, ls=":", zorder=1)
            ax.text(xlim[1] / 1.05, tol * 1.06, f"{tol:.0%}", color="0.4", fontsize=8, va="bottom", ha="right")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(*xlim)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if f"{v:g}"[0] in "25" else ""))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{100 * v:g}%"))
        if len(y):
            lo, hi = min(y.min(), min(tolerances)), max(y.max(), max(tolerances))
            ax.set_ylim(lo / 2.5, hi * 2.5)
        ax.set_xlabel(("wall" if cost == "wall" else "CPU") + " time of the run [s] (time stepping only)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.25)
        handles = [Line2D([], [], ls="", marker="o", color=colour[n], label=f"{n} SE") for n in counts]
        handles += [Line2D([], [], ls="", marker=m, color="0.4", label=t) for t, m in shape.items()
                    if any(r["terms"] == t for r in rows)]
        if any(r["runner"] == "fmu" for r in rows):
            handles.append(Line2D([], [], ls="", marker="o", mfc="none", color="0.4", label="through the FMU"))
        handles.append(Line2D([], [], color="k", marker="o", mfc="none", ms=10,
                              label="Pareto front" + (" (of the upper panel)" if key != front_key else "")))
        handles += [Line2D([], [], ls="-.", color=peer_style["color"], marker=peer_style["marker"],
                           label=f"{PEER_NAMES[p]} (full-order 3D beam) and its front")
                    for p in PEER_NAMES if any(r["runner"] == p for r in rows)]
        ax.legend(handles=handles, loc="lower left", fontsize=8, ncol=2)
        _place_labels(ax, list(x), list(y), [r["label"] + (" FMU" if r["runner"] == "fmu" else "") for r in pts])
        # failed runs: a strip above the panel, at the time they took until they failed
        top.set_yticks([])
        top.set_ylim(0, 1)
        top.tick_params(axis="x", which="both", labelbottom=False)
        top.set_ylabel("failed", rotation=0, ha="right", va="center", fontsize=8, color="C3")
        for k, r in enumerate(bad):
            xb = r[ck] or xlim[0] * 1.2
            top.plot([xb], [0.5], "x", color="C3", ms=7, mew=2)
            where = f" (stopped at t = {r['t_end_s']:.3g} s)" if r.get("t_end_s") is not None else ""
            top.annotate(r["label"] + (" FMU" if r["runner"] == "fmu" else "") + where, (xb, 0.5),
                         xytext=(6, 3 if k % 2 == 0 else -9), textcoords="offset points", fontsize=7, color="C3")
        if not bad:
            top.text(0.5, 0.5, "no failed runs", transform=top.transAxes, ha="center", va="center", fontsize=8,
                     color="0.5")
    fig.suptitle(title, fontsize=11, y=0.97)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def replot(out_dir, cost: str | None = None) -> Path:
    """Redraw DIR/chart.png from DIR/chart.csv and DIR/chart.json (Pareto front recomputed for `cost`)."""
    out_dir = Path(out_dir)
    rows = read_csv(out_dir / "chart.csv")
    meta = json.loads((out_dir / "chart.json").read_text(encoding="utf-8"))
    cost = cost or meta.get("cost", "wall")
    err_key = "metric_error_rel" if meta.get("metric") else "rms_error_rel"
    for r in {row["runner"] for row in rows}:
        sel = [j for j, row in enumerate(rows) if row["runner"] == r and row["completed"]]
        front = {sel[k] for k in pareto_front([rows[j][COSTS[cost]] or math.nan for j in sel],
                                               [rows[j][err_key] if rows[j][err_key] is not None else math.nan
                                                for j in sel])}
        for j, row in enumerate(rows):
            if row["runner"] == r:
                row["pareto"] = j in front
    ref = meta["reference"]
    png = out_dir / "chart.png"
    plot_chart(rows, png, title=f"{Path(meta['model']).stem} / {meta['scene']}: error against {'CPU' if cost == 'cpu' else 'wall'} time (reference: "
               f"full-order beam, {ref['n_elements']} elements, h = {_fmt_step(ref['step'])})"
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


def format_markdown(rows: list[dict]) -> str:
    """The chart rows as a markdown table (docs/accuracy.md)."""
    f = lambda v, fmt: format(v, fmt) if v is not None else "–"  # noqa: E731
    out = ["| configuration | runner | wall [s] | CPU [s] | real-time factor | metric | metric error | RMS error "
           "| front | status |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        status = "ok" if r["completed"] else f"failed at t = {f(r.get('t_end_s'), '.3g')} s"
        out.append(f"| {r['label']} | {r['runner']} | {f(r['wall_time_s'], '.2f')} | {f(r['cpu_time_s'], '.2f')} | "
                   f"{f(r['real_time_factor'], '.2f')} | {f(r['metric'], '.5f')} | {f(r['metric_error_rel'], '.2%')} | "
                   f"{f(r['rms_error_rel'], '.2%')} | {'*' if r.get('pareto') else ''} | {status} |")
    return "\n".join(out)
