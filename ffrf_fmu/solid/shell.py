"""Flat 4-node shell (MITC4 bending + bilinear membrane + drilling penalty) on 6-dof nodes, and the
assembly of these quads, shell_tri.py's DKT triangles and shell_mitc9.py's 9-node quads into one
model (docs/shells.md).

Dofs are node-major, 6 per node: dof 6 i + c, c = ux uy uz rx ry rz (global axes). Each quad is
flat (a warped quad is projected on the plane through its centre spanned by its mid-side vectors).
In the element frame (e1, e2 in plane, e3 normal), with the fibre rotations beta_x = ry, beta_y = -rx:
  membrane   eps = (u_x, v_y, u_y + v_x),            C_m = E t / (1 - nu^2) [[1 nu 0][nu 1 0][0 0 (1-nu)/2]]
  bending    kappa = (bx_x, by_y, bx_y + by_x),      C_b = t^2/12 C_m
  shear      gamma = (w_x + bx, w_y + by),           C_s = k G t I, k = 5/6
2 x 2 Gauss points; the transverse shear is Bathe & Dvorkin's (1986) assumed covariant strain
(MITC4): gamma_xi from the tying points (0, +-1), gamma_eta from (+-1, 0), interpolated linearly
and mapped to the Cartesian frame with J^-1 at the Gauss point; this removes shear locking.
Drilling (rz about e3): the penalty k_d sum_i (rz_i - omega_c)^2, omega_c = (v_x - u_y)/2 at the
centre (Hughes & Brezzi type, one point), k_d = DRILL * the smallest membrane diagonal of the
element: no energy in any rigid motion, and small enough to leave the plate modes unchanged.
Mass: consistent (2 x 2 Gauss), rho t N^T N on each translation and the rotary inertia
rho t^3 / 12 N^T N on rx, ry; none on the drilling rotation (a fibre has no spin inertia), so M
is singular on drilling dofs of a flat plate: use shift-invert eigensolvers (free_modes).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np
import scipy.sparse as sp

from .mesh import Material  # E, nu, rho: the one isotropic material of the solid family
from .shell_section import DRILL, SHEAR_FACTOR, add_section_mass, corner_frame, drilling_penalty, plate_section  # noqa: F401 (shell.DRILL, shell.SHEAR_FACTOR kept)
from .shell_mitc9 import quad9_frame, quad9_matrices
from .shell_tri import tria_frame, tria_matrices

_G = 1.0 / np.sqrt(3.0)
_GAUSS = [(-_G, -_G), (_G, -_G), (_G, _G), (-_G, _G)]
_XI = np.array([-1.0, 1.0, 1.0, -1.0])
_ETA = np.array([-1.0, -1.0, 1.0, 1.0])


@dataclass(frozen=True, eq=False)
class ShellFE:
    """A linear shell FE model: nodes, quads, triangles and 9-node quads, per-element thickness (quads,
    then triangles, then 9-node quads), sparse K and M on 6 dofs per node (dof 6 node + c, c = ux uy uz rx ry rz)."""

    coords: np.ndarray  # (n, 3) [m]
    quads: np.ndarray  # (e, 4) node indices, counter-clockwise about the element normal
    thickness: np.ndarray  # (e + e3 + e9,) [m], quads, then trias, then quads9
    material: Material
    K: sp.csr_matrix  # (6n, 6n)
    M: sp.csr_matrix  # (6n, 6n)
    trias: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=int))  # (e3, 3), counter-clockwise
    quads9: np.ndarray = field(default_factory=lambda: np.zeros((0, 9), dtype=int))  # (e9, 9), shell_mitc9.py order

    @property
    def n_nodes(self) -> int:
        return self.coords.shape[0]

    @property
    def n_dof(self) -> int:
        return 6 * self.coords.shape[0]

    def dof(self, node, component: int):
        return 6 * np.asarray(node) + component


def _shape(xi, eta):
    N = 0.25 * (1 + _XI * xi) * (1 + _ETA * eta)
    dN = np.array([0.25 * _XI * (1 + _ETA * eta), 0.25 * _ETA * (1 + _XI * xi)])  # (2, 4): d/dxi, d/deta
    return N, dN


def element_frame(X: np.ndarray):
    """Rotation T (rows e1, e2, e3) and the in-plane coordinates (4, 2) of a quad's corners X (4, 3)."""
    T = corner_frame(X)
    return T, (X - X.mean(axis=0)) @ T[:2].T


def element_matrices(xy: np.ndarray, t: float, mat: Material, section=None):
    """Local 24 x 24 K, M of a flat quad with in-plane corners xy (4, 2), local dofs per node
    (u v w rx ry rz); `section` a shell_section.PlateSection in the element axes (a laminate's, with
    its coupling B and inertia (m0, m1, m2)), else the isotropic plate of t and mat."""
    sec = plate_section(t, mat) if section is None else section
    Cm, Cb, Cs, Cmb = sec.Cm, sec.Cb, sec.Cs, sec.Cmb
    K = np.zeros((24, 24))
    M = np.zeros((24, 24))
    iu, iv, iw, irx, iry, irz = (np.arange(4) * 6 + k for k in range(6))

    def covariant_shear(xi, eta):  # rows gamma_xi, gamma_eta (2, 24) at (xi, eta)
        N, dN = _shape(xi, eta)
        J = dN @ xy
        B = np.zeros((2, 24))
        for r in range(2):
            B[r, iw] = dN[r]
            B[r, iry] += N * J[r, 0]  # beta_x = ry
            B[r, irx] -= N * J[r, 1]  # beta_y = -rx
        return B

    gA, gC = covariant_shear(0, 1)[0], covariant_shear(0, -1)[0]
    gB, gD = covariant_shear(-1, 0)[1], covariant_shear(1, 0)[1]
    area = 0.0
    for xi, eta in _GAUSS:
        N, dN = _shape(xi, eta)
        J = dN @ xy
        detJ = np.linalg.det(J)
        if detJ <= 0:
            raise ValueError(f"quad with corners {xy.tolist()} is inverted or not convex (det J = {detJ:.3g})")
        dNx = np.linalg.solve(J, dN)  # (2, 4): d/dx, d/dy
        area += detJ
        Bm = np.zeros((3, 24))
        Bm[0, iu] = dNx[0]
        Bm[1, iv] = dNx[1]
        Bm[2, iu] = dNx[1]
        Bm[2, iv] = dNx[0]
        Bb = np.zeros((3, 24))
        Bb[0, iry] = dNx[0]
        Bb[1, irx] = -dNx[1]
        Bb[2, iry] = dNx[1]
        Bb[2, irx] = -dNx[0]
        g_nat = np.array([0.5 * (1 + eta) * gA + 0.5 * (1 - eta) * gC,
                          0.5 * (1 + xi) * gD + 0.5 * (1 - xi) * gB])
        Bs = np.linalg.solve(J, g_nat)
        K += (Bm.T @ Cm @ Bm + Bb.T @ Cb @ Bb + Bs.T @ Cs @ Bs) * detJ
        if sec.coupled:
            K += (Bm.T @ Cmb @ Bb + Bb.T @ Cmb @ Bm) * detJ
        add_section_mass(M, np.outer(N, N) * detJ, sec.inertia, iu, iv, iw, irx, iry)
    N, dN = _shape(0, 0)
    drilling_penalty(K, np.linalg.solve(dN @ xy, dN), iu, iv, irz)
    return K, M


def _cells(cells, corners: int, name: str, n_nodes: int) -> np.ndarray:
    C = np.zeros((0, corners), dtype=int) if cells is None or np.size(cells) == 0 else np.asarray(cells, dtype=int)
    if C.ndim != 2 or C.shape[1] != corners:
        raise ValueError(f"{name}: shape {C.shape}, expected (e, {corners})")
    if C.size and (C.min() < 0 or C.max() >= n_nodes):
        raise ValueError(f"{name}: node index out of range 0..{n_nodes - 1}")
    return C


def assemble_shells(nodes, quads, thickness, material: Material, trias=None, tria_bending: str = "dkt",
                    quads9=None) -> ShellFE:
    """Global sparse K, M (6 dofs per node, dof 6 node + c) of flat quads, triangles (`trias`,
    (e3, 3), shell_tri.py, bending `tria_bending`: "dkt", or "mitc3" which locks) and MITC9 quads
    (`quads9`, (e9, 9), shell_mitc9.py) on `nodes` (n, 3) [m]; `thickness` a number or one per
    element, quads, then triangles, then 9-node quads [m] (PSHELL-like). Any cell list may be empty."""
    X = np.asarray(nodes, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"nodes: shape {X.shape}, expected (n, 3)")
    Q = _cells(quads, 4, "quads", len(X))
    T3 = _cells(trias, 3, "trias", len(X))
    Q9 = _cells(quads9, 9, "quads9", len(X))
    n_el = len(Q) + len(T3) + len(Q9)
    t = np.asarray(thickness, dtype=float)
    if t.ndim and t.shape != (n_el,):
        raise ValueError(f"thickness: shape {t.shape}, expected a number or ({n_el},) (quads, trias, quads9)")
    t = np.broadcast_to(t, (n_el,)).copy()
    if np.any(t <= 0):
        raise ValueError(f"thickness: element {int(np.argmin(t))} has t = {t.min():g} <= 0")
    rows, cols, kv, mv = [], [], [], []
    cells = [("quad", e, q, element_frame, element_matrices) for e, q in enumerate(Q)]
    tria = partial(tria_matrices, bending=tria_bending)
    cells += [("tria", e, q, tria_frame, tria) for e, q in enumerate(T3)]
    cells += [("quad9", e, q, quad9_frame, quad9_matrices) for e, q in enumerate(Q9)]
    for k, (kind, e, q, frame, matrices) in enumerate(cells):
        where = f"{kind} {e} (nodes {', '.join(str(int(i)) for i in q)})"
        try:
            T, xy = frame(X[q])
            Ke, Me = matrices(xy, t[k], material)
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from err
        R = np.kron(np.eye(2 * len(q)), T)  # local = R global (translations and rotations of the nodes)
        Ke, Me = R.T @ Ke @ R, R.T @ Me @ R
        d = (6 * q[:, None] + np.arange(6)).ravel()
        rows.append(np.repeat(d, len(d)))
        cols.append(np.tile(d, len(d)))
        kv.append(Ke.ravel())
        mv.append(Me.ravel())
    n = 6 * len(X)
    r, c = (np.concatenate(v) if v else np.zeros(0, dtype=int) for v in (rows, cols))
    K = sp.csr_matrix((np.concatenate(kv) if kv else np.zeros(0), (r, c)), shape=(n, n))
    M = sp.csr_matrix((np.concatenate(mv) if mv else np.zeros(0), (r, c)), shape=(n, n))
    return ShellFE(X, Q, t, material, K, M, T3, Q9)


def rigid_modes(coords: np.ndarray, centre=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(6n, 6) rigid motions: 3 translations, 3 rotations about `centre` (small-angle)."""
    X = np.asarray(coords, dtype=float) - np.asarray(centre, dtype=float)
    n = len(X)
    R = np.zeros((6 * n, 6))
    for k in range(3):
        R[k::6, k] = 1.0
        e = np.eye(3)[k]
        R[np.arange(n)[:, None] * 6 + np.arange(3), 3 + k] = np.cross(e, X)
        R[3 + k::6, 3 + k] = 1.0
    return R


def free_modes(fe: ShellFE, count: int, shift: float | None = None):
    """The lowest `count` eigenpairs (omega^2, modes) of K x = omega^2 M x, by shift-invert Lanczos
    about a small negative shift (M is singular on drilling dofs, module doc)."""
    from scipy.sparse.linalg import eigsh

    if shift is None:
        shift = -1e-3 * abs(fe.K.diagonal()).max() / abs(fe.M.diagonal()).max() * 1e-6
    w, V = eigsh(fe.K.tocsc(), k=count, M=fe.M.tocsc(), sigma=shift, which="LM")
    order = np.argsort(w)
    return w[order], V[:, order]


def plate_mesh(a: float, b: float, nx: int, ny: int):
    """Nodes (z = 0) and quads of an a x b rectangle [m] from the origin, nx x ny cells."""
    x, y = np.meshgrid(np.linspace(0, a, nx + 1), np.linspace(0, b, ny + 1), indexing="xy")
    nodes = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    n0 = (j * (nx + 1) + i).ravel()
    quads = np.column_stack([n0, n0 + 1, n0 + nx + 2, n0 + nx + 1])
    return nodes, quads
