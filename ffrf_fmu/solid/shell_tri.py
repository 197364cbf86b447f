"""Flat 3-node shell triangle (DKT bending + CST membrane + drilling penalty) on 6-dof nodes, the
triangle beside shell.py's MITC4 quad (docs/shells.md).

Local dofs per node (u v w rx ry rz) in the element frame (e1 along the side 0 -> 1, e3 the normal
(X1 - X0) x (X2 - X0), e2 = e3 x e1), the fibre rotations beta_x = ry, beta_y = -rx, and the section
of shell_section.py, exactly as shell.py's element_matrices. Natural coordinates (r, s): node 0 at
(0, 0), node 1 at (1, 0), node 2 at (0, 1); N = (1 - r - s, r, s); J = d(x, y)/d(r, s) is constant.
  membrane   CST: eps = (u_x, v_y, u_y + v_x) constant (Turner et al. 1956)
  bending    DKT (Batoz, Bathe & Ho 1980, Int. J. Numer. Meth. Eng. 15): beta quadratic on the
             6-node triangle, its corner values the nodal rotations and its midside values fixed
             by the discrete Kirchhoff constraints (_dkt_rotations); kappa = (bx_x, by_y,
             bx_y + by_x) linear. No transverse shear energy at all, hence no shear locking at any
             thickness (Kirchhoff plate: the shear flexibility of a thick plate is left out).
  shear      none with DKT. bending="mitc3": linear beta, constant kappa, and the MITC3 assumed
             shear (Lee & Bathe 2004, Comput. Struct. 82, eqs. 13-14): the covariant strains
             e_rt = w_r + beta . g_r, e_st = w_s + beta . g_s tied at the edge midpoints,
               e_rt^AS = e_rt^(1) + c s,  e_st^AS = e_st^(2) - c r,
               c = e_rt^(3) - e_rt^(1) - e_st^(3) + e_st^(2),
             points (1/2, 0), (0, 1/2), (1/2, 1/2), mapped to Cartesian with J^-1. On a mesh of
             N nodes it sets about 3 N edge constraints against 3 N bending dofs, and it locks on
             thin plates (measured in docs/shells.md); kept for that comparison only.
Drilling: the penalty k_d sum_i (rz_i - omega)^2 with the CST rotation omega = (v_x - u_y)/2 and
k_d = DRILL * the smallest membrane diagonal (as the quad): zero on rigid motion, so a free plate
has exactly 6 zero modes. Mass: consistent, rho t N^T N on u, v, w and rho t^3/12 N^T N on rx, ry
(linear N), none on rz, integrated with MASS_RULE (exact for N_i N_j); the stiffness uses the same
rule (DKT's kappa and MITC3's assumed shear are linear, their energies quadratic: exact).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import Material
from .shell_section import add_section_mass, drilling_penalty, plate_section


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
_EDGES = ((0, 1), (1, 2), (2, 0))  # midside k of the 6-node triangle lies on edge _EDGES[k]


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


def _quadratic(r: float, s: float):
    """(6,) 6-node shape functions (corners 0 1 2, then midsides 01 12 20) and (2, 6) d/dr, d/ds."""
    L = np.array([1 - r - s, r, s])
    dL = _DN
    N, dN = np.zeros(6), np.zeros((2, 6))
    for i in range(3):
        N[i] = L[i] * (2 * L[i] - 1)
        dN[:, i] = (4 * L[i] - 1) * dL[:, i]
    for k, (i, j) in enumerate(_EDGES):
        N[3 + k] = 4 * L[i] * L[j]
        dN[:, 3 + k] = 4 * (L[j] * dL[:, i] + L[i] * dL[:, j])
    return N, dN


def _dkt_rotations(xy: np.ndarray) -> np.ndarray:
    """(6, 2, 18) the fibre rotation beta at the corners and midsides of the DKT (Batoz, Bathe & Ho
    1980, eqs. 9-13) in terms of the 18 local dofs: beta = -grad w at the corners (beta_x = ry,
    beta_y = -rx); at the midside of edge ij (tangent s, normal n, length L) the Kirchhoff constraint
    with w cubic along the edge, beta_s = -3/(2L) (w_j - w_i) - (beta_s,i + beta_s,j)/4, and beta_n
    linear along the edge, beta_n = (beta_n,i + beta_n,j)/2."""
    B = np.zeros((6, 2, 18))
    for i in range(3):
        B[i, 0, 6 * i + 4] = 1.0  # beta_x = ry
        B[i, 1, 6 * i + 3] = -1.0  # beta_y = -rx
    for k, (i, j) in enumerate(_EDGES):
        d = xy[j] - xy[i]
        L = np.hypot(*d)
        tan, nor = d / L, np.array([d[1], -d[0]]) / L
        bs = -0.25 * tan @ (B[i] + B[j])
        bs[6 * j + 2] -= 1.5 / L
        bs[6 * i + 2] += 1.5 / L
        bn = 0.5 * nor @ (B[i] + B[j])
        B[3 + k] = np.outer(tan, bs) + np.outer(nor, bn)
    return B


def _dkt_curvature(beta: np.ndarray, Jinv: np.ndarray, r: float, s: float) -> np.ndarray:
    """(3, 18) kappa = (bx_x, by_y, bx_y + by_x) of the quadratic rotation field at (r, s)."""
    _, dN = _quadratic(r, s)
    dNx = Jinv @ dN  # (2, 6): d/dx, d/dy
    bx, by = beta[:, 0, :], beta[:, 1, :]  # (6, 18)
    return np.array([dNx[0] @ bx, dNx[1] @ by, dNx[1] @ bx + dNx[0] @ by])


def tria_matrices(xy: np.ndarray, t: float, mat: Material, bending: str = "dkt", section=None):
    """Local 18 x 18 K, M of a flat triangle with counter-clockwise corners xy (3, 2), local dofs per
    node (u v w rx ry rz): CST membrane, drilling penalty, and the bending of the DKT (Kirchhoff, no
    transverse shear; default) or of the MITC3 (Reissner-Mindlin, `bending="mitc3"`, locks on thin
    plates: docs/shells.md); `section` a shell_section.PlateSection in the element axes (a laminate's:
    its coupling B between the CST membrane and the bending), else the isotropic plate of t and mat."""
    if bending not in ("dkt", "mitc3"):
        raise ValueError(f"bending {bending!r}: expected 'dkt' or 'mitc3'")
    sec = plate_section(t, mat) if section is None else section
    iu, iv, iw, irx, iry, irz = (np.arange(3) * 6 + k for k in range(6))
    J = _DN @ xy  # rows g_r, g_s
    detJ = np.linalg.det(J)
    if detJ <= 0:
        raise ValueError(f"triangle with corners {xy.tolist()} is clockwise or degenerate (det J = {detJ:.3g})")
    area = detJ / 2
    Jinv = np.linalg.inv(J)
    dNx = Jinv @ _DN  # (2, 3): d/dx, d/dy
    Bm = np.zeros((3, 18))
    Bm[0, iu], Bm[1, iv], Bm[2, iu], Bm[2, iv] = dNx[0], dNx[1], dNx[1], dNx[0]
    K = Bm.T @ sec.Cm @ Bm * area
    M = np.zeros((18, 18))
    beta = _dkt_rotations(xy) if bending == "dkt" else None
    if bending == "mitc3":
        Bb = np.zeros((3, 18))
        Bb[0, iry], Bb[1, irx], Bb[2, iry], Bb[2, irx] = dNx[0], -dNx[1], dNx[1], -dNx[0]
        K += Bb.T @ sec.Cb @ Bb * area

        def covariant(r, s, k):  # row e_rt (k = 0) or e_st (k = 1) of the displacement-based strain
            N = np.array([1 - r - s, r, s])
            B = np.zeros(18)
            B[iw] = _DN[k]
            B[iry] += N * J[k, 0]  # beta_x = ry
            B[irx] -= N * J[k, 1]  # beta_y = -rx
            return B

        e1, e2 = covariant(0.5, 0.0, 0), covariant(0.0, 0.5, 1)
        c = covariant(0.5, 0.5, 0) - e1 - covariant(0.5, 0.5, 1) + e2
    for (r, s), w, N in zip(MASS_RULE.points, MASS_RULE.weights, MASS_RULE.shape()):
        if bending == "dkt":  # kappa linear: the degree-2 rule integrates its energy exactly
            Bb = _dkt_curvature(beta, Jinv, r, s)
            K += Bb.T @ sec.Cb @ Bb * (w * area)
        else:
            Bs = Jinv @ np.array([e1 + c * s, e2 - c * r])
            K += Bs.T @ sec.Cs @ Bs * (w * area)
        if sec.coupled:  # B between the constant membrane strain and the (linear) curvature: exact
            Bk = _dkt_curvature(beta, Jinv, r, s) if bending == "dkt" else Bb
            K += (Bm.T @ sec.Cmb @ Bk + Bk.T @ sec.Cmb @ Bm) * (w * area)
        add_section_mass(M, np.outer(N, N) * (w * area), sec.inertia, iu, iv, iw, irx, iry)
    drilling_penalty(K, dNx, iu, iv, irz)
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
