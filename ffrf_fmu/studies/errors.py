"""A run's errors against its reference: the scene's primary metric and the relative errors charts report,
advise budgets and the reference refinement (resolve.py) measures. Below chart.py and resolve.py alike."""
from __future__ import annotations

import numpy as np


def primary_metric(scene) -> str | None:
    """The metric of the scene whose relative error charts report and advise budgets (its model
    file's [scenes.NAME.metrics] primary), or None."""
    return scene.metrics.primary or None


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
