"""The co-simulation map (docs/stability.md): communication step against coupling scheme for two
coupled systems, each run's tip deflection against its monolithic reference.

 motor: the beam FMU (scene hub_free: hub rotation force-driven, translation motion-driven)
        joined at its hub port to the hub drive FMU (ffrf_fmu.examples: hub inertia, motor, PI speed
        controller on the Wu-Haug profile, torsional shaft to the beam root);
 split: the beam cut at its middle boundary node into two body FMUs (split.py), A (hub
        motion-driven by the Wu-Haug law, cut force-driven) and B (cut motion-driven, tip free).

The systems and their runs: case.py. Every run is a task of the sweep layer (runner "cosim":
case, H, scheme and the run settings as options; tasks.py runs it in a worker).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..sweep import SweepOptions, sweep_into
from ..task import make_task
from . import margin
from .case import CosimRun, CosimSettings
from .common import write_map
from .tasks import COMPLIANT, IMPLICIT, INTERFACE_JACOBIAN, REFERENCE, perturbed_run, run_settings

TORQUE_BLOWUP = 10.0  # unstable: shaft torque beyond this many times the monolithic run's peak
GROWTH_DEVIATION = 0.5  # ... or off the monolithic run by half its peak and growing (see compare)
#: "stable" needs the run to complete AND its errors to stay under this fraction of the monolithic
#: run's peak, for the tip deflection history and (B5) the hub speed history, max over the run.
#: Why 1 %: it is the size of the model's own error (4 superelements against the nonlinear beam:
#: +1.4 % of the peak deflection at 4 rad/s, docs/stability.md section 1), so a coupling error
#: beyond it changes the answer more than the model choice does; a completed run above it is
#: "inaccurate", not stable (B5 plain Gauss-Seidel at 10 ms: 9 % deflection, 86 % hub speed).
ACCURACY_BOUND = 1e-2
VERDICTS = ("stable", "inaccurate", "unstable", "marginal")  # marginal: cosim_margin_verdict


def compare(run: CosimRun, ref: CosimRun, length: float, ref_torque_peak: float) -> dict:
    """Errors of a coupled run against its monolithic reference, and the stability verdict."""
    n = len(run.t)
    d_ref = np.interp(run.t, ref.t, ref.deflection)
    scale = float(np.max(np.abs(ref.deflection)))
    finite = np.all(np.isfinite(run.deflection)) and np.all(np.isfinite(run.torque))
    err = float(np.max(np.abs(run.deflection - d_ref)) / scale) if n and finite else float("nan")
    speed_err = float("nan")
    if np.any(np.isfinite(run.speed)) and finite:
        s_ref = np.interp(run.t, ref.t, ref.speed)
        speed_err = float(np.max(np.abs(run.speed - s_ref)) / max(np.max(np.abs(ref.speed)), 1e-300))
    reasons, ratios = [], []  # ratios: value over bound of each instability bound (> 1 crossed), margin.py
    if run.stopped_early:
        reasons.append(run.stopped_early.split(": Newton")[0] + (": Newton failure" if "Newton" in run.stopped_early else ""))
    if not finite:
        reasons.append("non-finite values")
    elif (ratios := [float(np.max(run.deflection)) / length]) and np.max(run.deflection) > length:
        reasons.append(f"tip deflection {np.max(run.deflection):.3g} m > L")
    elif not np.isfinite(ref_torque_peak) or not np.all(np.isfinite(ref.torque)):
        pass  # the reference has no interface moment (split beam: the cut is inside the one body)
    elif (ratios := [*ratios, float(np.max(np.abs(run.torque))) / (TORQUE_BLOWUP * ref_torque_peak)]) \
            and np.max(np.abs(run.torque)) > TORQUE_BLOWUP * ref_torque_peak:
        reasons.append(f"interface torque {np.max(np.abs(run.torque)):.3g} N m > {TORQUE_BLOWUP:g} x monolithic peak")
    elif n > 10:
        # a growing oscillation that has not failed yet: the interface torque has left the monolithic
        # run by more than half its peak over the last second, and by 10x more than in the first half
        dev = np.abs(run.torque - np.interp(run.t, ref.t, ref.torque))
        last, first = dev[run.t >= run.t[-1] - 1.0], dev[run.t <= run.t[-1] / 2]
        # both must hold: the conjunction's ratio is the smaller one
        ratios.append(min(float(np.max(last)) / (GROWTH_DEVIATION * ref_torque_peak),
                          float(np.max(last)) / (10.0 * max(float(np.max(first)), 1e-12))))
        if np.max(last) > GROWTH_DEVIATION * ref_torque_peak and np.max(last) > 10.0 * max(np.max(first), 1e-12):
            reasons.append(f"growing interface oscillation: torque off the monolithic run by {np.max(last):.3g} N m "
                           f"in the last second, {np.max(first):.2g} N m in the first half")
    worst = max(err, speed_err if np.isfinite(speed_err) else 0.0)
    verdict = "unstable" if reasons else ("inaccurate" if not worst <= ACCURACY_BOUND else "stable")
    return {"rel_error": err, "speed_rel_error": speed_err, "verdict": verdict, "unstable": bool(reasons),
            "failure": "; ".join(reasons),
            "t_end": float(run.t[-1]) if n else 0.0, "sweeps": run.sweeps, "wall_time_s": run.wall_time_s,
            # a run stopped by a failed step ends there: its time decides (margin.py), not a ratio
            "bound_ratio": float(max(ratios)) if ratios and not run.stopped_early else float("nan")}


def cosim_margin_verdict(model_path, settings: CosimSettings, kind: str, row: dict, ref: CosimRun,
                         ref_torque_peak: float, grid: Sequence[float]) -> str:
    """The row's verdict with a margin (margin.classify; docs/stability.md, "Marginal points"): a run that
    failed in the last 10 % of its duration, or whose instability bounds (tip deflection over L, torque
    over TORQUE_BLOWUP x the monolithic peak, the growing-oscillation test) were met within
    margin.BOUND_FACTOR, is re-run with the hub profile perturbed at margin.PERTURBATION
    (tasks.perturbed_run) and at the neighbour communication step of the map's grid; `marginal` when a
    re-run's stable / unstable verdict differs. A stable row keeps its stable / inaccurate class."""
    duration = settings.duration if kind == "motor" else settings.split_duration
    ratio = row.get("bound_ratio", float("nan"))
    point = margin.Point(unstable=bool(row["unstable"]), t_end=float(row.get("t_end", 0.0)), duration=duration,
                         failure=row.get("failure", ""), bound_ratios=(ratio,) if ratio == ratio else ())

    def rerun(H, eps):
        run = perturbed_run(model_path, settings, kind, H, row["scheme"], eps)
        return bool(compare(run, ref, row["length"], ref_torque_peak)["unstable"])

    v = margin.classify(point, float(row["H"]), tuple(grid), rerun)
    return row["verdict"] if v != margin.MARGINAL else v


def cosim_map(model_path, settings: CosimSettings, out_dir, *, cases=("motor", "split"),
              implicit_steps: Sequence[float] = (0.002, 0.01, 0.04), sweep: SweepOptions = SweepOptions(),
              margin_check: bool = True) -> list[dict]:
    """Communication step against coupling scheme for the motor and the split systems; one CSV row
    per run, its verdict stable / inaccurate / unstable (compare), or marginal (cosim_margin_verdict; not
    checked when margin_check is False). Monolithic references
    (monolithic.py, docs/stability.md): motor -> beam, shaft, hub and drive in one standalone run at
    settings.reference_step; split -> the one-body scene standalone at the same H."""
    opts = {"settings": run_settings(settings)}
    ov = list(settings.overrides)

    def task(kind, H, label):
        return make_task(model_path, ov, None, "cosim", case=kind, H=float(H), scheme=label, **opts)

    refs, runs, notes = {}, [], {}
    for kind in cases:
        schemes = [*settings.schemes, IMPLICIT, INTERFACE_JACOBIAN, *([COMPLIANT] if kind == "motor" else [])]
        for H in (settings.steps if kind == "motor" else settings.split_steps):
            H_ref = settings.reference_step if kind == "motor" else H
            if (kind, H_ref) not in refs:
                refs[kind, H_ref] = t = task(kind, H_ref, REFERENCE)
                notes[t.key] = f"{kind}: monolithic reference at H = {H_ref:g} s"
            for label, *_ in schemes:
                if label == IMPLICIT[0] and kind == "motor" and not any(abs(H - h) < 1e-12 for h in implicit_steps):
                    continue
                runs.append((kind, H, H_ref, label, t := task(kind, H, label)))
                notes[t.key] = f"{kind} H = {H:g} s {label}"
    results = sweep_into(out_dir, [*refs.values(), *(r[-1] for r in runs)], "co-simulation map", notes, sweep).results
    rows, series = [], {}
    for (kind, H_ref), t in refs.items():  # (rows of the references; `series` keeps their histories)
        r = results[t.key]
        if not r.get("completed") or r.get("stopped_early"):
            raise RuntimeError(f"{kind}: the monolithic reference failed: {r.get('stopped_early') or r['failure']}")
        run = CosimRun.of(r)
        rows.append({"case": kind, "scheme": REFERENCE, "H": H_ref, "rel_error": 0.0, "verdict": "reference", "unstable": False,
                     "failure": "", "t_end": float(run.t[-1]), "sweeps": run.sweeps, "wall_time_s": run.wall_time_s})
        series[f"{kind}_reference_H{H_ref:g}"] = np.column_stack([run.t, run.deflection, run.speed, run.torque])
    for kind, H, H_ref, label, t in runs:
        r, ref = results[t.key], CosimRun.of(results[refs[kind, H_ref].key])
        if not r.get("completed"):  # the run could not start (an FMU failed to build, ...): a row with its cause
            rows.append({"case": kind, "scheme": label, "H": float(H), "verdict": "unstable", "unstable": True,
                         "failure": r["failure"]})
            continue
        run = CosimRun.of(r)
        peak = float(np.max(np.abs(ref.torque)))
        row = {"case": kind, "scheme": label, "H": float(H), **compare(run, ref, r["length"], peak)}
        if margin_check:
            grid = settings.steps if kind == "motor" else settings.split_steps
            if label == IMPLICIT[0] and kind == "motor":
                grid = [h for h in grid if any(abs(h - g) < 1e-12 for g in implicit_steps)]
            row["verdict"] = cosim_margin_verdict(model_path, settings, kind, {**row, "length": r["length"]}, ref, peak, grid)
        rows.append(row)
        series[f"{kind}_{label}_H{H:g}"] = np.column_stack([run.t, run.deflection, run.speed, run.torque])
    write_map(out_dir, rows, series)
    return rows
