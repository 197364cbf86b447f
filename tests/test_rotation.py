"""SO(3) helpers (runtime/rotation.py) against exact arithmetic."""
from fractions import Fraction
from math import factorial

import numpy as np
import pytest

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


@pytest.mark.parametrize("scale", [1e-4, 0.05, 0.5, 2.5])
def test_exp_log_round_trip_and_tangent(scale):
    """exp/log round trip and the tangent (right Jacobian) by central differences of log, at small
    and large angles (the coefficient series switch at 1e-5 and 2 rad, logm's at 1e-2 rad)."""
    rng = np.random.default_rng(1)
    a = scale * rng.normal(size=(6, 3)) / np.sqrt(3)
    R = rot.expm(a)
    assert np.allclose(np.swapaxes(R, -1, -2) @ R, np.eye(3), atol=1e-14)
    assert np.allclose(rot.logm(R), a, atol=1e-13)
    # exp(a + da) = exp(a) exp(T(a) da) to first order; central difference, error O(eps^2)
    eps = 1e-6
    for k in range(3):
        da = np.zeros(3)
        da[k] = eps
        d = rot.logm(np.swapaxes(rot.expm(a - da), -1, -2) @ rot.expm(a + da)) / (2 * eps)
        assert np.allclose(d, rot.tangent(a)[:, :, k], atol=1e-8)


def test_logm_near_pi():
    """At and next to pi, where the skew part vanishes, the axis comes from the symmetric part."""
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    for t in (np.pi - 1e-3, np.pi - 1e-7, np.pi):
        assert np.allclose(rot.logm(rot.expm(t * axis)), t * axis, atol=1e-8)


def test_rotation_defect_and_is_rotation_share_one_check():
    """rotation_defect gives max |R^T R - I| and det R exactly on matrices where both are known; is_rotation
    accepts at ROTATION_TOL and refuses just above it, a reflection, a non-finite entry and a wrong shape."""
    R = rot.expm(np.array([0.3, -1.2, 0.7]))
    d = rot.rotation_defect(R.ravel().tolist())
    assert d.orthonormality < 1e-15 and abs(d.det - 1.0) < 1e-15
    # a reflection is orthonormal with det -1
    d = rot.rotation_defect(np.diag([1.0, 1.0, -1.0]).ravel().tolist())
    assert d.orthonormality == 0.0 and d.det == -1.0
    # (1 + s) I: every diagonal entry of R^T R - I is (1 + s)^2 - 1, the off-diagonal ones 0
    s = 0.9 * rot.ROTATION_TOL / 2
    assert rot.rotation_defect(((1 + s) * np.eye(3)).ravel().tolist()).orthonormality == pytest.approx((1 + s) ** 2 - 1)
    assert rot.is_rotation((1 + s) * np.eye(3))
    assert not rot.is_rotation((1 + 1.2 * rot.ROTATION_TOL / 2) * np.eye(3))
    assert not rot.is_rotation(np.diag([1.0, 1.0, -1.0]))
    bad = R.copy()
    bad[1, 2] = np.nan
    assert not rot.is_rotation(bad)
    assert not rot.is_rotation(np.eye(2))
