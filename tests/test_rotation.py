"""SO(3) helpers (runtime/rotation.py) against exact arithmetic."""
from fractions import Fraction
from math import factorial

import numpy as np

from ffrf_fmu.runtime import rotation as rot


def _exact_series(t: float, offset: int) -> Fraction:
    """sum_k (-1)^k t^(2k) / (2k + offset)! in exact rational arithmetic on the float t (|t| <= 4:
    the terms fall below 1e-40 of the first within 30 terms)."""
    x2 = Fraction(t) ** 2
    return sum((-1) ** k * x2**k / factorial(2 * k + offset) for k in range(30))


def test_tangent_coefficients_are_exact_to_round_off():
    """sin(t)/t, (1 - cos t)/t^2 and (t - sin t)/t^3, the coefficients of exp and its tangent, to a
    few eps relative at every angle, in particular on both sides of the series switches (the closed
    forms lose ~eps/t^2 to cancellation: 2e-6 at t = 1e-5). Bound 4 eps: the evaluation of a
    polynomial or of sin and a division rounds a few times; measured <= 1.6 eps."""
    eps = np.finfo(float).eps
    ts = np.concatenate([np.geomspace(1e-8, 3.5, 160), [1e-5 * (1 - 1e-9), 1e-5, 1e-5 * (1 + 1e-9),
                                                        2.0 * (1 - 1e-12), 2.0, 2.0 * (1 + 1e-12)]])
    a, b, c = rot._coefficients(np.column_stack([ts, 0 * ts, 0 * ts]))  # |theta| = sqrt(t^2) = t exactly
    worst = 0.0
    for t, values in zip(ts, zip(a, b, c)):
        for offset, v in zip((1, 2, 3), values):
            exact = _exact_series(float(t), offset)
            worst = max(worst, abs(float((Fraction(float(v)) - exact) / exact)))
    assert worst < 4 * eps, worst
