"""Verdicts with a margin (docs/stability.md, "Marginal points"): a map point whose verdict could flip
under round-off is re-run with its initial state perturbed at `PERTURBATION` relative and at the
neighbour step of the map's grid; a point whose verdict changes is `marginal`, never stable or unstable.

A verdict could flip (`could_flip`) when the run failed in the last `LATE_FRACTION` of its duration,
when a bound (energy growth, tip deflection) was crossed or missed by less than the factor
`BOUND_FACTOR`, or when Newton stopped at its iteration limit late in the run."""
from __future__ import annotations

import dataclasses
from typing import Callable

PERTURBATION = 1e-9  # relative perturbation of the initial state of a re-run
LATE_FRACTION = 0.1  # a failure in the last 10 % of the run could be round-off's
BOUND_FACTOR = 2.0  # a bound met within this factor either way could be round-off's
STABLE, UNSTABLE, MARGINAL = "stable", "unstable", "marginal"


@dataclasses.dataclass(frozen=True)
class Point:
    """One map point as the margin check needs it: the run's end, its failure and its bound ratios
    (value over bound: > 1 crossed), e.g. energy growth over ENERGY_GROWTH, peak deflection over L."""

    unstable: bool
    t_end: float
    duration: float
    failure: str = ""
    bound_ratios: tuple[float, ...] = ()


def could_flip(p: Point) -> bool:
    """True when the point's verdict could change with the last bits of the arithmetic."""
    if p.unstable and p.t_end >= (1.0 - LATE_FRACTION) * p.duration:
        return True
    if any(1.0 / BOUND_FACTOR <= r <= BOUND_FACTOR for r in p.bound_ratios):
        return True
    return False


def verdict(unstable: bool, rechecks: list[bool]) -> str:
    """The point's class: `marginal` when any re-run's verdict (unstable or not) differs from its own."""
    if any(bool(u) != bool(unstable) for u in rechecks):
        return MARGINAL
    return UNSTABLE if unstable else STABLE


def neighbour_steps(step: float, grid: tuple[float, ...]) -> list[float]:
    """The grid's steps next to `step` (the one below and the one above, where there are)."""
    g = sorted(set(float(h) for h in grid))
    if step not in g:
        return []
    i = g.index(step)
    return [g[j] for j in (i - 1, i + 1) if 0 <= j < len(g)]


def classify(p: Point, step: float, grid: tuple[float, ...],
             rerun: Callable[[float, float], bool]) -> str:
    """`verdict` of a point: when it `could_flip`, re-run it (`rerun(step, perturbation)` -> unstable)
    with the initial state perturbed by PERTURBATION at its own step, and unperturbed at the neighbour
    step of the grid on the side where the verdict must be the same if the map is monotone in the step
    (the larger step for an unstable point, the smaller one for a stable point): a stable point whose
    smaller step fails, or an unstable one whose larger step runs through, is round-off-marginal."""
    if not could_flip(p):
        return UNSTABLE if p.unstable else STABLE
    rechecks = [rerun(step, PERTURBATION)]
    for h in neighbour_steps(step, grid):
        if (h > step) == p.unstable:
            rechecks.append(rerun(h, 0.0))
    return verdict(p.unstable, rechecks)
