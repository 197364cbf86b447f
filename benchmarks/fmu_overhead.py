#!/usr/bin/env python3
"""Benchmark: B1 (4 superelements) through the FMU under fmpy vs the standalone run.

    python benchmarks/fmu_overhead.py [--duration 2] [--comm-step H] [--model models/haug_beam.toml]

Prints wall and CPU times (best of --repeat interleaved runs: on a shared machine the CPU time is
the stable measure) for the same scene, internal step and number of internal steps:
  standalone   simulate.run on the reduced body (exact drive signals at every internal step; on numba
               chunks of steps in one kernel call, the drives and the recording inside it)
  stepwise     the same steps one BodySystem.step call each, with the recording (simulate.record) after
               each: the standalone cost of one Python call per step, as an FMU at H = h makes
  core         the FMU's BodyCoSim in-process (the FMU's input rule, no FMI layers)
  fmu          the built FMU under fmpy.simulate_fmu (pythonfmu + fmpy + input table + recorder)
and the ratios fmu/standalone (what a user sees), fmu/stepwise (the FMU against the same one call per
step), core/standalone (cost of the input rule: the
extrapolated hub motion changes the Newton iterations) and (fmu - core) per communication step
(the FMI wrapper overhead).
"""
from __future__ import annotations

import argparse
import os
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
from ffrf_fmu.fmu.run import run_fmu  # noqa: E402


def run_core(fmu_resources: Path, scene, inputs, H: float) -> tuple[float, float, int, float]:
    """The FMU's BodyCoSim in-process: (wall, CPU, doSteps, mean Newton iterations per doStep)."""
    core = BodyCoSim.from_resources(fmu_resources)
    pv_fields = ("r", "v", "R", "w", "f", "t")

    def set_inputs(t):
        vals = inputs(t)
        for p in core.data.ports:
            for f in pv_fields:
                ix = core.index[(p.name, f)]
                if core.causality[ix[0]] == "input":
                    core.values[ix] = np.ravel(getattr(vals[p.name], f))

    w0, c0 = time.perf_counter(), time.process_time()
    core.setup_experiment(0.0)
    core.enter_initialization_mode()
    set_inputs(0.0)
    core.exit_initialization_mode()
    n = int(round(scene.duration / H))
    iterations = 0
    for k in range(n):
        set_inputs(k * H)
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
    ap.add_argument("--comm-step", type=float, default=None, help="communication step (default: internal step)")
    ap.add_argument("--backend", choices=("numba", "numpy"), default="numba",
                    help="the body's backend, the same for the standalone run and the FMU (default numba)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, interleaved; the best counts (default 3)")
    args = ap.parse_args(argv)
    overrides = [f"duration={args.duration}"]
    model = load_model(args.model, overrides)
    scene = model.scene(args.scene)
    H = args.comm_step or scene.step
    body, _ = build_body(scene_body(model.body, scene))
    inputs = scene_inputs(body, scene)
    best = {k: [np.inf, np.inf] for k in ("standalone", "stepwise", "core", "fmu")}

    def keep(key, wall, cpu):
        best[key] = [min(best[key][0], wall), min(best[key][1], cpu)]

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
            wall, cpu, n, it_core = run_core(Path(tmp) / "x" / "resources", scene, inputs, H)
            keep("core", wall, cpu)
            fmu_run, wall, cpu = timed(lambda: run_fmu(fmu, scene, inputs, H, record=outputs))
            keep("fmu", wall, cpu)
            if not fmu_run.reached:
                print(f"FMU run stopped early at t = {fmu_run.t[-1]}: {fmu_run.log[-1:]}")
                return 1
    steps = int(round(scene.duration / scene.step))
    print(f"B1 {model.body.name}/{scene.name}: {len(body.superelements)} SE, {args.duration:g} s, "
          f"internal step {scene.step:g} s ({steps} steps), communication step {H:g} s ({n} doStep); "
          f"backend {args.backend} (standalone ran {ref.summary['backend']}), best of {args.repeat}, load average {os.getloadavg()[0]:.2f}")
    print(f"  {'':12s} {'wall [s]':>9s} {'CPU [s]':>8s} {'CPU/step':>10s}")
    for key, label in (("standalone", "standalone"), ("stepwise", "stepwise"), ("core", "core"), ("fmu", "fmu (fmpy)")):
        w, c = best[key]
        print(f"  {label:12s} {w:9.2f} {c:8.2f} {1e3 * c / steps:7.3f} ms")
    (ws, cs), (wp, cp), (wc, cc), (wf, cf) = best["standalone"], best["stepwise"], best["core"], best["fmu"]
    print(f"  ratio fmu/standalone   wall {wf / ws:.3f}  CPU {cf / cs:.3f}")
    print(f"  ratio fmu/stepwise     wall {wf / wp:.3f}  CPU {cf / cp:.3f}  (the same one call per step)")
    print(f"  ratio core/standalone  wall {wc / ws:.3f}  CPU {cc / cs:.3f}  (the FMU's input rule and bookkeeping)")
    print(f"  Newton iterations per step: standalone {ref.summary['newton_iterations_mean']:.3f}, core {it_core:.3f}")
    print(f"  FMI layers (fmpy + pythonfmu): {1e6 * (cf - cc) / n:.0f} us CPU per communication step")
    return 0


if __name__ == "__main__":
    sys.exit(main())
