"""What one refresh of the iteration matrix costs on the C runtime: B1 1 SE x 2 modes stiffened at 40 ms.

    python benchmarks/refresh_cost.py [--repeat 20] [--every 2] [--config KEY=V ...]

From states along the 20 s spin-up (every `--every` steps), one step is timed twice, best of `--repeat`
each (wall clock around BodySystem.step, the same Python around both): with the factorization the state
carries (and the last step's iterations set to 1, so that the rule REFRESH_AFTER does not drop it), and
with no factorization (the step builds its matrix at its predictor). Where both take the same Newton
iterations and the first builds no matrix, their difference is one refresh: the superelement's Jacobian,
its assembly with the rotation tangents and the factorization by structure (median and quartiles over
those states). A kept matrix ages fast over a 40 ms step and is mostly rebuilt within the step (it then
takes a third iteration), so only some states qualify; the script says how many.

    python benchmarks/refresh_cost.py --workload [--every 2]

steps once from each of those states without a matrix (a refresh at the predictor, and what the step
refreshes after it) and times nothing: the workload for an instruction count, `valgrind --tool=callgrind
--toggle-collect='ffrf_step*' python benchmarks/refresh_cost.py --workload` (its count is repeatable where
wall time is not); it prints the refreshes it made.
"""
from __future__ import annotations

import os
import time

import numpy as np

from _timing import b1_arguments, b1_spinup


def timed_step(system, state, h, inputs, fresh: bool, repeat: int):
    """(best seconds, iterations, matrices built) of one step from state, with or without its matrix."""
    best, body = float("inf"), system._compiled.body
    for _ in range(repeat):
        system.set_state(state)
        if fresh:
            system._lu = None
        else:
            system.iterations = 1
        v0 = body.get("lu_version")
        t0 = time.perf_counter()
        it = system.step(h, inputs)
        best = min(best, time.perf_counter() - t0)
    return best, it, body.get("lu_version") - v0


def main(argv=None) -> int:
    ap = b1_arguments(__doc__)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--every", type=int, default=2)
    ap.add_argument("--workload", action="store_true", help="step from each state without a matrix, untimed")
    args = ap.parse_args(argv)
    scene, _, system, inputs = b1_spinup(args.config)
    h, n = scene.step, int(round(scene.duration / scene.step))
    states = []
    for k in range(n):
        if k % args.every == args.every // 2:
            states.append(system.get_state())
        system.step(h, inputs)
    if args.workload:
        body, v0 = system._compiled.body, system._compiled.body.get("lu_version")
        for state in states:
            system.set_state(state)
            system._lu = None
            system.step(h, inputs)
        print(f"B1 {' '.join(args.config)}: {len(states)} steps without a matrix, "
              f"{int(body.get('lu_version') - v0)} refreshes (after the spin-up's 500 steps, which refresh at nearly every step)")
        return 0
    diffs, skipped = [], 0
    for state in states:
        kept, it_k, built_k = timed_step(system, state, h, inputs, False, args.repeat)
        fresh, it_f, built_f = timed_step(system, state, h, inputs, True, args.repeat)
        if it_k != it_f or built_k != 0 or built_f != 1:
            skipped += 1
            continue
        diffs.append(fresh - kept)
    print(f"B1 {' '.join(args.config)}: {len(states)} states, {len(diffs)} used ({skipped} where the kept matrix "
          f"was rebuilt in the step or took other iterations); load average {os.getloadavg()[0]:.2f}")
    if diffs:
        q1, med, q3 = np.percentile(1e6 * np.array(diffs), [25, 50, 75])
        print(f"same iterations: one refresh, median {med:.1f} us (quartiles {q1:.1f}-{q3:.1f}); wall, best of {args.repeat} per state")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
