"""`advise --check`: an advice run against a reference that proves itself (resolve.py), with the
achieved errors and cost, and its report; apart from the rules that make the advice (advise.py)."""
from __future__ import annotations

import math
from typing import Any, Sequence

from ..model import load_model
from .advise import Advice
from .errors import primary_metric
from .task import make_task


def check(model_path, scene_name: str | None, advice: Advice, *, overrides: Sequence[str] = (),
          reference_elements: int | None = None, reference_step: float | None = None, out_dir="chart",
          chart_csv=None, scheduler=None, fresh: bool = False, backend: str | None = None,
          progress: bool = False, refine: bool = True) -> dict:
    """Run the advised configuration (standalone, or through its FMU when advice.indicators["runner"]
    says so) and the reference (reference_elements, reference_step: default the scene's [reference]) as
    tasks of the sweep layer (sweep.py; scheduler as chart's), results in out_dir's store (a chart's
    directory holds the same reference run: it is not repeated); the achieved errors and cost. With
    refine (default), the reference proves itself first (resolve.py): refined in mesh and step until the
    primary metric moves by less than a tenth of the tolerance; an unresolved reference gives
    within_tolerance None (no verdict) and its refinement table. With chart_csv, compare with the
    cheapest chart configuration that meets the tolerance. backend: the advice's own unless given."""
    from .chart import errors, read_csv
    from .grid import value_overrides
    from .resolve import resolve_reference
    from .sweep import Scheduler, SweepOptions, sweep_into

    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    values = {"superelements": str(advice.superelements), "modes": str(advice.modes), "terms": advice.terms,
              "step": f"{advice.step:g}", "stiffening": "true" if advice.stiffening else "false"}
    runner = advice.indicators.get("runner", "standalone")
    backend = backend or advice.backend
    run_task = make_task(model_path, [*overrides, *value_overrides(values)], scene.name, runner, backend)
    sweep = SweepOptions(scheduler or Scheduler(), fresh, progress)
    resolution = None
    if refine:
        from .store import ResultStore

        before = None if fresh else ResultStore(out_dir)  # what the store had: the reference cached or not
        resolution, ref = resolve_reference(model_path, scene.name, advice.tolerance, overrides=overrides,
                                            n_elements=reference_elements, step=reference_step, out_dir=out_dir,
                                            sweep=sweep)
        ref_key = make_task(model_path, overrides, scene.name, "reference", elements=resolution.n_elements,
                            step=resolution.step).key
        cached = before is not None and before.finished(ref_key)
        sweep = SweepOptions(sweep.scheduler, False, progress)  # the store now holds the references
        outcome = sweep_into(out_dir, [run_task], f"advise --check {model.body.name}/{scene.name}",
                             {run_task.key: advice.label}, sweep)
        run = outcome.results[run_task.key]
    else:
        ref_task = make_task(model_path, overrides, scene.name, "reference", elements=reference_elements,
                             step=reference_step)
        outcome = sweep_into(out_dir, [ref_task, run_task], f"advise --check {model.body.name}/{scene.name}",
                             {ref_task.key: "reference", run_task.key: advice.label}, sweep)
        results, cached = outcome.results, ref_task.key in outcome.from_store
        ref, run = results[ref_task.key], results[run_task.key]
    if not ref or not ref.get("completed"):
        raise RuntimeError(f"the reference run failed: {ref.get('failure') if ref else 'not run'}")
    metric = primary_metric(scene)
    err = errors(run, ref, metric)
    out = {"label": advice.label, "runner": runner, "completed": run["completed"], "failure": run["failure"],
           "wall_time_s": run.get("wall_time_s"), "cpu_time_s": run.get("cpu_time_s"), "metric_name": metric,
           **err, "metric_reference": ref["metrics"].get(metric) if metric else None,
           "reference": {**{k: ref[k] for k in ("n_elements", "step", "wall_time_s")}, "cached": cached},
           "reference_resolution": resolution.as_dict() if resolution is not None else None}
    key = "metric_error_rel" if metric else "rms_error_rel"
    within = bool(run["completed"] and err[key] is not None and err[key] <= advice.tolerance)
    out["within_tolerance"] = within if resolution is None or resolution.resolved else None
    if chart_csv:
        out |= _against_chart(read_csv(chart_csv), out, runner, key, advice)
    return out


def _against_chart(rows: list[dict], out: dict, runner: str, key: str, advice: Advice) -> dict:
    """The check's cost against the cheapest chart configuration that meets the tolerance."""
    res: dict[str, Any] = {}
    ok = [r for r in rows if r["runner"] == runner and r["completed"] and r[key] is not None
          and r[key] <= advice.tolerance]
    if ok:
        best = min(ok, key=lambda r: r["wall_time_s"])
        best_cpu = min(ok, key=lambda r: r["cpu_time_s"] or math.inf)
        res["chart_cheapest"] = {"label": best["label"], "wall_time_s": best["wall_time_s"], key: best[key]}
        res["wall_ratio_to_cheapest"] = out["wall_time_s"] / best["wall_time_s"] if out["wall_time_s"] else None
        if best_cpu.get("cpu_time_s") and out.get("cpu_time_s"):
            res["chart_cheapest_cpu"] = {"label": best_cpu["label"], "cpu_time_s": best_cpu["cpu_time_s"]}
            res["cpu_ratio_to_cheapest"] = out["cpu_time_s"] / best_cpu["cpu_time_s"]
        same = [r for r in rows if r["runner"] == runner and r["label"] == advice.label]
        if same:
            res["chart_same_configuration"] = {"wall_time_s": same[0]["wall_time_s"], key: same[0][key]}
    return res


def format_check(res: dict, tolerance: float) -> str:
    pct = lambda v: "-" if v is None else f"{v:.2%}"  # noqa: E731
    ref = res["reference"]
    ref_cost = "cached" if ref["cached"] else f"{ref['wall_time_s']:.1f} s wall"
    if res.get("wall_time_s") is None:
        return f"check: {res['label']} FAILED: {res['failure']}"
    status = "completed" if res["completed"] else "FAILED: " + str(res["failure"])
    within = {True: "within", False: "NOT within", None: "no verdict: the reference is not resolved, against"}[
        res["within_tolerance"]]
    if res["metric_name"]:
        judged = (f"{res['metric_name']} {res['metric']:.6g} vs {res['metric_reference']:.6g}: error "
                  f"{pct(res['metric_error_rel'])} ({within} {tolerance:.2%}); trajectory RMS error {pct(res['rms_error_rel'])}")
    else:  # no primary metric: the tolerance is on the trajectory (check())
        judged = f"no primary metric; trajectory RMS error {pct(res['rms_error_rel'])} ({within} {tolerance:.2%})"
    lines = []
    if res.get("reference_resolution"):
        from .resolve import Resolution, format_resolution

        lines.append(format_resolution(Resolution.from_dict(res["reference_resolution"])))
    lines += [f"check: {res['label']} ({res['runner']}) {status}, wall {res['wall_time_s']:.2f} s, cpu {res['cpu_time_s']:.2f} s",
             f"  against the reference ({ref['n_elements']} elements, h = {ref['step']:g} s, {ref_cost}): {judged}"]
    if "chart_cheapest" in res:
        c = res["chart_cheapest"]
        lines.append(f"  cheapest chart configuration within {tolerance:.2%}: {c['label']} ({c['wall_time_s']:.2f} s "
                     f"wall): this run costs {res['wall_ratio_to_cheapest']:.2f} x")
        if "cpu_ratio_to_cheapest" in res:
            lines.append(f"  by CPU time: cheapest {res['chart_cheapest_cpu']['label']} "
                         f"({res['chart_cheapest_cpu']['cpu_time_s']:.2f} s): {res['cpu_ratio_to_cheapest']:.2f} x")
        if "chart_same_configuration" in res:
            s = res["chart_same_configuration"]
            lines.append(f"  the same configuration in the chart: {s['wall_time_s']:.2f} s wall")
    return "\n".join(lines)
