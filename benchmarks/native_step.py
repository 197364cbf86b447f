"""CPU per step of the C runtime on B1, the many-step path of simulate.run (the scene's schedule and the
recording inside one call), and what a run costs around it: the figures of docs/runtime.md.

    python benchmarks/native_step.py [--repeat 10]

Per configuration (superelements x modes, step, stiffening): the 20 s spin-up from the same initial
state `--repeat` times, each timed by this process's CPU clock around BodySystem.run_schedule alone
(set-up and metrics apart), best kept; with the Newton iterations and matrix refreshes per step, and the
body's set-up (simulate.build_system: BodySystem and its C body, the initial state; CPU, best of `--repeat`).
Then the phases of one standalone run of B1 1 SE stiffened at 40 ms (CPU, best of `--repeat`): the
reduction (FE model and superelement), the cached reduced body's load (body_cache.py), the body's
set-up (BodySystem with its image and C body, the initial state: simulate.build_system), the solve
with its recording, and the scene's metrics.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from ffrf_fmu import simulate as sim
from ffrf_fmu.body_cache import scene_body_data
from ffrf_fmu.model import load_model

MODEL = Path(__file__).resolve().parents[1] / "models" / "haug_beam.toml"
CONFIGS = (["superelements=1", "modes=2", "step=0.002"], ["superelements=4", "modes=6", "step=0.002"],
           ["superelements=8", "modes=2", "step=0.002"], ["superelements=1", "modes=2", "stiffening=true", "step=0.04"])


def measure(overrides, repeat):
    model = load_model(MODEL, overrides)
    scene = model.scene("spinup")
    body = scene_body_data(model.body, scene)
    setup = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        system, _ = sim.build_system(body, scene)
        setup = min(setup, time.process_time() - c0)
    schedule = sim.scene_schedule(body, scene)
    n = int(round(scene.duration / scene.step))
    rows, times = np.empty((n, len(sim.column_names(body)))), np.empty(n)
    start, best = system.get_state(), float("inf")
    for _ in range(repeat):
        system.set_state(start)
        v0 = system._compiled.body.get("lu_version")
        c0 = time.process_time()
        done, failure = system.run_schedule(scene.step, schedule, rows, times)
        best = min(best, time.process_time() - c0)
        refreshes = system._compiled.body.get("lu_version") - v0
    assert done == n and failure is None, failure
    return best, n, rows[:, -1].mean(), refreshes / n, setup


def phases(repeat) -> dict[str, float]:
    """CPU seconds (best of repeat) of the phases of one standalone run (module doc)."""
    from ffrf_fmu.body_cache import key
    from ffrf_fmu.model import scene_body
    from ffrf_fmu.reduction import reduce_body, reduction_options

    model = load_model(MODEL, CONFIGS[-1])
    scene = model.scene("spinup")
    scene_body_data(model.body, scene)  # cached from here on
    clock, best = time.process_time, {}

    def timed(name, fn):
        c0 = clock()
        out = fn()
        best[name] = min(best.get(name, float("inf")), clock() - c0)
        return out

    run_body, options = scene_body(model.body, scene), reduction_options(scene)
    assert key(run_body, options)
    for _ in range(repeat):
        timed("reduction (uncached)", lambda: reduce_body(run_body, **options))
        body = timed("reduced body from the cache", lambda: scene_body_data(model.body, scene))
        system, _ = timed("set-up (build_system)", lambda: sim.build_system(body, scene))
        schedule = sim.scene_schedule(body, scene)
        n = int(round(scene.duration / scene.step))
        rows, times = np.empty((n, len(sim.column_names(body)))), np.empty(n)
        timed("solve and recording", lambda: system.run_schedule(scene.step, schedule, rows, times))
        result = sim.run(body, scene, progress=False)
        timed("metrics", lambda: sim.metrics(result, scene))
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=10)
    args = ap.parse_args(argv)
    print(f"B1 spin-up 20 s, C runtime, CPU best of {args.repeat}; load average {os.getloadavg()[0]:.2f}")
    for overrides in CONFIGS:
        best, n, it, ref, setup = measure(overrides, args.repeat)
        print(f"  {' '.join(overrides):45s} {n:6d} steps  {1e3 * best:8.2f} ms  {1e6 * best / n:7.1f} us/step  "
              f"Newton {it:.2f}/step  matrices {ref:.2f}/step  set-up {1e3 * setup:.2f} ms")
    print(f"phases of one run of B1 {' '.join(CONFIGS[-1])} (CPU, best of {args.repeat}):")
    for name, seconds in phases(args.repeat).items():
        print(f"  {name:30s} {1e3 * seconds:8.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
