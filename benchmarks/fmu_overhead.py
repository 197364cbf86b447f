#!/usr/bin/env python3
"""Benchmark: B1 (4 superelements) through the FMU under fmpy vs the standalone run, per communication step.

    python benchmarks/fmu_overhead.py [--duration 2] [--comm-step H [H ...]] [--model models/haug_beam.toml]

Prints wall and CPU times (best of --repeat interleaved runs: on a shared machine the CPU time is
the stable measure) for the same scene, internal step h and number of internal steps:
  standalone   simulate.run on the reduced body (exact drive signals at every internal step; on numba
               chunks of steps in one kernel call, the drives and the recording inside it)
  stepwise     the same steps one BodySystem.step call each, with the recording (simulate.record) after
               each: the standalone cost of one Python call per step
  core         the FMU's BodyCoSim in-process (the FMU's input rule, no FMI layers), per communication step H
  fmu          the built FMU under fmpy.simulate_fmu (pythonfmu + fmpy + input table + recorder), per H
and, per H (default h, 5 h, 10 h), the ratio fmu/standalone (what a user sees), (core - standalone) per
communication step (the FMU's own bookkeeping and input rule) and (fmu - core) per communication step
(the FMI layers: fmpy and pythonfmu, our getters and setters).

BLAS runs one thread in every path (set here before numpy loads): the FMU limits itself to one
(fmu/core.py), and a standalone run with two OpenBLAS threads on a busy 2-core machine measured 7x
slower (0.97 against 0.13 ms CPU per step, 10:45 UTC 2026-11-25), which no ratio should contain.
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from fmpy import read_model_description

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ffrf_fmu.fmu.builder import build_from_model  # noqa: E402
from ffrf_fmu.fmu.core import BodyCoSim  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.model import scene_body  # noqa: E402
from ffrf_fmu.reduction import build_body  # noqa: E402
from ffrf_fmu.simulate import build_system, record, run, scene_inputs, whole_steps  # noqa: E402
from ffrf_fmu.fmu.run import fmu_input_table, run_fmu  # noqa: E402


def run_core(fmu: Path, fmu_resources: Path, scene, inputs, H: float) -> tuple[float, float, int, float]:
    """The FMU's BodyCoSim in-process: (wall, CPU, doSteps, mean over doSteps of their most Newton iterations).
    The inputs are tabulated on the communication grid before the clock starts (fmpy does the same with
    run_fmu's input table) and set with one set_many per doStep."""
    core = BodyCoSim.from_resources(fmu_resources)
    n = int(round(scene.duration / H))
    table = fmu_input_table(fmu, inputs, H * np.arange(n + 1))
    names = [name for name in table.dtype.names if name != "time"]
    vrs = [core.by_name[name] for name in names]
    rows = np.column_stack([table[name] for name in names])
    w0, c0 = time.perf_counter(), time.process_time()
    core.setup_experiment(0.0)
    core.enter_initialization_mode()
    core.set_many(vrs, rows[0])
    core.exit_initialization_mode()
    iterations = 0
    for k in range(n):
        core.set_many(vrs, rows[k])
        rep = core.do_step(k * H, H)
        if not rep.ok:
            raise RuntimeError(rep.message)
        iterations += rep.iterations
    return time.perf_counter() - w0, time.process_time() - c0, n, iterations / n


def run_stepwise(body, scene, origin, backend) -> float:
    """simulate.run's steps one BodySystem.step call each, recorded after each; mean Newton iterations."""
    system, inputs = build_system(body, scene, origin, backend)
    n, h = whole_steps(scene.duration, scene.step)
    rows, iterations = np.empty((n + 1, record(system).size)), 0
    for k in range(n):
        iterations += system.step(h, inputs)
        rows[k + 1] = record(system)
    return iterations / n


def timed(fn, *args):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn(*args)
    return out, time.perf_counter() - w0, time.process_time() - c0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    ap.add_argument("--scene", default="spinup")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated time [s] (default 2)")
    ap.add_argument("--comm-step", type=float, nargs="+", default=None,
                    help="communication steps H [s] (default: h, 5 h, 10 h with the scene's internal step h)")
    ap.add_argument("--backend", choices=("numba", "numpy"), default="numba",
                    help="the body's backend, the same for the standalone run and the FMU (default numba)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, interleaved; the best counts (default 3)")
    args = ap.parse_args(argv)
    overrides = [f"duration={args.duration}"]
    model = load_model(args.model, overrides)
    scene = model.scene(args.scene)
    Hs = args.comm_step or [scene.step * m for m in (1, 5, 10)]
    body, _ = build_body(scene_body(model.body, scene))
    inputs = scene_inputs(body, scene)
    best: dict = {}
    doSteps, iters = {}, {}

    def keep(key, wall, cpu):
        w, c = best.get(key, (np.inf, np.inf))
        best[key] = (min(w, wall), min(c, cpu))

    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_from_model(args.model, Path(tmp) / "body.fmu", scene=scene.name, overrides=overrides,
                               backend=args.backend)
        zipfile.ZipFile(fmu).extractall(Path(tmp) / "x")
        outputs = [v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"]
        for _ in range(max(1, args.repeat)):
            ref, wall, cpu = timed(lambda: run(body, scene, origin=model.body.origin, progress=False,
                                                backend=args.backend))
            keep("standalone", wall, cpu)
            _, wall, cpu = timed(run_stepwise, body, scene, model.body.origin, args.backend)
            keep("stepwise", wall, cpu)
            for H in Hs:
                wall, cpu, doSteps[H], iters[H] = run_core(fmu, Path(tmp) / "x" / "resources", scene, inputs, H)
                keep(("core", H), wall, cpu)
                fmu_run, wall, cpu = timed(lambda: run_fmu(fmu, scene, inputs, H, record=outputs))
                keep(("fmu", H), wall, cpu)
                if not fmu_run.reached:
                    print(f"FMU run at H = {H:g} s stopped early at t = {fmu_run.t[-1]}: {fmu_run.log[-1:]}")
                    return 1
    steps = int(round(scene.duration / scene.step))
    print(f"B1 {model.body.name}/{scene.name}: {len(body.superelements)} SE, {args.duration:g} s, internal step h = "
          f"{scene.step:g} s ({steps} steps); backend {args.backend} (standalone ran {ref.summary['backend']}), best of "
          f"{args.repeat}, load average {os.getloadavg()[0]:.2f}")
    (ws, cs), (wp, cp) = best["standalone"], best["stepwise"]
    print(f"  standalone  wall {ws:.3f} s  CPU {cs:.3f} s  ({1e6 * cs / steps:.0f} us CPU per internal step; "
          f"Newton {ref.summary['newton_iterations_mean']:.3f} per step)")
    print(f"  stepwise    wall {wp:.3f} s  CPU {cp:.3f} s  ({1e6 * cp / steps:.0f} us CPU per internal step)")
    print("  | H | doSteps | core wall / CPU [s] | fmu wall / CPU [s] | fmu/standalone wall | fmu/standalone CPU "
          "| core - standalone per doStep | FMI layers per doStep | Newton/doStep (worst) |")
    print("  |---|---|---|---|---|---|---|---|---|")
    for H in Hs:
        (wc, cc), (wf, cf), n = best[("core", H)], best[("fmu", H)], doSteps[H]
        print(f"  | {1e3 * H:g} ms | {n} | {wc:.3f} / {cc:.3f} | {wf:.3f} / {cf:.3f} | {wf / ws:.2f} | {cf / cs:.2f} "
              f"| {1e6 * (cc - cs) / n:.0f} us | {1e6 * (cf - cc) / n:.0f} us | {iters[H]:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
