"""Cost per step of geometric stiffening and of the term set `full`, as ratios to `linear` measured in
the same run. B1 (haug_beam spinup), 2 modes per superelement, h = 10 ms, the first 500
steps after one untimed step (the spin-up, where Newton works), 1 and 4 superelements, and 1 stiffened against 8 linear; best of 3 repetitions per
configuration (CPU time of this process).

    python benchmarks/stiffening_cost.py
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from _timing import cpu_per_step  # noqa: E402

STEPS, REPEAT = 500, 3
CONFIGS = {
    "linear": [],
    "linear + stiffening": ["stiffening=true"],
    "gyroscopic": ["terms=gyroscopic"],
    "full": ["terms=full"],
    "full + stiffening": ["terms=full", "stiffening=true"],
}


def cost_per_step(overrides):
    return cpu_per_step("models/haug_beam.toml", "spinup", overrides, STEPS, REPEAT)


def main():
    for n in (1, 4):
        base = [f"superelements={n}", "modes=2", "step=0.01"]
        costs = {name: cost_per_step(base + ov) for name, ov in CONFIGS.items()}
        print(f"B1, {n} superelement(s), 2 modes, h = 10 ms, {STEPS} steps, best of {REPEAT} (CPU):")
        for name, c in costs.items():
            print(f"  {name:22s} {1e3 * c:7.3f} ms/step   x {c / costs['linear']:.2f}")
    # accuracy at equal footing: one stiffened superelement (+0.16 % on B1) against the linear chain
    # that gets closest without stiffening (8 SE, +0.24 %; docs/accuracy.md)
    one = cost_per_step(["superelements=1", "modes=2", "step=0.01", "stiffening=true"])
    eight = cost_per_step(["superelements=8", "modes=2", "step=0.01"])
    print(f"1 SE + stiffening {1e3 * one:.3f} ms/step against 8 SE linear {1e3 * eight:.3f} ms/step: x {one / eight:.2f}")


if __name__ == "__main__":
    main()
