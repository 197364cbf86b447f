#!/usr/bin/env python3
"""Benchmark: what one kernel call per communication step costs beyond the standalone run's steps
(an FMU at H = h pays one `BodySystem.run_extrapolated` call per internal step, `simulate.run`
one call per 500 steps).

    python benchmarks/kernel_call_cost.py [--duration 2] [--traffic-mb 1]

B1 (4 SE x 6 modes, h = 2 ms, native, one BLAS thread), in this process, wall time of the calls
alone (perf_counter around each; mean, median and minimum over the calls: the steps vary with their
Newton iterations, the mean also with the machine's other jobs):
  run 500             simulate.run's path: BodySystem.run_schedule, 500 steps per call (per step)
  run 1               the same with one step per call
  extrapolated n=0    BodySystem.run_extrapolated with no step to take: the call's own cost (its Python wrappers,
                      BodySystem.run_extrapolated and CompiledStep.run_extrapolated, and unboxing the kernel's ~75 argument arrays)
  extrapolated warm   run_extrapolated of one step from the same state again and again (the state restored
                      between calls, outside the timing): the step with the kernel's data and code in cache
  extrapolated cold   the same after writing --traffic-mb of memory between calls, as a host's code does
                      between doSteps (fmpy, pythonfmu, the slave)
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ffrf_fmu.model import load_model, scene_body  # noqa: E402
from ffrf_fmu.reduction import reduce_body  # noqa: E402
from ffrf_fmu.runtime import input_rule  # noqa: E402
from ffrf_fmu.simulate import build_system, record, scene_schedule, whole_steps  # noqa: E402


def run_chunks(body, scene, chunk: int) -> list[float]:
    """Seconds per step of run_schedule calls of `chunk` steps (after two untimed first steps)."""
    system, inputs = build_system(body, scene, backend="native")
    n, h = whole_steps(scene.duration, scene.step)
    schedule = scene_schedule(body, scene)
    rows, times = np.empty((n + 1, record(system).size)), np.empty(n + 1)
    system.step(h, inputs)  # the first step is checked against numpy
    k, out = 1, []
    while k < n:
        m = min(chunk, n - k)
        t0 = time.perf_counter()
        done, exc = system.run_schedule(h, schedule, rows[k:k + m], times[k:k + m])
        out.append((time.perf_counter() - t0) / m)
        if exc is not None:
            raise exc
        k += m
    return out


def step_calls(body, scene, n_steps: int, calls: int, traffic: np.ndarray | None) -> list[float]:
    """Seconds per run_extrapolated(h, n_steps) call from one state mid-run (t = duration / 2), restored
    between calls; `traffic` written between calls when given."""
    system, inputs = build_system(body, scene, backend="native")
    h = scene.step
    for _ in range(int(round(scene.duration / 2 / h))):
        system.run_extrapolated(h, 1, system.t, input_rule.point_values(body.ports, inputs(system.t)))
    values, row = input_rule.point_values(body.ports, inputs(system.t)), np.empty(record(system).size)
    start, t_c = system.snapshot(), system.t
    out = []
    for _ in range(calls):
        system.restore(start)
        if traffic is not None:
            traffic += 1.0
        t0 = time.perf_counter()
        system.run_extrapolated(h, n_steps, t_c, values, row)
        out.append(time.perf_counter() - t0)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--traffic-mb", type=float, default=1.0)
    args = ap.parse_args(argv)
    model = load_model(args.model, [f"duration={args.duration}"])
    scene = model.scene("spinup")
    body = reduce_body(scene_body(model.body, scene)).data
    run_chunks(body, scene, 500)  # untimed: the kernel's entry points load from the disk cache (or compile) once
    rows = {
        "run 500 (per step)": run_chunks(body, scene, 500),
        "run 1": run_chunks(body, scene, 1),
        "extrapolated n=0": step_calls(body, scene, 0, args.calls, None),
        "extrapolated warm": step_calls(body, scene, 1, args.calls, None),
        f"extrapolated cold ({args.traffic_mb:g} MB between)": step_calls(body, scene, 1, args.calls,
                                                                 np.zeros(int(args.traffic_mb * 1e6 / 8))),
    }
    print(f"B1 {scene.name}, h = {scene.step:g} s, native; load average {os.getloadavg()[0]:.2f}, "
          f"{time.strftime('%H:%M UTC', time.gmtime())}")
    for label, t in rows.items():
        print(f"  {label:32s} mean {1e6 * np.mean(t):6.1f} us   median {1e6 * np.median(t):6.1f} us   "
              f"min {1e6 * np.min(t):6.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
