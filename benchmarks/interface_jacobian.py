#!/usr/bin/env python3
"""Benchmark: the interface-Jacobian master (linearly implicit coupling) with the coupling Jacobian
from the FMUs' directional derivatives ("fmu") against finite differences of the sweep ("fd").

    python benchmarks/interface_jacobian.py [--H 0.01] [--split-duration 0.5] [--motor-duration 2]
                                            [--repeat 2] [--model models/haug_beam.toml]

Cases of docs/stability.md: "split" (B1 cut into two body FMUs, hub spun up; both provide
directional derivatives) and "motor" (B5: the beam FMU with a free hub and the hub-drive FMU,
which provides none: its derivative is a forward difference of its own step). Each run is
Gauss-Seidel, interface_jacobian=True; fd and fmu runs alternate, --repeat times each. Prints per
case: sweeps per step, wall and CPU time (best of the repeats; on a shared machine the CPU time
is the stable measure), the ratio fmu/fd of both, and how far the two runs are apart (max tip
deflection difference over the peak; hub speed for the motor).
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

from ffrf_fmu.studies import stability as st  # noqa: E402


def timed(case, H, duration, jacobian):
    c0, w0 = time.process_time(), time.perf_counter()
    run = case.run(H, "gauss-seidel", duration=duration, interface_jacobian=True, jacobian=jacobian)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    if run.stopped_early:
        raise SystemExit(f"{jacobian}: stopped early: {run.stopped_early}")
    return run, wall, cpu


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--H", type=float, default=0.01)
    ap.add_argument("--split-duration", type=float, default=0.5)
    ap.add_argument("--motor-duration", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="ffrf_ij_") as tmp:
        for kind, duration in (("split", args.split_duration), ("motor", args.motor_duration)):
            case = st.CosimCase(kind, args.model, Path(tmp) / kind, st.CosimSettings())
            timed(case, args.H, 2 * args.H, "fmu")  # warm-up: imports, the C runtime, FMU extraction
            best = {"fd": (np.inf, np.inf), "fmu": (np.inf, np.inf)}
            runs = {}
            for _ in range(args.repeat):
                for jac in ("fd", "fmu"):
                    run, wall, cpu = timed(case, args.H, duration, jac)
                    runs[jac] = run
                    best[jac] = (min(best[jac][0], wall), min(best[jac][1], cpu))
            fd, fmu = runs["fd"], runs["fmu"]
            peak = np.max(np.abs(fd.deflection))
            print(f"{kind}: H = {args.H * 1e3:g} ms, {duration:g} s, {len(fd.t) - 1} steps")
            for jac in ("fd", "fmu"):
                print(f"  {jac:4s} sweeps/step {runs[jac].sweeps:4.1f}   wall {best[jac][0]:7.2f} s   "
                      f"cpu {best[jac][1]:7.2f} s")
            print(f"  fmu/fd: wall {best['fmu'][0] / best['fd'][0]:.2f}, cpu {best['fmu'][1] / best['fd'][1]:.2f}")
            print(f"  max |deflection fmu - fd| / peak {np.max(np.abs(fmu.deflection - fd.deflection)) / peak:.2e}")
            if kind == "motor":
                print(f"  max |hub speed fmu - fd| / peak {np.nanmax(np.abs(fmu.speed - fd.speed)) / np.nanmax(np.abs(fd.speed)):.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
