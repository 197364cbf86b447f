"""SO(3) helpers of the reference solver, vectorized over leading axes.

Deliberately self-contained (numpy only): the reference must not share dynamics code with the
superelement path, rotation helpers included.

Conventions: `hat(a) b = a x b`; `expm(a)` is the Rodrigues formula; right (body) perturbations
`R exp(hat(theta))`; `jr(a)` is the right Jacobian of the exponential,
`exp(hat(a + da)) ~ exp(hat(a)) exp(hat(jr(a) da))`, and `jl(a) = jr(-a) = expm(a) jr(a)`.

The arrays are small (one entry per node or element), so the cost is the number of numpy calls,
not flops: the scalar coefficient functions are evaluated together, from a Taylor series in
p = phi^2 when every angle is below `SERIES` rad (the common case: element relative rotations and
per-step rotation increments), from closed forms otherwise.
"""
from __future__ import annotations

import numpy as np

SERIES = 0.1  # rad; series truncation error < 1e-13 below; closed forms lose digits to cancellation

# hat(a) = (a @ _HAT).reshape(..., 3, 3)
_EPS = np.zeros((3, 3, 3))
_EPS[0, 1, 2] = _EPS[1, 2, 0] = _EPS[2, 0, 1] = 1.0
_EPS[0, 2, 1] = _EPS[2, 1, 0] = _EPS[1, 0, 2] = -1.0
_HAT = np.ascontiguousarray(np.einsum("ijk->kij", -_EPS).reshape(3, 9))
_I3 = np.eye(3)
_VI = np.array([2, 0, 1])
_VJ = np.array([1, 2, 0])

# Taylor coefficients in p = phi^2 (columns: s1, s2, s3, s4, ds1/dp, ds2/dp, ds3/dp, ds4/dp)
#   s1 = sin(phi)/phi, s2 = (1 - cos phi)/phi^2, s3 = (phi - sin phi)/phi^3,
#   s4 = 1/phi^2 - (1 + cos phi)/(2 phi sin phi)
_TAYLOR = np.array(
    [
        [1.0, 1 / 2, 1 / 6, 1 / 12, -1 / 6, -1 / 24, -1 / 120, 1 / 720],
        [-1 / 6, -1 / 24, -1 / 120, 1 / 720, 1 / 60, 1 / 360, 1 / 2520, 1 / 15120],
        [1 / 120, 1 / 720, 1 / 5040, 1 / 30240, -1 / 1680, -1 / 13440, -1 / 120960, 1 / 403200],
        [-1 / 5040, -1 / 40320, -1 / 362880, 1 / 1209600, 1 / 90720, 1 / 907200, 1 / 9979200, 1 / 11975040],
        [1 / 362880, 1 / 3628800, 1 / 39916800, 1 / 47900160, 0.0, 0.0, 0.0, 0.0],
    ]
)
_POW = np.arange(5)


def hat(a: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) skew matrix."""
    a = np.asarray(a, dtype=float)
    return (a @ _HAT).reshape(a.shape[:-1] + (3, 3))


def vee(A: np.ndarray) -> np.ndarray:
    """Axial vector of the skew part times 2: vee(A - A^T)/... -> (A[2,1], A[0,2], A[1,0])."""
    return A[..., _VI, _VJ]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (hat(a) @ b[..., None])[..., 0]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a * b).sum(-1)


def coefficients(p: np.ndarray, derivatives: bool = False) -> np.ndarray:
    """Coefficient functions of p = phi^2, stacked on a new last axis.

    Returns (..., 4) [s1, s2, s3, s4], or (..., 8) with their derivatives d/dp appended.
    """
    p = np.asarray(p, dtype=float)
    ncol = 8 if derivatives else 4
    if p.size == 0 or p.max() < SERIES * SERIES:
        return (p[..., None] ** _POW) @ _TAYLOR[:, :ncol]
    small = p < SERIES * SERIES
    q = np.where(small, 1.0, p)
    f = np.sqrt(q)
    sn, cs = np.sin(f), np.cos(f)
    cot_h = (1.0 + cs) / sn  # cot(phi/2)
    cols = [sn / f, (1.0 - cs) / q, (f - sn) / (f * q), 1.0 / q - cot_h / (2.0 * f)]
    if derivatives:
        csc2_h = 1.0 / np.sin(0.5 * f) ** 2
        cols += [
            (f * cs - sn) / (2.0 * f * q),
            (f * sn - 2.0 + 2.0 * cs) / (2.0 * q * q),
            ((1.0 - cs) * f - 3.0 * (f - sn)) / (2.0 * q * q * f),
            (-2.0 / (f * q) + (f * csc2_h + 2.0 * cot_h) / (4.0 * q)) / (2.0 * f),
        ]
    out = np.stack(cols, axis=-1)
    if np.any(small):
        out = np.where(small[..., None], (p[..., None] ** _POW) @ _TAYLOR[:, :ncol], out)
    return out


def _poly(a: np.ndarray, c1: np.ndarray, c2: np.ndarray) -> np.ndarray:
    """I + c1 hat(a) + c2 hat(a)^2."""
    A = hat(a)
    return _I3 + c1[..., None, None] * A + c2[..., None, None] * (A @ A)


def expm(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    s = coefficients(dot(a, a))
    return _poly(a, s[..., 0], s[..., 1])


def expm_jr(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(expm(a), jr(a)) sharing the work."""
    a = np.asarray(a, dtype=float)
    s = coefficients(dot(a, a))
    A = hat(a)
    A2 = A @ A
    return (
        _I3 + s[..., 0, None, None] * A + s[..., 1, None, None] * A2,
        _I3 - s[..., 1, None, None] * A + s[..., 2, None, None] * A2,
    )


def jr(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    s = coefficients(dot(a, a))
    return _poly(a, -s[..., 1], s[..., 2])


def jr_inv(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    s = coefficients(dot(a, a))
    return _poly(a, np.full(s.shape[:-1], 0.5), s[..., 3])


# [vee((R - R^T)/2), (trace R - 1)/2] = R.reshape(9) @ _LOG + [0, 0, 0, -1/2]
_LOG = np.zeros((9, 4))
_LOG[7, 0], _LOG[5, 0], _LOG[2, 1], _LOG[6, 1], _LOG[3, 2], _LOG[1, 2] = 0.5, -0.5, 0.5, -0.5, 0.5, -0.5
_LOG[[0, 4, 8], 3] = 0.5
_LOG_OFF = np.array([0.0, 0.0, 0.0, -0.5])


def logm(R: np.ndarray) -> np.ndarray:
    """Rotation vector of R (..., 3, 3); valid for angles below pi - 1e-6 (raises otherwise)."""
    R = np.asarray(R, dtype=float)
    vc = R.reshape(R.shape[:-2] + (9,)) @ _LOG + _LOG_OFF
    v, c = vc[..., :3], vc[..., 3]
    s2 = dot(v, v)
    if s2.size and s2.max() < 1e-4 and c.min() > 0.0:  # all angles < 0.01 rad: phi/sin(phi) series in s^2
        k = 1.0 + s2 / 6.0 + 3.0 * s2 * s2 / 40.0
        return k[..., None] * v
    s = np.sqrt(s2)
    phi = np.arctan2(s, c)
    if np.any(phi > np.pi - 1e-6):
        raise ValueError("logm: rotation angle too close to pi (element relative rotation too large)")
    small = phi < 1e-2
    p2 = phi * phi
    k = np.where(small, 1.0 + p2 / 6.0 + 7.0 * p2 * p2 / 360.0, phi / np.where(small, 1.0, s))
    return k[..., None] * v


def rot_about(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    return expm(angle * axis / np.linalg.norm(axis))
