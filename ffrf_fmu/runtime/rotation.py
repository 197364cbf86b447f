"""SO(3) in one place: skew, exponential, tangent operator and the elastic rotation map `vect`.

Conventions: rotations are matrices R (columns = rotated axes in fixed axes), updated on the
right, R <- R exp(skew(theta)), with theta in the rotated (body) axes. All functions accept
stacks (..., 3) / (..., 3, 3) so that the body equations vectorize over nodes and superelements.
"""
from __future__ import annotations

import numpy as np

_EPS = 1e-5  # below this angle the series expansions are exact to round-off


def skew(a: np.ndarray) -> np.ndarray:
    """skew(a) b = a x b."""
    a = np.asarray(a, dtype=float)
    out = np.zeros(a.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -a[..., 2], a[..., 1]
    out[..., 1, 0], out[..., 1, 2] = a[..., 2], -a[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -a[..., 1], a[..., 0]
    return out


def _coefficients(theta: np.ndarray):
    """sin(t)/t, (1 - cos t)/t^2, (t - sin t)/t^3 for t = |theta|, series near 0."""
    t2 = np.einsum("...i,...i->...", theta, theta)
    t = np.sqrt(t2)
    small = t < _EPS
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(ts) / ts)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(ts)) / ts**2)
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0, (ts - np.sin(ts)) / ts**3)
    return a, b, c


def expm(theta: np.ndarray) -> np.ndarray:
    """Rodrigues: exp(skew(theta))."""
    a, b, _ = _coefficients(theta)
    S = skew(theta)
    return np.eye(3) + a[..., None, None] * S + b[..., None, None] * (S @ S)


def tangent(theta: np.ndarray) -> np.ndarray:
    """T(theta) with exp(skew(theta + d)) = exp(skew(theta)) exp(skew(T(theta) d)) + O(d^2)."""
    _, b, c = _coefficients(theta)
    S = skew(theta)
    return np.eye(3) - b[..., None, None] * S + c[..., None, None] * (S @ S)


def logm(R: np.ndarray) -> np.ndarray:
    """Rotation vector of R (angle in [0, pi]); used for outputs, not in the equations."""
    R = np.asarray(R, dtype=float)
    cos = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    t = np.arccos(cos)
    v = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    small = t < _EPS
    factor = np.where(small, 1.0 + t**2 / 6.0, t / np.where(small, 1.0, np.sin(np.where(small, 1.0, t))))
    out = factor[..., None] * v
    # near pi, sin(t) -> 0: take the axis from the symmetric part instead
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
    return 0.5 * np.stack([Q[..., 2, 1] - Q[..., 1, 2], Q[..., 0, 2] - Q[..., 2, 0], Q[..., 1, 0] - Q[..., 0, 1]], -1)


def vect_tangent(Q: np.ndarray) -> np.ndarray:
    """H(Q) = (tr(Q) I - Q^T) / 2: the exact tangent of `vect` for right variations of Q."""
    tr = np.trace(Q, axis1=-2, axis2=-1)
    return 0.5 * (tr[..., None, None] * np.eye(3) - np.swapaxes(Q, -1, -2))


def is_rotation(R: np.ndarray, tol: float = 1e-6) -> bool:
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        return False
    return bool(np.max(np.abs(R.T @ R - np.eye(3))) <= tol and np.linalg.det(R) > 0)
