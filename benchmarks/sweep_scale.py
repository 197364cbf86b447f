"""How a sweep scales on this machine, in one run: the same R runs (B1's first 2 s, 1 superelement,
2 modes, numpy backend: about a second each) on the local process pool with 1, 2 and N workers
and on a dask LocalCluster of 2 workers, as wall-time ratios to the 1-worker pool measured here;
then the wall time of 2, 4, ... R runs on 2 workers (how wall time grows with the number of runs).

    python benchmarks/sweep_scale.py [--runs 8] [--workers 4]

Every configuration starts its workers afresh (their start-up is part of its wall time) and
stores nothing (no result store: every run runs). Prints a markdown table (docs/scale.md).
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import contextlib

from ffrf_fmu.studies.sweep import Pool, connect, parse_scheduler, run_sweep
from ffrf_fmu.studies.task import make_task

B1 = Path(__file__).resolve().parent.parent / "models" / "haug_beam.toml"


def tasks(n: int):
    # distinct runs (the spin rate varies a little) so no two share a key
    return [make_task(B1, ["superelements=1", "modes=2", "duration=2", f"scenes.spinup.drives.hub.rotation.angle.omega={4 + 0.01 * k}"],
                      "spinup") for k in range(n)]


def timed(scheduler_text, workers, n) -> tuple[float, float]:
    """(wall time of the sweep, sum of the runs' own wall times)."""
    t0 = time.perf_counter()
    # a pool even for one worker (parse_scheduler's one worker runs in this process, without start-up)
    where = contextlib.nullcontext(Pool(1, "spawn")) if workers == 1 and not scheduler_text else \
        connect(parse_scheduler(scheduler_text, workers))
    with where as runner:
        out = run_sweep(tasks(n), runner)
    wall = time.perf_counter() - t0
    assert all(r["completed"] for r in out.results.values())
    return wall, sum(r["wall_time_s"] for r in out.results.values())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--workers", type=int, default=4, help="N, the largest pool")
    a = ap.parse_args()
    print(f"cpu_count {os.cpu_count()}, load average {os.getloadavg()[0]:.2f} at start")
    rows = []
    for label, sched, k in (("pool, 1 worker", None, 1), ("pool, 2 workers", None, 2),
                            (f"pool, {a.workers} workers", None, a.workers), ("dask LocalCluster, 2 workers", "local:2", 2)):
        wall, runs = timed(sched, k, a.runs)
        rows.append((label, wall, runs))
    base = rows[0][1]
    print(f"\n{a.runs} runs (B1 first 2 s, 1 SE, 2 modes, numpy)\n")
    print("| where | wall [s] | speed-up vs 1 worker | sum of run wall times [s] |\n|---|---|---|---|")
    for label, wall, runs in rows:
        print(f"| {label} | {wall:.1f} | {base / wall:.2f} | {runs:.1f} |")
    print("\nwall time against the number of runs, pool of 2 workers\n")
    print("| runs | wall [s] | wall per run [s] |\n|---|---|---|")
    for n in sorted({2, 4, a.runs, 2 * a.runs}):
        wall, _ = timed(None, 2, n)
        print(f"| {n} | {wall:.1f} | {wall / n:.2f} |")
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
