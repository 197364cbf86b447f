"""What one superelement's Jacobian costs on the C runtime: `ffrf_body_superelement` (ffrf_runtime.h) with
its Jacobian blocks and without, at one state of B1's spin-up.

    python benchmarks/jacobian_cost.py [--calls 20000] [--repeat 3] [--config KEY=V ...]

The body steps `--steps` steps of the scene's schedule, then superelement 0's rows are evaluated `--calls`
times at the last stage (p, ydot, R of the C body's work arrays) without the Jacobian, with it, and with it
in a refresh's form (jac = 2: the k_q rows premultiplied by M_bar^-1, motion-driven columns not formed) into
the body's own blocks (work.Fz, work.Fy: a refresh's, zeroed only on the rows added into), the three alternating
`--repeat` times; CPU time per call, best of the repeats (the ctypes call is in all, so the differences are the
Jacobian: its local blocks F_ydot, F_y of superelement.c `jacobian`).
"""
from __future__ import annotations

import ctypes
import os
import time

import numpy as np

from _timing import b1_arguments, b1_spinup
from ffrf_fmu import simulate as sim


def main(argv=None) -> int:
    ap = b1_arguments(__doc__)
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=100)
    args = ap.parse_args(argv)
    scene, body, system, _ = b1_spinup(args.config)
    assert system.backend == "native", system.backend_note
    rows, times = np.empty((args.steps, len(sim.column_names(body)))), np.empty(args.steps)
    system.run_schedule(scene.step, sim.scene_schedule(body, scene), rows, times)
    B = system._compiled.body
    p, yd, R = (B.array(k).copy() for k in ("p", "ydw", "R"))
    ncv = B.array("Fl").size
    F, Fz, Fy = np.zeros(ncv), np.zeros((ncv, ncv)), np.zeros((ncv, ncv))
    fn = B.lib.ffrf_body_superelement
    fn.restype = ctypes.c_int
    fn.argtypes = [ctypes.c_void_p, ctypes.c_int] + [ctypes.c_void_p] * 3 + [ctypes.c_int] + [ctypes.c_void_p] * 3
    inputs, outputs = [a.ctypes.data for a in (p, yd, R)], [a.ctypes.data for a in (F, Fz, Fy)]
    own = [F.ctypes.data, B.array("Fz").ctypes.data, B.array("Fy").ctypes.data]  # a refresh's blocks
    best = {0: float("inf"), 1: float("inf"), 2: float("inf")}
    for _ in range(args.repeat):
        for jac in (0, 1, 2):
            c0 = time.process_time()
            for _ in range(args.calls):
                fn(B.ptr, 0, *inputs, jac, *(own if jac == 2 else outputs))
            best[jac] = min(best[jac], (time.process_time() - c0) / args.calls)
    print(f"B1 {' '.join(args.config)}, superelement 0 after {args.steps} steps; load average {os.getloadavg()[0]:.2f}")
    print(f"  rows alone {1e6 * best[0]:.2f} us per call, with the Jacobian {1e6 * best[1]:.2f} us: "
          f"the Jacobian {1e6 * (best[1] - best[0]):.2f} us, in a refresh's form {1e6 * (best[2] - best[0]):.2f} us "
          f"(CPU, best of {args.repeat} x {args.calls} calls)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
