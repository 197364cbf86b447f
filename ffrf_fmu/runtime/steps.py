"""Splitting a span of time into equal steps: the one rule every run uses (the standalone run, an FMU's
communication step, the full-order reference, the peers, the advisor's grids).

A span within STEP_COUNT_TOLERANCE (relative) of a whole number of steps is that many steps; otherwise
the step is reduced to the next whole number. Never a sliver: a last step of 1e-11 s makes the
iteration matrix nearly the singular F_ydot of the DAE and leaves a lasting high-frequency error in the
reactions.

Runtime module: no import from the rest of ffrf_fmu (it ships inside FMUs).
"""
from __future__ import annotations

import math
from typing import NamedTuple

# 1e-6 of a step: spans handed over by a co-simulation master are differences of communication
# points, t_{k+1} - t_k, rounded at the size of t (1e-16 t); at t = 1e4 s and H = 1e-4 s that is 1e-8
# of a step, well inside. A span that far from whole steps changes each step by at most 1e-6
# relative: nothing the integrator's error (O(h^2)) can see.
STEP_COUNT_TOLERANCE = 1e-6


class Steps(NamedTuple):
    """n equal steps of h = span / n."""

    n: int
    h: float


def whole_steps(span: float, step: float) -> Steps:
    """The fewest equal steps of at most `step` (within STEP_COUNT_TOLERANCE) that make up `span`:
    Steps(n, span / n)."""
    if not (span > 0.0 and step > 0.0) or not math.isfinite(span / step):
        raise ValueError(f"a span of {span!r} s cannot be split into steps of {step!r} s (both must be > 0)")
    ratio = span / step
    n = round(ratio)
    if n < 1 or abs(ratio - n) > STEP_COUNT_TOLERANCE * ratio:
        n = max(1, math.ceil(ratio))
    return Steps(int(n), span / n)


def divides(span: float, step: float) -> bool:
    """Whether `step` makes up `span` in whole steps (whole_steps keeps it, within its tolerance)."""
    n = whole_steps(span, step).n
    return abs(span / step - n) <= STEP_COUNT_TOLERANCE * (span / step)


def communication_grid(span: float, H: float) -> list[float]:
    """The communication points 0, H, 2 H, ... of a run of `span` at a master's fixed step H: the span's
    end is the last point, reached by a whole step when H divides the span (divides) and otherwise by a
    shorter last step; never a point past the span."""
    if not (span > 0.0 and H > 0.0) or not math.isfinite(span / H):
        raise ValueError(f"a span of {span!r} s cannot be split into steps of {H!r} s (both must be > 0)")
    if divides(span, H):
        n = whole_steps(span, H).n
        return [k * H for k in range(n)] + [span]
    n = math.floor(span / H)
    return [k * H for k in range(n + 1)] + [span]
