#!/usr/bin/env python3
"""Benchmark: the native B1 FMU (4 superelements x 6 modes, h = 2 ms) against the standalone run, in a plain C
host and under fmpy, per communication step, with fmpy's zero-work floor measured in the same run.

    python benchmarks/fmu_overhead.py [--duration D] [--comm-step H [H ...]] [--model models/haug_beam.toml]

Runs (best of --repeat interleaved runs of each; CPU time, the stable measure on a shared machine):
  standalone   simulate.run on the C runtime (backend native: the scene's exact drive signals at every
               internal step, recorded every step)
  C host       benchmarks/fmu_host_bench.c: the FMU's binary in a C process (fmi2SetReal of the inputs at
               t_c, fmi2DoStep, fmi2GetReal of every output, per communication step), and in the same
               process the runtime library's body started from the FMU's initial state and stepped with the
               point values the FMU's input rule makes of the same inputs (ffrf_body_advance EXTRAPOLATED): the FMU
               without its FMI layer, the same numbers
  fmu          the FMU under fmpy.simulate_fmu (fmpy's input table, output_interval = H, every output
               recorded, debug logging on)
  floor C      a zero-work C FMU with exactly our FMU's model variables (benchmarks/_fmu_floor.py), run the
               same way: what fmpy alone costs per doStep for this interface
Also: the wall time of instantiate + initialize + the first doStep in the C host (its first repeat: the
binary and the resources freshly read).

Targets (issue: the native FMU): C host / standalone <= 1.05 at H = h; under fmpy, fmu <= 1.1 x (standalone +
floor C), the least any FMU of this interface costs there; instantiate + first doStep <= 20 ms.
"""
from __future__ import annotations

import argparse
import os
import subprocess
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

from _fmu_floor import c_floor  # noqa: E402
from ffrf_fmu.fmu.builder import build_fmu, c_compiler  # noqa: E402
from ffrf_fmu.fmu.native.resource import point_map, images  # noqa: E402
from ffrf_fmu.fmu.run import fmu_input_table, run_fmu  # noqa: E402
from ffrf_fmu.fmu.variables import body_variables  # noqa: E402
from ffrf_fmu.model import load_model, scene_body  # noqa: E402
from ffrf_fmu.reduction import reduce_body  # noqa: E402
from ffrf_fmu.runtime.native import build as runtime_build  # noqa: E402
from ffrf_fmu.simulate import run, scene_inputs  # noqa: E402
from ffrf_fmu.fmu.builder import SceneParameters  # noqa: E402


def host_table(fmu: Path, body, scene, inputs, H: float, path: Path) -> int:
    """The C host's input table (fmu_host_bench.c TABLE): per communication point the FMU's input values
    and the point values of runtime/input_rule.py made of them. Returns the number of communication steps."""
    md = read_model_description(str(fmu))
    n = int(round(scene.duration / H))
    table = fmu_input_table(fmu, inputs, H * np.arange(n + 1))
    names = [name for name in table.dtype.names if name != "time"]
    by = {v.name: v.valueReference for v in md.modelVariables}
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    variables = body_variables(body.ports, body.node_positions, SceneParameters.of_scene(scene).as_config())
    hmap = point_map(variables, body.ports).ravel()
    values = np.zeros(len(variables))
    rows = []
    for k in range(n + 1):
        for name in names:
            values[by[name]] = table[name][k]
        rows.append(np.concatenate([[table[name][k] for name in names], np.where(hmap >= 0, values[hmap], 0.0)]))
    head = [len(names), hmap.size, len(outs), *[by[nm] for nm in names], *outs]
    np.concatenate([np.array(head, dtype=float), np.concatenate(rows)]).astype("<f8").tofile(path)
    return n


def host_command(fmu: Path, scene, tmp: Path) -> tuple[list, object]:
    """The FMU unpacked into tmp, benchmarks/fmu_host_bench.c compiled there: the host's first six arguments
    (the host, FMU_BINARY, RESOURCE_URI, GUID, RUNTIME_LIBRARY, IMAGE of the scene's term set) and the
    FMU's model description."""
    x = tmp / "x"
    zipfile.ZipFile(fmu).extractall(x)
    md = read_model_description(str(fmu))
    binary = x / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    image = tmp / "image.bin"
    image.write_bytes(images((x / "resources" / "body.bin").read_bytes())[scene.terms])
    host = tmp / "fmu_host_bench"
    done = subprocess.run([c_compiler(), "-std=c11", "-O2", "-o", str(host), str(ROOT / "benchmarks" / "fmu_host_bench.c"),
                           "-ldl"], capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(done.stderr)
    return [str(host), str(binary), (x / "resources").as_uri(), md.guid, str(runtime_build.library(False)), str(image)], md


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    ap.add_argument("--scene", default="spinup")
    ap.add_argument("--duration", type=float, default=None, help="simulated time [s] (default: the scene's)")
    ap.add_argument("--comm-step", type=float, nargs="+", default=None,
                    help="communication steps H [s] (default: h, 5 h, 10 h with the scene's internal step h)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, interleaved; the best counts (default 3)")
    args = ap.parse_args(argv)
    overrides = [f"duration={args.duration}"] if args.duration else []
    model = load_model(args.model, overrides)
    scene = model.scene(args.scene)
    Hs = args.comm_step or [scene.step * m for m in (1, 5, 10)]
    body = reduce_body(scene_body(model.body, scene)).data
    inputs = scene_inputs(body, scene)
    best: dict = {}
    first_wall = []

    def keep(key, cpu):
        best[key] = min(best.get(key, np.inf), cpu)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        fmu = build_fmu(args.model, tmp / "body.fmu", scene=scene.name, overrides=overrides)
        floor = c_floor(fmu, tmp)
        host, md = host_command(fmu, scene, tmp)
        tables = {H: (tmp / f"table_{H:g}.bin") for H in Hs}
        steps = {H: host_table(fmu, body, scene, inputs, H, tables[H]) for H in Hs}
        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        run(body, scene, origin=model.body.origin, progress=False)  # untimed: the runtime library loads
        for _ in range(max(1, args.repeat)):
            t0 = time.process_time()
            ref = run(body, scene, origin=model.body.origin, progress=False)
            keep("standalone", time.process_time() - t0)
            for H in Hs:
                done = subprocess.run([*host, str(tables[H]), str(steps[H]), repr(H), "1",
                                       str(max(1, round(H / scene.step)))],
                                      capture_output=True, text=True, timeout=3600)
                if done.returncode:
                    raise RuntimeError(f"fmu_host_bench exit {done.returncode}: {done.stderr[-2000:]}")
                words = done.stdout.split()
                got = dict(zip(words[::2], map(float, words[1::2])))
                keep(("host", H), got["fmu_cpu"])
                keep(("runtime", H), got["runtime_cpu"])
                first_wall.append(got["first_wall"])
                for which, path in (("fmu", fmu), ("floor C", floor)):
                    out = run_fmu(path, scene, inputs, H, record=outputs)
                    if not out.reached:
                        raise RuntimeError(f"{which} at H = {H:g} s stopped early at t = {out.t[-1]}: {out.log[-1:]}")
                    keep((which, H), out.cpu_time_s)
    n_int = int(round(scene.duration / scene.step))
    cs = best["standalone"]
    print(f"B1 {model.body.name}/{scene.name}: {len(body.superelements)} SE, {scene.duration:g} s, internal step h = "
          f"{scene.step:g} s ({n_int} steps); standalone on {ref.summary['backend']}; best of {args.repeat}, load "
          f"average {os.getloadavg()[0]:.2f}, {time.strftime('%H:%M UTC', time.gmtime())}")
    print(f"  standalone CPU {cs:.3f} s ({1e6 * cs / n_int:.1f} us per internal step)")
    print(f"  C host: instantiate + initialize + first doStep {1e3 * min(first_wall):.1f} ms wall (first run of "
          f"each, best; worst {1e3 * max(first_wall):.1f} ms)")
    print("  | H | doSteps | standalone CPU [s] | C host: FMU [s] | C host: runtime alone [s] | FMU / standalone (C host) "
          "| FMU / runtime alone | fmpy: FMU [s] | fmpy: floor C [s] | fmpy FMU / (standalone + floor C) |")
    print("  |---|---|---|---|---|---|---|---|---|---|")
    for H in Hs:
        f, r, p, c = best[("host", H)], best[("runtime", H)], best[("fmu", H)], best[("floor C", H)]
        print(f"  | {1e3 * H:g} ms | {steps[H]} | {cs:.3f} | {f:.3f} | {r:.3f} | {f / cs:.3f} | {f / r:.3f} | {p:.3f} "
              f"| {c:.3f} | {p / (cs + c):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
