"""The homogeneous isotropic shell section shared by the flat shell elements (shell.py's MITC4 quad,
shell_tri.py's MITC3 triangle; docs/shells.md): membrane, bending and transverse-shear resultant
matrices of a thickness t, the shear correction factor and the drilling penalty factor."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import Material

DRILL = 1e-3  # drilling penalty / smallest membrane stiffness diagonal of the element
SHEAR_FACTOR = 5.0 / 6.0  # Reissner-Mindlin shear correction k


@dataclass(frozen=True)
class PlateSection:
    """Resultant-strain matrices of a plate of thickness t: N = Cm eps, M = Cb kappa, Q = Cs gamma."""

    Cm: np.ndarray  # (3, 3) E t / (1 - nu^2) [[1 nu 0][nu 1 0][0 0 (1-nu)/2]]
    Cb: np.ndarray  # (3, 3) t^2 / 12 Cm
    Cs: np.ndarray  # (2, 2) k G t I


def plate_section(t: float, mat: Material) -> PlateSection:
    E, nu = mat.E, mat.nu
    Cm = E * t / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    return PlateSection(Cm, Cm * t**2 / 12, SHEAR_FACTOR * E / (2 * (1 + nu)) * t * np.eye(2))


def drilling_penalty(K, dNx, iu, iv, irz) -> None:
    """Add the drilling penalty to a flat element's local K (in place): k_d sum_i (rz_i - omega_c)^2,
    omega_c = (v_x - u_y) / 2 from the shape function gradients dNx (2, k) at the centre, k_d = DRILL x
    the smallest membrane diagonal (shell.py's module doc): no energy in a rigid motion."""
    kd = DRILL * np.min(np.diag(K)[np.concatenate([iu, iv])])
    omega = np.zeros(K.shape[0])
    omega[iv] = 0.5 * dNx[0]
    omega[iu] = -0.5 * dNx[1]
    for i in irz:
        b = -omega.copy()
        b[i] += 1.0
        K += kd * np.outer(b, b)


def corner_frame(X: np.ndarray, what: str = "quad") -> np.ndarray:
    """Rotation T (rows e1, e2, e3) of a quad from its corners X[:4]: e3 normal to the plane of the
    mid-side vectors g1, g2, e1 along g1 (a warped quad is projected on that plane: shell.py)."""
    g1 = (X[1] + X[2] - X[0] - X[3]) / 2
    g2 = (X[2] + X[3] - X[0] - X[1]) / 2
    e3 = np.cross(g1, g2)
    if np.linalg.norm(e3) <= 1e-14 * np.linalg.norm(g1) * np.linalg.norm(g2) + 1e-300:
        raise ValueError(f"degenerate {what}: its mid-side vectors are parallel")
    e3 /= np.linalg.norm(e3)
    e1 = g1 / np.linalg.norm(g1)
    return np.array([e1, np.cross(e3, e1), e3])

