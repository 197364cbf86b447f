"""The shell section shared by the flat shell elements (shell.py's MITC4 quad, shell_tri.py's DKT and
MITC3 triangles, shell_mitc9.py's MITC9; docs/shells.md): the resultant matrices of a homogeneous
isotropic plate of thickness t or of a laminate by classical laminate theory, the shear correction
factor and the drilling penalty factor.

Laminate (Jones, Mechanics of Composite Materials, 2nd ed. 1999, sec. 4.2; Reddy, Mechanics of
Laminated Composite Plates and Shells, 2nd ed. 2004, eqs. 3.3.17 and 3.4.28): plies k = 1..n from the
bottom, z_0 = Z0 (bottom surface, measured from the reference plane along the element normal),
z_k = z_(k-1) + t_k; each ply's plane-stress stiffness in its axes (1 along the fibre)
    Q = 1 / (1 - nu12 nu21) [[E1, nu12 E2, 0], [nu12 E2, E2, 0], [0, 0, G12 (1 - nu12 nu21)]],
    nu21 = nu12 E2 / E1,
turned to the element axes by the ply angle theta (from the element's material x axis to the fibre,
about the normal): Qbar = T^T Q T, T = [[c^2, s^2, c s], [s^2, c^2, -c s], [-2 c s, 2 c s, c^2 - s^2]]
(engineering strains: eps_12 = T eps_xy). Then, with eps(z) = eps0 + z kappa,
    A = sum Qbar_k (z_k - z_(k-1)),  B = 1/2 sum Qbar_k (z_k^2 - z_(k-1)^2),
    D = 1/3 sum Qbar_k (z_k^3 - z_(k-1)^3),   N = A eps0 + B kappa,  M = B eps0 + D kappa,
and the transverse shear (first-order shear deformation, one shear factor for the stack)
    H = k sum R_k^T diag(G1z, G2z)_k R_k t_k,  R = [[c, s], [-s, c]],  k = 5/6,
a homogeneous ply of MAT1 having G1z = G2z = G. Inertia per unit area about the reference plane:
m0 = sum rho_k t_k (+ NSM), m1 = sum rho_k (z_k^2 - z_(k-1)^2) / 2, m2 = sum rho_k (z_k^3 - z_(k-1)^3) / 3.
The isotropic plate of thickness t is the one-ply laminate from -t/2: A = E t / (1 - nu^2) [..],
B = 0, D = t^2 / 12 A, H = k G t I, (m0, m1, m2) = (rho t, 0, rho t^3 / 12).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .mesh import Material

DRILL = 1e-3  # drilling penalty / smallest membrane stiffness diagonal of the element
SHEAR_FACTOR = 5.0 / 6.0  # Reissner-Mindlin shear correction k


@dataclass(frozen=True)
class PlateSection:
    """Resultant-strain matrices of a plate: N = Cm eps + Cmb kappa, M = Cmb eps + Cb kappa, Q = Cs gamma
    (module doc: Cm = A, Cmb = B, Cb = D, Cs = H), and its inertia per unit area about the reference
    plane (m0, m1, m2) = int rho (1, z, z^2) dz."""

    Cm: np.ndarray  # (3, 3) membrane A
    Cb: np.ndarray  # (3, 3) bending D
    Cs: np.ndarray  # (2, 2) transverse shear H (with the shear factor)
    Cmb: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # (3, 3) coupling B
    inertia: tuple = (0.0, 0.0, 0.0)  # (m0, m1, m2) [kg/m^2, kg/m, kg]

    @property
    def coupled(self) -> bool:
        return bool(np.any(self.Cmb != 0.0))


def plate_section(t: float, mat: Material) -> PlateSection:
    """The homogeneous isotropic plate of thickness t about its mid-plane (module doc)."""
    E, nu = mat.E, mat.nu
    Cm = E * t / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    return PlateSection(Cm, Cm * t**2 / 12, SHEAR_FACTOR * E / (2 * (1 + nu)) * t * np.eye(2),
                        inertia=(mat.rho * t, 0.0, mat.rho * t**3 / 12))


@dataclass(frozen=True)
class Orthotropic:
    """A ply material in plane stress (Nastran's MAT8): moduli along (E1) and across (E2) the fibre,
    nu12 (strain across / strain along under a load along), in-plane G12, transverse shear G1z, G2z."""

    E1: float
    E2: float
    nu12: float
    G12: float
    G1z: float
    G2z: float
    rho: float

    def Q(self) -> np.ndarray:
        """(3, 3) the plane-stress stiffness in the ply axes (module doc)."""
        nu21 = self.nu12 * self.E2 / self.E1
        d = 1.0 - self.nu12 * nu21
        if d <= 0 or self.E1 <= 0 or self.E2 <= 0 or self.G12 <= 0:
            raise ValueError(f"ply material not positive definite: E1 = {self.E1:g}, E2 = {self.E2:g}, "
                             f"NU12 = {self.nu12:g}, G12 = {self.G12:g} (needs E1, E2, G12 > 0, NU12^2 < E1/E2)")
        return np.array([[self.E1, self.nu12 * self.E2, 0.0], [self.nu12 * self.E2, self.E2, 0.0],
                         [0.0, 0.0, self.G12 * d]]) / d

    def shear(self) -> np.ndarray:
        """(2, 2) diag(G1z, G2z) in the ply axes."""
        return np.diag([self.G1z, self.G2z])


def isotropic_ply(mat: Material) -> Orthotropic:
    """An isotropic material as a ply (E1 = E2 = E, G12 = G1z = G2z = E / (2 (1 + nu)))."""
    G = mat.E / (2 * (1 + mat.nu))
    return Orthotropic(mat.E, mat.E, mat.nu, G, G, G, mat.rho)


def strain_rotation(angle):
    """T (..., 3, 3) with eps_12 = T eps_xy for axes 1 at `angle` [rad] from x (module doc)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.moveaxis(np.array([[c * c, s * s, c * s], [s * s, c * c, -c * s],
                                 [-2 * c * s, 2 * c * s, c * c - s * s]]), (0, 1), (-2, -1))


def shear_rotation(angle):
    """R (..., 2, 2) with gamma_(1z, 2z) = R gamma_(xz, yz)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.moveaxis(np.array([[c, s], [-s, c]]), (0, 1), (-2, -1))


@dataclass(frozen=True)
class Ply:
    material: Orthotropic
    thickness: float
    theta: float  # [deg] from the element's material x axis to the fibre, about the normal


@dataclass(frozen=True)
class Laminate:
    """Plies from the bottom; z0 the bottom surface from the reference plane; nsm mass per area."""

    plies: tuple
    z0: float
    nsm: float = 0.0

    @property
    def thickness(self) -> float:
        return float(sum(p.thickness for p in self.plies))

    def section(self, angle: float = 0.0) -> PlateSection:
        """The laminate's PlateSection in axes turned by `angle` [rad] from its material axes (module
        doc: each ply's Qbar at theta_k + angle)."""
        z = self.z0 + np.concatenate([[0.0], np.cumsum([p.thickness for p in self.plies])])
        A, B, D, H = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((2, 2))
        m = np.zeros(3)
        for k, p in enumerate(self.plies):
            a = np.radians(p.theta) + angle
            T, R = strain_rotation(a), shear_rotation(a)
            Qb = T.T @ p.material.Q() @ T
            dz = [(z[k + 1] ** j - z[k] ** j) / j for j in (1, 2, 3)]
            A += Qb * dz[0]
            B += Qb * dz[1]
            D += Qb * dz[2]
            H += R.T @ p.material.shear() @ R * dz[0]
            m += p.material.rho * np.array(dz)
        m[0] += self.nsm
        return PlateSection(A, D, SHEAR_FACTOR * H, B, inertia=tuple(float(v) for v in m))


def rotate_sections(sec: PlateSection, angle):
    """(A, B, D, H) (e, 3, 3) x 3 and (e, 2, 2) of the section turned by angles (e,) [rad]: the element
    axes at -angle from the section's axes (angle: from the element axis to the material axis)."""
    T, R = strain_rotation(np.asarray(angle, dtype=float)), shear_rotation(np.asarray(angle, dtype=float))
    Tt = np.swapaxes(T, -1, -2)
    return (Tt @ sec.Cm @ T, Tt @ sec.Cmb @ T, Tt @ sec.Cb @ T, np.swapaxes(R, -1, -2) @ sec.Cs @ R)


def add_section_mass(M, NN, inertia, iu, iv, iw, irx, iry) -> None:
    """Add a fibre's consistent mass to a flat element's local M (in place) for one quadrature point's
    NN = N_i N_j dA: u(z) = u0 + z beta with beta_x = ry, beta_y = -rx, so m0 on u v w, m2 on rx ry
    and m1 between u and ry, and (with a minus sign) between v and rx; none on rz."""
    m0, m1, m2 = inertia
    for idx, m in ((iu, m0), (iv, m0), (iw, m0), (irx, m2), (iry, m2)):
        M[np.ix_(idx, idx)] += m * NN
    if m1:
        for a, b, sign in ((iu, iry, 1.0), (iv, irx, -1.0)):
            M[np.ix_(a, b)] += sign * m1 * NN
            M[np.ix_(b, a)] += sign * m1 * NN.T


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

