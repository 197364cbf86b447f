"""Flat 3-node shell triangle (MITC3 bending and shear + CST membrane + drilling penalty) on 6-dof
nodes, the triangle beside shell.py's MITC4 quad (docs/shells.md).

Local dofs per node (u v w rx ry rz) in the element frame (e1 along the side 0 -> 1, e3 the normal
(X1 - X0) x (X2 - X0), e2 = e3 x e1), the fibre rotations beta_x = ry, beta_y = -rx, and the section
of shell_section.py, exactly as shell.py's element_matrices. Natural coordinates (r, s): node 0 at
(0, 0), node 1 at (1, 0), node 2 at (0, 1); N = (1 - r - s, r, s); J = d(x, y)/d(r, s) is constant.
  membrane   CST: eps = (u_x, v_y, u_y + v_x) constant (Turner et al. 1956)
  bending    kappa = (bx_x, by_y, bx_y + by_x) constant (linear rotations)
  shear      MITC3 (Lee & Bathe 2004, Comput. Struct. 82, eqs. 13-14): the covariant strains
             e_rt = w_r + beta . g_r and e_st = w_s + beta . g_s are tied at the edge midpoints,
             e_rt^(1) at (1/2, 0), e_st^(2) at (0, 1/2), and e_st - e_rt at (1/2, 1/2) (point 3):
               e_rt^AS = e_rt^(1) + c s,  e_st^AS = e_st^(2) - c r,
               c = e_rt^(3) - e_rt^(1) - e_st^(3) + e_st^(2),
             (constant tangential strain along each edge: the lowest Nedelec space), mapped to
             Cartesian with J^-1. The Kirchhoff constraint gamma = 0 then leaves the plate its bending
             modes instead of forcing w and beta both linear and equal: no shear locking.
Drilling: the penalty k_d sum_i (rz_i - omega)^2 with the CST rotation omega = (v_x - u_y)/2 and
k_d = DRILL * the smallest membrane diagonal (as the quad): zero on rigid motion, so a free plate
has exactly 6 zero modes. Mass: consistent, rho t N^T N on u, v, w and rho t^3/12 N^T N on rx, ry,
none on rz, integrated with MASS_RULE (exact for N_i N_j); the stiffness uses the same rule (the
assumed shear is linear, its energy quadratic: exact).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import Material
from .shell_section import DRILL, plate_section


@dataclass(frozen=True)
class TriangleRule:
    """A quadrature rule on the triangle: points in natural coordinates (r, s) (node 0 at (0, 0),
    node 1 at (1, 0), node 2 at (0, 1)) and weights as fractions of the element area (sum 1)."""

    points: np.ndarray  # (q, 2)
    weights: np.ndarray  # (q,)

    def shape(self) -> np.ndarray:
        """(q, 3) the linear shape functions N = (1 - r - s, r, s) at the points."""
        r, s = self.points.T
        return np.column_stack([1 - r - s, r, s])


# Strang & Fix's 3-point rule, interior points, degree 2: exact for N_i N_j of the linear triangle.
MASS_RULE = TriangleRule(points=np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]]),
                         weights=np.full(3, 1 / 3))
_DN = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])  # (2, 3): d/dr, d/ds of N


def tria_frame(X: np.ndarray):
    """Rotation T (rows e1, e2, e3) and in-plane coordinates (3, 2) about the centroid of a triangle's
    corners X (3, 3); a ValueError if its area vanishes against its sides."""
    g1, g2 = X[1] - X[0], X[2] - X[0]
    n = np.cross(g1, g2)
    side = max(np.linalg.norm(X[[1, 2, 0]] - X, axis=1))
    if np.linalg.norm(n) <= 1e-10 * side**2 or side == 0:
        raise ValueError(f"degenerate triangle (area {np.linalg.norm(n) / 2:.3g} against longest side "
                         f"{side:.3g}: its corners are collinear or coincide)")
    e3 = n / np.linalg.norm(n)
    e1 = g1 / np.linalg.norm(g1)
    T = np.array([e1, np.cross(e3, e1), e3])
    return T, (X - X.mean(axis=0)) @ T[:2].T


def tria_matrices(xy: np.ndarray, t: float, mat: Material):
    """Local 18 x 18 K, M of a flat MITC3 triangle with counter-clockwise corners xy (3, 2), local
    dofs per node (u v w rx ry rz)."""
    sec = plate_section(t, mat)
    iu, iv, iw, irx, iry, irz = (np.arange(3) * 6 + k for k in range(6))
    J = _DN @ xy  # rows g_r, g_s
    detJ = np.linalg.det(J)
    if detJ <= 0:
        raise ValueError(f"triangle with corners {xy.tolist()} is clockwise or degenerate (det J = {detJ:.3g})")
    area = detJ / 2
    dNx = np.linalg.solve(J, _DN)  # (2, 3): d/dx, d/dy
    Bm = np.zeros((3, 18))
    Bm[0, iu], Bm[1, iv], Bm[2, iu], Bm[2, iv] = dNx[0], dNx[1], dNx[1], dNx[0]
    Bb = np.zeros((3, 18))
    Bb[0, iry], Bb[1, irx], Bb[2, iry], Bb[2, irx] = dNx[0], -dNx[1], dNx[1], -dNx[0]

    def covariant(r, s, k):  # row e_rt (k = 0) or e_st (k = 1) of the displacement-based strain at (r, s)
        N = np.array([1 - r - s, r, s])
        B = np.zeros(18)
        B[iw] = _DN[k]
        B[iry] += N * J[k, 0]  # beta_x = ry
        B[irx] -= N * J[k, 1]  # beta_y = -rx
        return B

    e1, e2 = covariant(0.5, 0.0, 0), covariant(0.0, 0.5, 1)
    c = covariant(0.5, 0.5, 0) - e1 - covariant(0.5, 0.5, 1) + e2
    K = (Bm.T @ sec.Cm @ Bm + Bb.T @ sec.Cb @ Bb) * area
    M = np.zeros((18, 18))
    for (r, s), w, N in zip(MASS_RULE.points, MASS_RULE.weights, MASS_RULE.shape()):
        Bs = np.linalg.solve(J, np.array([e1 + c * s, e2 - c * r]))
        K += Bs.T @ sec.Cs @ Bs * (w * area)
        NN = np.outer(N, N) * (w * area)
        for idx, m in ((iu, mat.rho * t), (iv, mat.rho * t), (iw, mat.rho * t),
                       (irx, mat.rho * t**3 / 12), (iry, mat.rho * t**3 / 12)):
            M[np.ix_(idx, idx)] += m * NN
    kd = DRILL * np.min(np.diag(K)[np.concatenate([iu, iv])])
    omega = np.zeros(18)
    omega[iv] = 0.5 * dNx[0]
    omega[iu] = -0.5 * dNx[1]
    for i in range(3):
        b = -omega.copy()
        b[irz[i]] += 1.0
        K += kd * np.outer(b, b)
    return K, M


def split_quads(quads, diagonal: str = "02") -> np.ndarray:
    """Triangles (2 e, 3) of quads (e, 4) cut along the diagonal "02" (corners 0-2) or "13"."""
    Q = np.asarray(quads, dtype=int).reshape(-1, 4)
    if diagonal == "02":
        pairs = (Q[:, [0, 1, 2]], Q[:, [0, 2, 3]])
    elif diagonal == "13":
        pairs = (Q[:, [0, 1, 3]], Q[:, [1, 2, 3]])
    else:
        raise ValueError(f"diagonal {diagonal!r}: expected '02' or '13'")
    return np.stack(pairs, axis=1).reshape(-1, 3)
