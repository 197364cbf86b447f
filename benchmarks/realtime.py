#!/usr/bin/env python3
"""Benchmark: the real-time datasheet of the native FMU, one doStep's wall and CPU time over many doSteps in a
plain C host, and the Newton iterations per step that bound it (docs/fmu.md, "Real-time datasheet").

    python benchmarks/realtime.py [--steps 100000] [--case b1 b1_1se2m solid] [--cap N]

Per case the FMU is built from the model file with the scene's duration set to steps x h, and
benchmarks/fmu_host_bench.c (its STEP_LOG mode) runs it at H = h (one internal step per doStep, the rate a
real-time master steps at): fmi2SetReal of the scene's inputs at t_k, fmi2DoStep(t_k, h) timed alone
(CLOCK_MONOTONIC and CLOCK_THREAD_CPUTIME_ID read around the call), then fmi2GetReal of every output and
fmi2GetInteger of `solver.newton_iterations`. Cases:
  b1         models/haug_beam.toml, scene spinup (4 superelements x 6 modes, h = 2 ms; after 15 s a steady spin)
  b1_1se2m   the same with 1 superelement x 2 modes
  solid      models/haug_solid.toml, scene spinup (the bar of hex27 elements, 1 superelement x 6 modes, h = 2 ms)
Prints per case the median, p99, p99.9 and max of the wall and CPU time of one doStep (all steps; the first one
separately), the histogram of the iterations per step, and the CPU time by iteration count (median and max):
what a cap of the iterations bounds. --cap N builds with max_newton_iterations = N (the build checks the cap on
the whole run, fmu/realtime.py, and refuses it when it changes the result; docs/fmu.md).
Load average before and after each case: on a shared machine the wall time's tail is the scheduler's.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from fmu_overhead import host_command, host_table  # noqa: E402
from ffrf_fmu.fmu.builder import build_fmu  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.reduction import reduce_scene_body  # noqa: E402
from ffrf_fmu.simulate import scene_inputs  # noqa: E402

CASES = {
    "b1": ("haug_beam.toml", "spinup", []),
    "b1_1se2m": ("haug_beam.toml", "spinup", ["superelements=1", "modes=2"]),
    "solid": ("haug_solid.toml", "spinup", []),
}


def step_log(case: str, steps: int, tmp: Path, cap: int = 0) -> tuple[np.ndarray, dict]:
    """Rows (wall s, CPU s, iterations) of `steps` doSteps of a case's FMU at H = h in the C host, and what was run."""
    name, scene_name, extra = CASES[case]
    path = ROOT / "models" / name
    h = load_model(path).scene(scene_name).step
    overrides = [*extra, f"duration={steps * h!r}", f"max_newton_iterations={cap}"]
    model = load_model(path, overrides)
    scene = model.scene(scene_name)
    body = reduce_scene_body(model.body, scene).data
    fmu = build_fmu(path, tmp / f"{case}.fmu", scene=scene_name, overrides=overrides)
    host, md = host_command(fmu, scene, tmp)
    table = tmp / "table.bin"
    n = host_table(fmu, body, scene, scene_inputs(body, scene), h, table)
    vr_iter = next(v.valueReference for v in md.modelVariables if v.name == "solver.newton_iterations")
    log = tmp / "steps.bin"
    load = os.getloadavg()[0]
    done = subprocess.run([*host, str(table), str(n), repr(h), "1", "1", str(log), str(vr_iter)],
                          capture_output=True, text=True, timeout=7200)
    if done.returncode:
        raise RuntimeError(f"{case}: fmu_host_bench exit {done.returncode}: {done.stdout[-500:]}{done.stderr[-2000:]}")
    rows = np.fromfile(log, dtype="<f8").reshape(-1, 3)
    about = {"model": f"models/{name}", "scene": scene_name, "overrides": extra, "cap": cap, "h": h, "steps": n,
             "superelements": len(body.superelements), "load_before": load, "load_after": os.getloadavg()[0]}
    return rows, about


def _us(x) -> str:
    return f"{1e6 * x:.1f}"


def report(case: str, rows: np.ndarray, about: dict) -> None:
    wall, cpu, it = rows[:, 0], rows[:, 1], rows[:, 2].astype(int)
    print(f"{case}: {about['model']} {about['scene']} {' '.join(about['overrides'])} ({about['superelements']} SE), "
          f"h = {about['h']:g} s, {len(rows)} doSteps at H = h, max_newton_iterations = {about['cap']}; load average {about['load_before']:.2f} before, "
          f"{about['load_after']:.2f} after, {time.strftime('%H:%M UTC', time.gmtime())}")
    print("  | per doStep [us] | median | p99 | p99.9 | max | first doStep |")
    print("  |---|---|---|---|---|---|")
    for label, x in (("wall", wall), ("CPU", cpu)):
        q = np.percentile(x, [50, 99, 99.9])
        print(f"  | {label} | {_us(q[0])} | {_us(q[1])} | {_us(q[2])} | {_us(x.max())} | {_us(x[0])} |")
    values, counts = np.unique(it, return_counts=True)
    print(f"  Newton iterations per step: min {it.min()}, median {np.median(it):g}, max {it.max()}; histogram "
          + ", ".join(f"{v}: {c}" for v, c in zip(values, counts)))
    print("  CPU per doStep by iterations [us]: " + "; ".join(
        f"{v}: median {_us(np.median(cpu[it == v]))}, max {_us(cpu[it == v].max())}" for v in values))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--steps", type=int, default=100_000, help="doSteps per case (default 100000)")
    ap.add_argument("--case", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--cap", type=int, default=0, help="max_newton_iterations of the FMUs (default 0: no cap)")
    args = ap.parse_args(argv)
    for case in args.case:
        with tempfile.TemporaryDirectory() as tmp:
            rows, about = step_log(case, args.steps, Path(tmp), args.cap)
        report(case, rows, about)
    return 0


if __name__ == "__main__":
    sys.exit(main())
