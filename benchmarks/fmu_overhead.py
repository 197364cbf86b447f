#!/usr/bin/env python3
"""Benchmark: B1 (4 superelements) through the FMU under fmpy vs the standalone run.

    python benchmarks/fmu_overhead.py [--duration 2] [--comm-step H] [--model models/haug_beam.toml]

Prints three wall times for the same scene, internal step and number of internal steps:
  standalone   simulate.run_scene (exact drive signals at every internal step)
  core         the FMU's BodyCoSim in-process (the FMU's input rule, no FMI layers)
  fmu          the built FMU under fmpy.simulate_fmu (pythonfmu + fmpy + input table + recorder)
and the ratios fmu/standalone (what a user sees), core/standalone (cost of the input rule: the
extrapolated hub motion changes the Newton iterations) and (fmu - core) per communication step
(the FMI wrapper overhead).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ffrf_fmu.fmu.builder import build_from_model  # noqa: E402
from ffrf_fmu.fmu.core import BodyCoSim  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.simulate import run_scene, scene_inputs  # noqa: E402
from ffrf_fmu.validate import run_fmu  # noqa: E402


def run_core(fmu_resources: Path, scene, inputs, H: float) -> tuple[float, int]:
    core = BodyCoSim.from_resources(fmu_resources)
    pv_fields = ("r", "v", "R", "w", "f", "t")

    def set_inputs(t):
        vals = inputs(t)
        for p in core.data.ports:
            for f in pv_fields:
                ix = core.index[(p.name, f)]
                if core.causality[ix[0]] == "input":
                    core.values[ix] = np.ravel(getattr(vals[p.name], f))

    t0 = time.perf_counter()
    core.setup_experiment(0.0)
    core.enter_initialization_mode()
    set_inputs(0.0)
    core.exit_initialization_mode()
    n = int(round(scene.duration / H))
    for k in range(n):
        set_inputs(k * H)
        rep = core.do_step(k * H, H)
        if not rep.ok:
            raise RuntimeError(rep.message)
    return time.perf_counter() - t0, n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    ap.add_argument("--scene", default="spinup")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated time [s] (default 2)")
    ap.add_argument("--comm-step", type=float, default=None, help="communication step (default: internal step)")
    args = ap.parse_args(argv)
    overrides = [f"duration={args.duration}"]
    model = load_model(args.model, overrides)
    scene = model.scene(args.scene)
    H = args.comm_step or scene.step

    t0 = time.perf_counter()
    ref = run_scene(model, scene.name)
    wall_ref = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_from_model(args.model, Path(tmp) / "body.fmu", scene=scene.name, overrides=overrides)
        import zipfile

        zipfile.ZipFile(fmu).extractall(Path(tmp) / "x")
        wall_core, n = run_core(Path(tmp) / "x" / "resources", scene, scene_inputs(ref.body, scene), H)
        res, wall_fmu, log = run_fmu(fmu, scene, scene_inputs(ref.body, scene), H)
    if abs(res["time"][-1] - scene.duration) > 1e-9:
        print(f"FMU run stopped early at t = {res['time'][-1]}: {log[-1:]}")
        return 1
    steps = int(round(scene.duration / scene.step))
    print(f"B1 {model.body.name}/{scene.name}: {len(ref.body.superelements)} SE, {args.duration:g} s, "
          f"internal step {scene.step:g} s ({steps} steps), communication step {H:g} s ({n} doStep)")
    print(f"  standalone  {wall_ref:8.2f} s  ({1e3 * wall_ref / steps:.2f} ms/step)")
    print(f"  core        {wall_core:8.2f} s  ({1e3 * wall_core / steps:.2f} ms/step)")
    print(f"  fmu (fmpy)  {wall_fmu:8.2f} s  ({1e3 * wall_fmu / steps:.2f} ms/step)")
    print(f"  ratio fmu/standalone  {wall_fmu / wall_ref:.2f}")
    print(f"  ratio core/standalone {wall_core / wall_ref:.2f}  (the FMU's input rule vs exact signals)")
    print(f"  FMI layers: {1e3 * (wall_fmu - wall_core) / n:.2f} ms per communication step")
    return 0


if __name__ == "__main__":
    sys.exit(main())
