"""Parameter studies: `ffrf-fmu study MODEL --scene S --vary KEY=V1,V2,... [--vary ...]`.

Every combination of the varied values (cartesian product; keys are `--set` keys of model.py,
short ones such as length, EI2, superelements, duration or dotted paths such as
scenes.spinup.drives.hub.rotation.angle.omega) runs standalone on the scene through the sweep
layer (sweep.py: process pool, LocalCluster or a dask scheduler). Written to DIR:

- study.csv: one row per run: the varied values, the scene's metrics (simulate.metrics), the
  wall and CPU time, completion and the failure's cause, the attempts and the code version;
- study.png: each metric against each varied key (one panel per metric and key; a line per
  combination of the other keys; failed runs are left out of the lines and counted in the title);
- study.json: model, scene, overrides, the varied values, the scheduler, counts;
- runs.jsonl and arrays/: the result store (store.py): rerunning skips finished runs.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Sequence

from ..model import load_model
from .grid import GridError, combinations, value_overrides
from .sweep import Scheduler, SweepOptions, sweep_into
from .table import read_rows, replace_text, write_rows
from .task import code_version, make_task

FIRST = ("completed", "failure")
LAST = ("wall_time_s", "cpu_time_s", "t_end_s", "attempts", "code_version")


class StudyError(GridError):
    """A study cannot be set up (bad --vary)."""


def _number(text: str):
    try:
        return float(text)
    except ValueError:
        return text


def row_of(values: dict[str, str], result: dict) -> dict:
    """The table row of one run: varied values (numbers where they parse), scalar metrics, status."""
    row = {k: _number(v) for k, v in values.items()}
    row |= {"completed": bool(result.get("completed")), "failure": result.get("failure") or ""}
    for k, v in (result.get("metrics") or {}).items():
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            row[k] = float(v)
    row |= {k: result.get(k) for k in LAST}
    return row


def study(model_path, scene_name: str | None, vary: dict[str, list[str]], *, overrides: Sequence[str] = (),
          scheduler: Scheduler = Scheduler(), out_dir="study", progress: bool = True, plot: bool = True,
          fresh: bool = False, backend: str = "numpy") -> dict:
    """Run the study; write DIR/study.csv, study.png, study.json (module doc). Returns
    {"rows", "csv", "png", "json", "meta"}; rows in the order of the combinations."""
    if not vary:
        raise StudyError("--vary: give at least one KEY=V1,V2,... (e.g. --vary length=6,8,10)")
    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    combos = combinations(vary)
    for c in combos:  # every combination must load (ModelError naming the bad value) before anything runs
        load_model(model_path, [*overrides, *value_overrides(c)]).scene(scene.name)
    tasks = [make_task(model_path, [*overrides, *value_overrides(c)], scene.name, backend=backend) for c in combos]
    out_dir = Path(out_dir)
    outcome = sweep_into(out_dir, tasks, f"study {model.body.name}/{scene.name}",
                         {t.key: ", ".join(f"{k}={v}" for k, v in c.items()) for c, t in zip(combos, tasks)},
                         SweepOptions(scheduler, fresh, progress))
    rows = [row_of(c, outcome.results[t.key]) for c, t in zip(combos, tasks)]
    paths = {k: out_dir / f"study.{k}" for k in ("csv", "png", "json")}
    write_table(rows, list(vary), paths["csv"])
    meta = {"model": str(model_path), "scene": scene.name, "overrides": list(overrides), "vary": vary, "backend": backend,
            "scheduler": outcome.where, "code_version": code_version(), "runs": len(rows),
            "runs_stored": outcome.stored, "runs_ran": outcome.ran, "runs_retried": outcome.retried,
            "runs_failed": sum(not r["completed"] for r in rows), "cpu_count": os.cpu_count()}
    replace_text(paths["json"], json.dumps(meta, indent=2) + "\n")
    if plot:
        plot_study(rows, list(vary), paths["png"], f"{model.body.name} / {scene.name}")
    return {"rows": rows, "meta": meta, **{k: str(v) for k, v in paths.items()}}


def metric_names(rows: list[dict], keys: Sequence[str]) -> list[str]:
    skip = set(keys) | set(FIRST) | set(LAST)
    return list(dict.fromkeys(k for r in rows for k in r if k not in skip))


def write_table(rows: list[dict], keys: Sequence[str], path) -> None:
    write_rows(path, rows, [*keys, *FIRST, *metric_names(rows, keys), *LAST], float_format=".10g")


def read_table(path) -> list[dict]:
    """study.csv rows, numbers parsed as floats (empty -> None), completed as bool."""
    rows = read_rows(path, text=("failure", "code_version"))
    return [{k: float(v) if isinstance(v, int) and not isinstance(v, bool) else v for k, v in r.items()} for r in rows]


def plot_study(rows: list[dict], keys: Sequence[str], path, title: str = "") -> None:
    """Each metric (rows of panels) against each varied key (columns); one line per combination of
    the other keys, completed runs only."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = metric_names(rows, keys) or ["wall_time_s"]
    ok = [r for r in rows if r["completed"]]
    fig, axes = plt.subplots(len(metrics), len(keys), figsize=(4.5 * len(keys), 2.8 * len(metrics)), squeeze=False)
    for j, key in enumerate(keys):
        levels = list(dict.fromkeys(r[key] for r in rows))
        numeric = all(isinstance(v, float) for v in levels)
        others = [k for k in keys if k != key]
        groups = list(dict.fromkeys(tuple(r[k] for k in others) for r in ok))
        for i, m in enumerate(metrics):
            ax = axes[i][j]
            for g in groups:
                pts = [(r[key] if numeric else levels.index(r[key]), r.get(m)) for r in ok
                       if tuple(r[k] for k in others) == g and isinstance(r.get(m), float) and math.isfinite(r[m])]
                if pts:
                    x, y = zip(*sorted(pts))
                    ax.plot(x, y, "o-", ms=4, label=", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                                                              for k, v in zip(others, g)) or None)
            if not numeric:
                ax.set_xticks(range(len(levels)), [str(v) for v in levels])
            ax.set_xlabel(key.rsplit(".", 2)[-1] if len(key) > 30 else key, fontsize=8)
            ax.set_ylabel(m, fontsize=8)
            ax.grid(True, alpha=0.3)
            if others and i == 0 and len(groups) > 1:
                ax.legend(fontsize=6)
    failed = len(rows) - len(ok)
    fig.suptitle(f"{title}: {len(rows)} runs" + (f", {failed} failed (see study.csv)" if failed else ""), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
