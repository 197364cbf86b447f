"""Reduction cost of a solid against its dof count (docs/solids.md, "Scale"): a steel bar 8 x 1 x 1 of
quadratic hexahedra (hex27), divisions (4k, k, k), two averaging end-face frames, 8 free-free modes.
Each size runs in a fresh process: CPU time of the assembly and of each reduction stage (one thread:
SuperLU and ARPACK are serial, BLAS is limited to one thread; on an idle machine wall = CPU, on a shared
one the wall time measures the load, printed beside it), and the peak resident memory of that process
(ru_maxrss). Then the step cost of the reduced body at two mesh sizes:
the same frames and modes give the same reduced sizes, so the same cost per step.

    python benchmarks/reduction_scale.py                 # k = 3, 5, 8, 10, 13 (3.7k to 230k dofs)
    python benchmarks/reduction_scale.py --k 3 10         # chosen sizes
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def one(k: int, modes: int = 8) -> dict:
    """Assemble and reduce the bar with divisions (4k, k, k) in this process."""
    import resource

    import numpy as np

    from ffrf_fmu.reduction_sparse import reduce_solid
    from ffrf_fmu.solid.frames import Frame, select_nodes
    from ffrf_fmu.solid.mesh import Material, assemble, box_points

    t0, c0 = time.perf_counter(), time.process_time()
    fe = assemble(box_points((8.0, 1.0, 1.0), (4 * k, k, k)), Material(2e11, 0.3, 7800.0), "hex27")
    c1 = time.process_time()
    frames = [Frame(n, select_nodes(fe.coords, {}, {"plane": {"point": [x, 0, 0], "normal": [1, 0, 0]}}, 8.0),
                    "averaging", np.array([x, 0.5, 0.5])) for n, x in (("a", 0.0), ("b", 8.0))]
    c15 = time.process_time()
    red = reduce_solid(fe, frames, n_modes=modes)
    t2, c2 = time.perf_counter(), time.process_time()
    return {"k": k, "dofs": fe.n_dof, "assemble_s": c1 - c0, "reduce_s": c2 - c15, "wall_s": t2 - t0,
            "stages_s": red.timings,
            "peak_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "f1_hz": float(red.data.frequencies_hz[0]), "reduced_n": red.data.n, "lu_fill": red.lu_fill}


def step_cost(k: int, steps: int = 400) -> float:
    """CPU seconds per step of the reduced bar (frame a fixed, b free, under gravity) on the native (C)
    backend: what a body's step costs with this mesh's reduction."""
    import numpy as np

    from ffrf_fmu.model import Initial, Scene
    from ffrf_fmu.reduction_sparse import reduce_solid
    from ffrf_fmu.runtime.data import BodyData, PortData
    from ffrf_fmu.simulate import build_system
    from ffrf_fmu.solid.frames import Frame, select_nodes
    from ffrf_fmu.solid.mesh import Material, assemble, box_points

    fe = assemble(box_points((8.0, 1.0, 1.0), (4 * k, k, k)), Material(2e11, 0.3, 7800.0), "hex27")
    frames = [Frame(n, select_nodes(fe.coords, {}, {"plane": {"point": [x, 0, 0], "normal": [1, 0, 0]}}, 8.0),
                    "averaging", np.array([x, 0.5, 0.5])) for n, x in (("a", 0.0), ("b", 8.0))]
    red = reduce_solid(fe, frames, n_modes=8)
    body = BodyData("bar", (red.data,), np.array([f.point for f in frames]),
                    (PortData("a", 0, "motion", "motion"), PortData("b", 1, "force", "force")))
    scene = Scene(name="s", duration=steps * 1e-4, step=1e-4, rho_inf=0.8, terms="linear", gravity=(0.0, -9.81, 0.0),
                  drives=(), loads=(), initial=Initial())
    system, inputs = build_system(body, scene, backend="native")
    system.step(1e-4, inputs)  # untimed first step
    t = time.process_time()
    for _ in range(steps):
        system.step(1e-4, inputs)
    return (time.process_time() - t) / steps


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", type=int, nargs="*", default=[3, 5, 8, 10, 13])
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--step", type=int, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one is not None:
        print(json.dumps(one(a.one)))
        return
    if a.step is not None:
        print(json.dumps({"k": a.step, "s_per_step": step_cost(a.step)}))
        return
    print(f"CPU seconds; load average at start {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'k':>3} {'dofs':>8} {'assemble s':>11} {'reduce s':>9} {'shift s':>8} {'LU s':>6} {'modes s':>8} "
          f"{'static s':>9} {'LU fill':>9} {'peak MB':>8} {'wall s':>7} {'load':>5} {'f1 Hz':>9}")
    for k in a.k:
        load = os.getloadavg()[0]
        out = subprocess.run([sys.executable, __file__, "--one", str(k)], capture_output=True, text=True)
        if out.returncode:
            print(f"{k:>3} failed: {out.stderr.strip().splitlines()[-1]}")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        s = r["stages_s"]
        print(f"{k:>3} {r['dofs']:>8} {r['assemble_s']:>11.1f} {r['reduce_s']:>9.1f} {s['shift']:>8.1f} "
              f"{s['factor']:>6.1f} {s['modes']:>8.1f} {s['attachment']:>9.1f} {r['lu_fill']:>9.2e} {r['peak_MB']:>8.0f} "
              f"{r['wall_s']:>7.0f} {load:>5.1f} {r['f1_hz']:>9.3f}",
              flush=True)
    for k in (min(a.k), max(a.k)):
        out = subprocess.run([sys.executable, __file__, "--step", str(k)], capture_output=True, text=True)
        r = json.loads(out.stdout.strip().splitlines()[-1]) if not out.returncode else None
        print(f"step cost, k = {k}: " + (f"{1e6 * r['s_per_step']:.0f} us/step (native backend, CPU)" if r else
                                          f"failed: {out.stderr.strip().splitlines()[-1]}"), flush=True)


if __name__ == "__main__":
    main()
