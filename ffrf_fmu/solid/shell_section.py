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
