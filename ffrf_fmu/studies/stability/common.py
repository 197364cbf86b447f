"""What every stability map shares: its runs go through the sweep layer (sweep.py) into the
result store in the map's directory (DIR/runs.jsonl: a rerun repeats no finished run), with the
progress bar; the map's table is DIR/map.csv, its time series DIR/series.npz."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..progress import Bar
from ..store import ResultStore
from ..sweep import Scheduler, connect, run_sweep
from ..table import read_rows, write_rows
from ..task import Task

MAP_CSV, SERIES = "map.csv", "series.npz"
TEXT_COLUMNS = ("model", "terms", "failure", "benchmark", "scene", "case", "scheme")


@dataclasses.dataclass(frozen=True)
class SweepOptions:
    """Where a map's runs go (sweep.py) and how it reports: scheduler (default: this process),
    fresh (discard the stored results first), progress (the bar on a terminal), log (one line per
    finished run, e.g. print)."""

    scheduler: Scheduler = Scheduler()
    fresh: bool = False
    progress: bool = True
    log: Callable[[str], None] | None = None


def run_tasks(tasks: Sequence[Task], out_dir, name: str, notes: dict[str, str], options: SweepOptions) -> dict:
    """Run the tasks (stored ones are taken from DIR's store); {task key: result}. notes: a short
    text per task key for the bar and the log."""
    out_dir = Path(out_dir)
    bar = Bar(len({t.key for t in tasks}), name) if options.progress else None
    done = 0

    def on_result(t, result, from_store) -> None:
        nonlocal done
        done += 1
        note = notes.get(t.key, t.runner) + (" (stored)" if from_store else "")
        if bar:
            bar.update(done, note)
        if options.log and not from_store:
            status = "" if result.get("completed") else f": {result.get('failure')}"
            options.log(f"{note}{status} ({result.get('wall_time_s') or 0.0:.0f} s)")

    with connect(options.scheduler) as runner:  # an unreachable scheduler fails here, before DIR is written
        out_dir.mkdir(parents=True, exist_ok=True)
        store = ResultStore(out_dir)
        if options.fresh:
            store.discard()
        outcome = run_sweep(list(tasks), runner, store=store, on_result=on_result)
    if bar:
        bar.close()
    return outcome.results


def write_map(out_dir, rows: list[dict], series: dict[str, np.ndarray]) -> None:
    out_dir = Path(out_dir)
    write_rows(out_dir / MAP_CSV, rows)
    np.savez_compressed(out_dir / SERIES, **series)


def read_map(path) -> list[dict]:
    """map.csv rows, cells parsed (table.parse)."""
    return read_rows(path, text=TEXT_COLUMNS)


def is_true(v) -> bool:
    return v is True or v == "True" or v == 1.0
