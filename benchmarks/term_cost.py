"""Cost per step of the term sets against longer chains of linear superelements: the two fixes
of what one superelement misses on a centrifugally soft body. models/disk_rotor.toml, 2 modes per
superelement, h = 10 ms, the first STEPS steps of the spin-up (Newton works there), best of REPEAT (CPU
time of this process), ratios to 1 SE `linear` measured in the same run, for each backend.

    python benchmarks/term_cost.py [--backend numpy|native|both]
"""
from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from _timing import cpu_per_step  # noqa: E402

STEPS, REPEAT = 300, 3
CONFIGS = [(1, "linear"), (2, "linear"), (4, "linear"), (8, "linear"), (1, "gyroscopic"), (1, "full"), (2, "full")]


def cost_per_step(n_se: int, terms: str, backend: str) -> float:
    return cpu_per_step("models/disk_rotor.toml", "spinup", [f"superelements={n_se}", f"terms={terms}"], STEPS, REPEAT,
                        backend)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--backend", choices=("numpy", "native", "both"), default="both")
    backends = ("numpy", "native") if p.parse_args().backend == "both" else (p.parse_args().backend,)
    for backend in backends:
        costs = {c: cost_per_step(*c, backend) for c in CONFIGS}
        base = costs[(1, "linear")]
        print(f"disk_rotor, 2 modes, h = 10 ms, {STEPS} steps, best of {REPEAT} (CPU), backend {backend}:")
        for (n, terms), c in costs.items():
            print(f"  {n} SE {terms:10s} {1e3 * c:7.3f} ms/step   x {c / base:.2f}")


if __name__ == "__main__":
    main()
