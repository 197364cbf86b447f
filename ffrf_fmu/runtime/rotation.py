"""The one SO(3) toolkit of the package: skew, cross, exponential, its tangent, logarithm, the
elastic rotation map `vect` and the rotation check.

Every stage imports it from here (the FE model, linearization, the reference beam, the master,
the studies): it lives in runtime/ because runtime/ ships inside each FMU. Its C twins are
`ffrf_skew`, `ffrf_cross`, `ffrf_expm`, `ffrf_tangent`, `ffrf_logm` of runtime/native/so3.c (checked
through whole runs against the numpy backend in tests/test_backends.py).

Conventions: rotations are matrices R (columns = rotated axes in fixed axes), updated on the
right, R <- R exp(skew(theta)), with theta in the rotated (body) axes. All functions accept
stacks (..., 3) / (..., 3, 3) so that the body equations vectorize over nodes and superelements.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

# An input rotation matrix is accepted when max |R^T R - I| <= ROTATION_TOL and det R > 0 (runtime/body.py,
# fmu/signals.py; the FMU variable descriptions quote it)
ROTATION_TOL = 1e-6
_EPS = 1e-5  # below this angle 1 - t^2/6 and 1 + t^2/6 equal sin(t)/t and t/sin(t) to round-off (next term t^4/120)

# (t - sin t)/t^3 = sum_k (-1)^k t^(2k) / (2k+3)!: the closed form loses ~eps t/(t - sin t) ~ 6 eps/t^2 to
# cancellation (2e-6 relative at t = 1e-5), so below t = 2 the series is summed instead. Twelve terms
# (up to t^22) leave a truncation of 4^12/27! = 1.5e-21 at t = 2; at and above 2 the closed form loses
# at most ~2 eps. Measured against 50-digit mpmath (tests/test_invariants.py): <= 3e-16 relative.
_C_SWITCH = 2.0
_C_SERIES = tuple((-1) ** k / math.factorial(2 * k + 3) for k in range(12))[::-1]  # Horner order


_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0


_CROSS = _LEVI_CIVITA.reshape(3, 9).T.copy()  # (a outer b).ravel() @ _CROSS = a x b
_VECT = -0.5 * _CROSS  # Q.ravel() @ _VECT = axial vector of the skew part of Q
_TRACE = np.eye(3).ravel()


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over broadcast stacks: one outer product and one matmul, far faster than np.cross
    on the tiny arrays of the body equations."""
    outer = a[..., :, None] * b[..., None, :]
    return outer.reshape(outer.shape[:-2] + (9,)) @ _CROSS


_SKEW = np.einsum("ijk->kij", -_LEVI_CIVITA).reshape(3, 9)  # a @ _SKEW = skew(a).ravel()


def skew(a: np.ndarray) -> np.ndarray:
    """skew(a) b = a x b (one matmul with a constant operator, for stacks of vectors)."""
    a = np.asarray(a, dtype=float)
    return (a @ _SKEW).reshape(a.shape[:-1] + (3, 3))


def _coefficients(theta: np.ndarray):
    """sin(t)/t, (1 - cos t)/t^2, (t - sin t)/t^3 for t = |theta|, each to a few eps relative for
    every t: b as (sin(t/2)/(t/2))^2 / 2, free of the cancellation in 1 - cos t; c by its series
    below _C_SWITCH."""
    t2 = np.einsum("...i,...i->...", theta, theta)
    t = np.sqrt(t2)
    small = t < _EPS
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(ts) / ts)
    half = np.where(small, 1.0, 0.5 * t)
    b = np.where(small, 0.5 - t2 / 24.0, 0.5 * (np.sin(half) / half) ** 2)
    series = np.zeros_like(t2)
    t2s = np.minimum(t2, _C_SWITCH**2)  # where the series is not used: no overflow on huge angles
    for coef in _C_SERIES:
        series = series * t2s + coef
    tl = np.where(t < _C_SWITCH, _C_SWITCH, t)
    c = np.where(t < _C_SWITCH, series, (tl - np.sin(tl)) / tl**3)
    return a, b, c


def _quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of the unit quaternion q = (w, v): (w^2 - v.v) I + 2 v v^T + 2 w skew(v)."""
    w, v = q[0], q[1:]
    return (w * w - v @ v) * np.eye(3) + 2.0 * np.outer(v, v) + 2.0 * w * skew(v)


def _quadratic_form(f, n: int) -> np.ndarray:
    """B (n*n, m) with f(q).ravel() = (q outer q).ravel() @ B for a quadratic f (polarization)."""
    e = np.eye(n)
    B = np.zeros((n, n, np.size(f(e[0]))))
    for a in range(n):
        for b in range(n):
            B[a, b] = np.ravel(f(e[a]) if a == b else 0.5 * (f(e[a] + e[b]) - f(e[a]) - f(e[b])))
    return B.reshape(n * n, -1)


# (16, 9): R.ravel() = (q' outer q').ravel() @ _QUAT2_TO_R for q' = (w, 2 v), the unit quaternion (w, v)
# with its vector part doubled
_QUAT2_TO_R = _quadratic_form(lambda q: _quaternion_matrix(q * np.array([1.0, 0.5, 0.5, 0.5])), 4)
_QUARTER3 = np.full(3, 0.25)
_TINY = np.finfo(float).tiny


def expm(theta: np.ndarray) -> np.ndarray:
    """exp(skew(theta)) through the unit quaternion q = (cos(t/2), sin(t/2)/t theta), t = |theta|:
    R is a quadratic form in q, so one outer product and one matmul with a constant operator give
    every rotation of a stack. Exact for all angles, no series: with s = sin(t/2)/(t/2), taken 0 at
    t = 0 where it multiplies theta = 0, the quaternion is (cos(t/2), s theta/2); the operator takes
    (cos(t/2), s theta)."""
    theta = np.asarray(theta, dtype=float)
    shape = theta.shape[:-1]
    th = theta.reshape(-1, 3)
    half = np.sqrt((th * th) @ _QUARTER3)  # t/2
    q = np.empty((len(th), 4))
    np.cos(half, out=q[:, 0])
    np.multiply(th, (np.sin(half) / np.maximum(half, _TINY))[:, None], out=q[:, 1:])
    R = (q[:, :, None] * q[:, None, :]).reshape(-1, 16) @ _QUAT2_TO_R
    return R.reshape(shape + (3, 3))


def tangent(theta: np.ndarray) -> np.ndarray:
    """T(theta) with exp(skew(theta + d)) = exp(skew(theta)) exp(skew(T(theta) d)) + O(d^2)."""
    _, b, c = _coefficients(theta)
    S = skew(theta)
    return np.eye(3) - b[..., None, None] * S + c[..., None, None] * (S @ S)


# [axial vector of (R - R^T)/2, (trace R - 1)/2] = R.ravel() @ _LOG + _LOG_OFF
_LOG = np.zeros((9, 4))
_LOG[7, 0], _LOG[5, 0], _LOG[2, 1], _LOG[6, 1], _LOG[3, 2], _LOG[1, 2] = 0.5, -0.5, 0.5, -0.5, 0.5, -0.5
_LOG[[0, 4, 8], 3] = 0.5
_LOG_OFF = np.array([0.0, 0.0, 0.0, -0.5])


def logm(R: np.ndarray) -> np.ndarray:
    """Rotation vector of R (angle in [0, pi]). The angle is atan2(sin t, cos t) of the skew part
    v = sin(t) axis and of the trace, accurate at every angle (arccos of the trace loses half the
    digits near 0); near pi, where v -> 0, the axis comes from the symmetric part."""
    R = np.asarray(R, dtype=float)
    vc = R.reshape(R.shape[:-2] + (9,)) @ _LOG + _LOG_OFF
    v, cos = vc[..., :3], vc[..., 3]
    sin = np.sqrt(np.einsum("...i,...i->...", v, v))
    t = np.arctan2(sin, cos)
    small = t < 1e-2  # t/sin t = 1 + t^2/6 + 7 t^4/360 + O(t^6): below 1e-2 the next term is < 1e-13
    t2 = t * t
    factor = np.where(small, 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0, t / np.where(small, 1.0, sin))
    out = factor[..., None] * v
    near_pi = t > np.pi - 1e-4
    if np.any(near_pi):
        B = (R + np.swapaxes(R, -1, -2)) / 2.0 - cos[..., None, None] * np.eye(3)
        k = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        col = np.take_along_axis(B, k[..., None, None].repeat(3, -1), axis=-1)[..., 0]
        axis = col / np.linalg.norm(col, axis=-1, keepdims=True)
        axis = axis * np.where(np.einsum("...i,...i->...", axis, v) < 0, -1.0, 1.0)[..., None]
        out = np.where(near_pi[..., None], t[..., None] * axis, out)
    return out


def vect(Q: np.ndarray) -> np.ndarray:
    """Axial vector of the skew part of Q, the elastic rotation of geradin eq. (89).

    alpha = vect(Q) equals the rotation vector to O(|alpha|^3); it is the map the paper uses and
    its variation is linear in Q: delta alpha = H(Q) eps for delta Q = Q skew(eps)."""
    return Q.reshape(Q.shape[:-2] + (9,)) @ _VECT


def vect_tangent(Q: np.ndarray) -> np.ndarray:
    """H(Q) = (tr(Q) I - Q^T) / 2: the exact tangent of `vect` for right variations of Q."""
    tr = Q.reshape(Q.shape[:-2] + (9,)) @ _TRACE
    return 0.5 * (tr[..., None, None] * np.eye(3) - np.swapaxes(Q, -1, -2))


class RotationDefect(NamedTuple):
    """How far a 3 x 3 matrix is from a rotation: `orthonormality` = max |R^T R - I| (entrywise),
    `det` = det R (+1 for a rotation, negative for a reflection)."""
    orthonormality: float
    det: float


def rotation_defect(entries) -> RotationDefect:
    """The RotationDefect of the 3 x 3 matrix given as its 9 entries, row-major (a sequence of floats:
    on Python floats, cheaper than numpy at this size). A NaN or inf entry makes det NaN or the
    orthonormality infinite."""
    a, b, c, d, e, f, g, h, i = entries
    return RotationDefect(
        orthonormality=max(
            abs(a * a + d * d + g * g - 1.0), abs(b * b + e * e + h * h - 1.0), abs(c * c + f * f + i * i - 1.0),
            abs(a * b + d * e + g * h), abs(a * c + d * f + g * i), abs(b * c + e * f + h * i),
        ),
        det=a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g),
    )


def is_rotation(R: np.ndarray, tol: float = ROTATION_TOL) -> bool:
    """R is a (3, 3) array with |R^T R - I| <= tol and det(R) > 0 (`rotation_defect`; a NaN or inf
    entry fails: det NaN or |R^T R - I| infinite)."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        return False
    defect = rotation_defect(R.ravel().tolist())
    return bool(defect.orthonormality <= tol and defect.det > 0.0)
