#!/usr/bin/env python3
"""Benchmark: B1 (4 superelements) through the FMU under fmpy vs the standalone run, per communication
step, with the master's floor measured in the same run.

    python benchmarks/fmu_overhead.py [--duration D] [--comm-step H [H ...]] [--model models/haug_beam.toml]

Runs (best of --repeat interleaved runs of each; CPU time, the stable measure on a shared machine):
  standalone   simulate.run on the reduced body (exact drive signals at every internal step; on numba
               chunks of steps in one kernel call, the drives and the recording inside it)
  core         the FMU's BodyCoSim in-process (the FMU's input rule, no FMI layers), per communication step H
  fmu          the built FMU under fmpy.simulate_fmu (native loader + pythonfmu + our slave; fmpy's input
               table, output_interval = H, every output recorded, debug logging on), per H
  floor C      a zero-work C FMU with exactly our FMU's model variables (benchmarks/_fmu_floor.py), run
               the same way: what fmpy alone costs per doStep for this interface
  floor py     the same as a zero-work pythonfmu FMU: fmpy + pythonfmu's layer
The FMU runs' CPU is that of fmpy.simulate_fmu (FmuRun.cpu_time_s: unzip, instantiate, initialize, the
doSteps, terminate). Each FMU also runs --short doSteps at H = h: its fixed per-run cost is that short
run minus its doSteps, and the per-doStep costs below exclude it (a user's run pays it once).

Default duration: the scene's own (B1 spin-up 20 s), so that the fixed cost is amortized as in a user's
run; --duration shortens. Per H (default h, 5 h, 10 h) the table gives per doStep: the standalone run's
CPU per communication step, fmpy alone (floor C), pythonfmu's layer (floor py - floor C), our FMU's
own cost (fmu - floor py) and its part beyond the standalone steps, core - standalone (the same
in-process), then the whole-run ratio fmu/standalone (what a user sees) and the lower bounds
(standalone + floor)/standalone that no FMU (C floor) or no pythonfmu FMU (py floor) can go below.

BLAS runs one thread in every path (set here before numpy loads): the FMU limits itself to one
(fmu/core.py), and a standalone run with two OpenBLAS threads on a busy 2-core machine measured 7x
slower (0.97 against 0.13 ms CPU per step, 10:45 UTC 2026-11-25), which no ratio should contain.
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import dataclasses
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from fmpy import read_model_description

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _fmu_floor import c_floor, python_floor  # noqa: E402
from ffrf_fmu.fmu.builder import build_from_model  # noqa: E402
from ffrf_fmu.fmu.core import BodyCoSim  # noqa: E402
from ffrf_fmu.runtime.compiled import parse_kernel_report  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.model import scene_body  # noqa: E402
from ffrf_fmu.reduction import build_body  # noqa: E402
from ffrf_fmu.simulate import run, scene_inputs  # noqa: E402
from ffrf_fmu.fmu.run import fmu_input_table, run_fmu  # noqa: E402

FMUS = ("fmu", "floor py", "floor C")


def run_core(fmu: Path, fmu_resources: Path, scene, inputs, H: float) -> tuple[float, float, int, float]:
    """The FMU's BodyCoSim in-process: (wall, CPU, doSteps, mean over doSteps of their most Newton iterations).
    The inputs are tabulated on the communication grid before the clock starts (fmpy does the same with
    run_fmu's input table) and set with one set_many per doStep, as lists (pythonfmu passes lists)."""
    core = BodyCoSim.from_resources(fmu_resources)
    n = int(round(scene.duration / H))
    table = fmu_input_table(fmu, inputs, H * np.arange(n + 1))
    names = [name for name in table.dtype.names if name != "time"]
    vrs = [core.by_name[name] for name in names]
    rows = np.column_stack([table[name] for name in names]).tolist()
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    ap.add_argument("--scene", default="spinup")
    ap.add_argument("--duration", type=float, default=None, help="simulated time [s] (default: the scene's)")
    ap.add_argument("--comm-step", type=float, nargs="+", default=None,
                    help="communication steps H [s] (default: h, 5 h, 10 h with the scene's internal step h)")
    ap.add_argument("--backend", choices=("native", "numpy"), default="native",
                    help="the body's backend, the same for the standalone run and the FMU (default numba)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, interleaved; the best counts (default 3)")
    ap.add_argument("--short", type=int, default=10, help="doSteps of the runs that give the fixed cost (default 10)")
    args = ap.parse_args(argv)
    overrides = [f"duration={args.duration}"] if args.duration else []
    model = load_model(args.model, overrides)
    scene = model.scene(args.scene)
    Hs = args.comm_step or [scene.step * m for m in (1, 5, 10)]
    short = dataclasses.replace(scene, duration=args.short * scene.step)
    body, _ = build_body(scene_body(model.body, scene))
    inputs = scene_inputs(body, scene)
    best: dict = {}
    doSteps, iters = {}, {}

    def keep(key, cpu):
        best[key] = min(best.get(key, np.inf), cpu)

    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_from_model(args.model, Path(tmp) / "body.fmu", scene=scene.name, overrides=overrides,
                               backend=args.backend)
        paths = {"fmu": fmu, "floor py": python_floor(fmu, tmp), "floor C": c_floor(fmu, tmp)}
        zipfile.ZipFile(fmu).extractall(Path(tmp) / "x")
        outputs = [v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"]

        def fmu_run(which, sc, H):
            out = run_fmu(paths[which], sc, inputs, H, record=outputs)
            if not out.reached:
                raise RuntimeError(f"{which} at H = {H:g} s stopped early at t = {out.t[-1]}: {out.log[-1:]}")
            return out

        def fmu_cpu(which, sc, H):
            return fmu_run(which, sc, H).cpu_time_s

        # untimed first runs: the kernel compiles or loads from the disk cache once per process, in the
        # standalone run and in the FMU's own copy of the runtime (its log says how long: kernel_report)
        run(body, short, origin=model.body.origin, progress=False, backend=args.backend)
        first = parse_kernel_report(fmu_run("fmu", short, scene.step).log)
        for which in FMUS[1:]:
            fmu_run(which, short, scene.step)
        for _ in range(max(1, args.repeat)):
            t0 = time.process_time()
            ref = run(body, scene, origin=model.body.origin, progress=False, backend=args.backend)
            keep("standalone", time.process_time() - t0)
            for which in FMUS:
                keep((which, "short"), fmu_cpu(which, short, scene.step))
            for H in Hs:
                _, cpu, doSteps[H], iters[H] = run_core(fmu, Path(tmp) / "x" / "resources", scene, inputs, H)
                keep(("core", H), cpu)
                for which in FMUS:
                    keep((which, H), fmu_cpu(which, scene, H))
    steps = int(round(scene.duration / scene.step))
    cs = best["standalone"]
    # fixed per-run cost of each FMU: its short run minus its doSteps at the per-doStep cost of the long run at h
    h = min(Hs, key=lambda H: abs(H - scene.step))
    fixed = {}
    for which in FMUS:
        per = (best[(which, h)] - best[(which, "short")]) / (doSteps[h] - args.short)
        fixed[which] = best[(which, "short")] - args.short * per
    per_doStep = {(w, H): (best[(w, H)] - fixed[w]) / doSteps[H] for w in FMUS for H in Hs}
    print(f"B1 {model.body.name}/{scene.name}: {len(body.superelements)} SE, {scene.duration:g} s, internal step h = "
          f"{scene.step:g} s ({steps} steps); backend {args.backend} (standalone ran {ref.summary['backend']}), best of "
          f"{args.repeat}, load average {os.getloadavg()[0]:.2f}, {time.strftime('%H:%M UTC', time.gmtime())}")
    print(f"  standalone CPU {cs:.3f} s ({1e6 * cs / steps:.0f} us per internal step; Newton "
          f"{ref.summary['newton_iterations_mean']:.3f} per step)")
    print("  fixed cost per run (unzip, instantiate, initialize, first calls, terminate; from "
          f"{args.short}-doStep runs): " + ", ".join(f"{w} {1e3 * fixed[w]:.1f} ms" for w in FMUS))
    if first:
        print(f"  (the first FMU run of a process also loads the kernel: {first[0]:.3f} s wall in its first kernel calls, "
              f"{'compiled' if first[1] else 'from the disk cache'})")
    print("  per doStep, CPU [us]:")
    print("  | H | doSteps | standalone | fmpy alone (floor C) | pythonfmu layer (floor py - C) | ours (fmu - floor py) "
          "| ours - standalone | core - standalone | fmu/standalone (whole run) | bound (standalone + floor C) "
          "| bound (standalone + floor py) | Newton/doStep (worst) |")
    print("  |---|---|---|---|---|---|---|---|---|---|---|---|")
    for H in Hs:
        n = doSteps[H]
        S, C, P, F = cs / n, per_doStep[("floor C", H)], per_doStep[("floor py", H)], per_doStep[("fmu", H)]
        print(f"  | {1e3 * H:g} ms | {n} | {1e6 * S:.0f} | {1e6 * C:.0f} | {1e6 * (P - C):.0f} | {1e6 * (F - P):.0f} "
              f"| {1e6 * (F - P - S):.0f} | {1e6 * (best[('core', H)] - cs) / n:.0f} | {best[('fmu', H)] / cs:.2f} "
              f"| {(S + C) / S:.2f} | {(S + P) / S:.2f} | {iters[H]:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
