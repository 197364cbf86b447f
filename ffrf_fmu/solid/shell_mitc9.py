"""Flat 9-node shell quad (MITC9 bending and shear + 9-node membrane + drilling penalty) on 6-dof
nodes, the quadratic element beside shell.py's MITC4 (docs/shells.md).

Nodes: corners 0-3 counter-clockwise at (r, s) = (-1, -1), (1, -1), (1, 1), (-1, 1), midsides 4-7
on the sides 01, 12, 23, 30, centre 8 (CalculiX's S8 order, plus the centre). Local dofs per node
(u v w rx ry rz) in the element frame, beta_x = ry, beta_y = -rx, and the section of
shell_section.py, as shell.py's element_matrices; N = l_a(r) l_b(s) with the quadratic Lagrange
l(-1) = r (r - 1)/2, l(0) = 1 - r^2, l(1) = r (r + 1)/2.
  membrane   eps = (u_x, v_y, u_y + v_x) of the biquadratic displacement (3 x 3 Gauss)
  bending    kappa = (bx_x, by_y, bx_y + by_x) (3 x 3 Gauss)
  shear      MITC9 (Bucalem & Bathe 1993, Int. J. Numer. Meth. Eng. 36; Bathe, Bucalem & Brezzi
             1990): the covariant e_rt = w_r + beta . g_r is tied at the 6 points r = +-a,
             s = 0, +-b (a = 1/sqrt 3, b = sqrt(3/5)) and interpolated linearly in r over +-a and
             quadratically in s over -b, 0, b; e_st likewise with r and s exchanged; mapped to
             Cartesian with J^-1 at each Gauss point.
Drilling: k_d sum_i (rz_i - omega(x_i))^2, omega = (v_x - u_y)/2 of the membrane at node i,
k_d = DRILL * the smallest membrane diagonal: zero on rigid motion (omega constant = rz). Mass:
consistent, rho t N^T N on u, v, w and rho t^3/12 N^T N on rx, ry, none on rz, on 3 x 3 Gauss
(MASS_RULE_9: exact for N_i N_j of a parallelogram).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import Material
from .shell_section import DRILL, add_section_mass, corner_frame, plate_section

_R = np.array([-1.0, 1.0, 1.0, -1.0, 0.0, 1.0, 0.0, -1.0, 0.0])  # natural coordinates of the 9 nodes
_S = np.array([-1.0, -1.0, 1.0, 1.0, -1.0, 0.0, 1.0, 0.0, 0.0])
_G3 = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_W3 = np.array([5.0, 8.0, 5.0]) / 9.0


@dataclass(frozen=True)
class SquareRule:
    """A quadrature rule on [-1, 1]^2: points (r, s) and weights (sum 4; dA = weight * det J)."""

    points: np.ndarray  # (q, 2)
    weights: np.ndarray  # (q,)

    def shape(self) -> np.ndarray:
        """(q, 9) the 9-node shape functions at the points."""
        return np.array([shape9(r, s)[0] for r, s in self.points])


# 3 x 3 Gauss-Legendre: exact for N_i N_j of the biquadratic quad on a parallelogram (degree 4 per axis)
MASS_RULE_9 = SquareRule(points=np.array([(r, s) for s in _G3 for r in _G3]),
                         weights=np.array([wr * ws for ws in _W3 for wr in _W3]))
_A, _B = 1.0 / np.sqrt(3.0), np.sqrt(0.6)  # MITC9 tying abscissae


def _lagrange(x, nodes):
    """Values of the 1D Lagrange polynomials on `nodes` at x."""
    out = np.ones(len(nodes))
    for i, xi in enumerate(nodes):
        for j, xj in enumerate(nodes):
            if j != i:
                out[i] *= (x - xj) / (xi - xj)
    return out


def _l(x):
    return np.array([x * (x - 1) / 2, 1 - x**2, x * (x + 1) / 2]), np.array([x - 0.5, -2 * x, x + 0.5])


def shape9(r: float, s: float):
    """(9,) N and (2, 9) d/dr, d/ds of the 9-node quad at (r, s)."""
    lr, dr = _l(r)
    ls, ds = _l(s)
    a, b = (_R + 1).astype(int), (_S + 1).astype(int)
    return lr[a] * ls[b], np.array([dr[a] * ls[b], lr[a] * ds[b]])


def quad9_frame(X: np.ndarray):
    """Rotation T (rows e1, e2, e3) and the in-plane coordinates (9, 2) about the centre of a 9-node
    quad's nodes X (9, 3): the plane of the corners' mid-side vectors (as shell.element_frame)."""
    T = corner_frame(X, "9-node quad")
    return T, (X - X[:4].mean(axis=0)) @ T[:2].T


def quad9_matrices(xy: np.ndarray, t: float, mat: Material, section=None):
    """Local 54 x 54 K, M of a flat MITC9 quad with nodes xy (9, 2), local dofs per node
    (u v w rx ry rz); `section` a shell_section.PlateSection in the element axes, else the isotropic
    plate of t and mat."""
    sec = plate_section(t, mat) if section is None else section
    iu, iv, iw, irx, iry, irz = (np.arange(9) * 6 + k for k in range(6))

    def jacobian(r, s):
        N, dN = shape9(r, s)
        J = dN @ xy
        detJ = np.linalg.det(J)
        if detJ <= 0:
            raise ValueError(f"9-node quad with nodes {xy.tolist()} is inverted or distorted "
                             f"(det J = {detJ:.3g} at r = {r:.3g}, s = {s:.3g})")
        return N, dN, J, detJ

    def covariant(r, s, k):  # row e_rt (k = 0) or e_st (k = 1) of the displacement-based strain
        N, dN, J, _ = jacobian(r, s)
        B = np.zeros(54)
        B[iw] = dN[k]
        B[iry] += N * J[k, 0]  # beta_x = ry
        B[irx] -= N * J[k, 1]  # beta_y = -rx
        return B

    # tying values: e_rt at (+-a, {-b, 0, b}), e_st at ({-b, 0, b}, +-a)
    E_rt = np.array([[covariant(ra, sb, 0) for sb in (-_B, 0.0, _B)] for ra in (-_A, _A)])  # (2, 3, 54)
    E_st = np.array([[covariant(rb, sa, 1) for rb in (-_B, 0.0, _B)] for sa in (-_A, _A)])
    K = np.zeros((54, 54))
    M = np.zeros((54, 54))
    for (r, s), w in zip(MASS_RULE_9.points, MASS_RULE_9.weights):
        N, dN, J, detJ = jacobian(r, s)
        dNx = np.linalg.solve(J, dN)
        Bm = np.zeros((3, 54))
        Bm[0, iu], Bm[1, iv], Bm[2, iu], Bm[2, iv] = dNx[0], dNx[1], dNx[1], dNx[0]
        Bb = np.zeros((3, 54))
        Bb[0, iry], Bb[1, irx], Bb[2, iry], Bb[2, irx] = dNx[0], -dNx[1], dNx[1], -dNx[0]
        h2, g3 = _lagrange(r, (-_A, _A)), _lagrange(s, (-_B, 0.0, _B))
        e_r = np.einsum("i,j,ijk->k", h2, g3, E_rt)
        h2, g3 = _lagrange(s, (-_A, _A)), _lagrange(r, (-_B, 0.0, _B))
        e_s = np.einsum("i,j,ijk->k", h2, g3, E_st)
        Bs = np.linalg.solve(J, np.array([e_r, e_s]))
        dA = w * detJ
        K += (Bm.T @ sec.Cm @ Bm + Bb.T @ sec.Cb @ Bb + Bs.T @ sec.Cs @ Bs) * dA
        if sec.coupled:
            K += (Bm.T @ sec.Cmb @ Bb + Bb.T @ sec.Cmb @ Bm) * dA
        add_section_mass(M, np.outer(N, N) * dA, sec.inertia, iu, iv, iw, irx, iry)
    kd = DRILL * np.min(np.diag(K)[np.concatenate([iu, iv])])
    for i in range(9):
        _, dN, J, _ = jacobian(_R[i], _S[i])
        dNx = np.linalg.solve(J, dN)
        b = np.zeros(54)
        b[iv], b[iu] = -0.5 * dNx[0], 0.5 * dNx[1]
        b[irz[i]] += 1.0
        K += kd * np.outer(b, b)
    return K, M


def plate_mesh9(a: float, b: float, nx: int, ny: int):
    """Nodes (z = 0) and 9-node quads of an a x b rectangle [m] from the origin, nx x ny cells."""
    x, y = np.meshgrid(np.linspace(0, a, 2 * nx + 1), np.linspace(0, b, 2 * ny + 1), indexing="xy")
    nodes = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    row = 2 * nx + 1
    n0 = (2 * j * row + 2 * i).ravel()
    offsets = [0, 2, 2 * row + 2, 2 * row, 1, row + 2, 2 * row + 1, row, row + 1]
    return nodes, n0[:, None] + np.array(offsets)


# the serendipity centre: u_8 = -1/4 sum corners + 1/2 sum midsides (the 9-node quad whose centre
# follows the 8-node serendipity interpolation)
SERENDIPITY_CENTRE = np.array([-0.25] * 4 + [0.5] * 4)


def quad8_nodes(xy8: np.ndarray) -> np.ndarray:
    """(9, 2) the 8 nodes of a CQUAD8/S8 (corners, midsides 01 12 23 30) and the serendipity centre."""
    return np.vstack([xy8, SERENDIPITY_CENTRE @ xy8])


def quad8_matrices(xy8: np.ndarray, t: float, mat: Material, section=None, centre: str = "condensed"):
    """Local 48 x 48 K, M of the 8-node quad: the MITC9 of quad9_matrices on quad8_nodes with the
    centre's six dofs tied to the serendipity interpolation, K8 = C^T K9 C, u9 = C u8 (C: the identity
    on the 8 nodes, SERENDIPITY_CENTRE (x) I_6 for the centre). The element's displacements are then
    the 8-node serendipity field (its centre value is the serendipity one), with MITC9's assumed
    shear of that field (docs/shells.md, "CQUAD8")."""
    K9, M9 = quad9_matrices(quad8_nodes(xy8), t, mat, section)
    C = np.zeros((54, 48))
    C[:48] = np.eye(48)
    if centre == "serendipity":
        C[48:] = np.kron(SERENDIPITY_CENTRE[None, :], np.eye(6))
    elif centre == "condensed":  # Guyan: the centre at rest under no load of its own
        C[48:] = -np.linalg.solve(K9[48:, 48:], K9[48:, :48])
    else:
        raise ValueError(f"centre {centre!r}: expected 'serendipity' or 'condensed'")
    return C.T @ K9 @ C, C.T @ M9 @ C
