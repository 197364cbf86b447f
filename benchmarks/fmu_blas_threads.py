#!/usr/bin/env python3
"""Benchmark: the B1 FMU under fmpy with the default BLAS threads vs OPENBLAS_NUM_THREADS=1.

    python benchmarks/fmu_blas_threads.py [--duration 1] [--repeat 2]

Builds the B1 FMU (models/haug_beam.toml, spinup: 4 superelements, 6 modes, h = 2 ms) and runs
it with fmpy.simulate_fmu (hub at rest, 1 N tip force) in fresh processes that import fmpy only,
not ffrf_fmu: once with the BLAS thread variables removed from the environment (OpenBLAS then
starts one thread per core) and once with OPENBLAS_NUM_THREADS=OMP_NUM_THREADS=1. Prints the best
wall time of each and their ratio; the FMU limits BLAS to one thread during its own calls
(fmu/core.py, threadpoolctl), so the ratio should be about 1.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

RUN = r"""
import sys, time, fmpy
from threadpoolctl import threadpool_info
t = time.perf_counter()
fmpy.simulate_fmu(sys.argv[1], stop_time=float(sys.argv[2]), output_interval=2e-3, start_values={"tip.f[3]": 1.0})
wall = time.perf_counter() - t
print(wall, max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    from ffrf_fmu.fmu.builder import build_fmu

    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_fmu(ROOT / "models" / "haug_beam.toml", Path(tmp) / "B1.fmu", scene="spinup")
        blas = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
        base = {k: v for k, v in os.environ.items() if k not in blas and k != "PYTHONPATH"}
        envs = {"default threads": base, "OPENBLAS_NUM_THREADS=1": {**base, "OPENBLAS_NUM_THREADS": "1",
                                                                     "OMP_NUM_THREADS": "1"}}
        best = {}
        for _ in range(args.repeat):
            for label, env in envs.items():
                out = subprocess.run([sys.executable, "-c", RUN, str(fmu), str(args.duration)], env=env, cwd=tmp,
                                     capture_output=True, text=True, check=True)
                wall, threads = out.stdout.split()
                best[label] = min(best.get(label, (float("inf"), 0)), (float(wall), int(threads)))
    print(f"B1 FMU under fmpy, {args.duration:g} s simulated, best of {args.repeat}, {os.cpu_count()} cores")
    for label, (wall, threads) in best.items():
        print(f"  {label:24s} {wall:7.2f} s   (host's BLAS threads outside the FMU's calls: {threads})")
    ratio = best["default threads"][0] / best["OPENBLAS_NUM_THREADS=1"][0]
    print(f"  ratio default / one thread: {ratio:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
