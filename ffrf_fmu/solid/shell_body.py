"""A shell model (solid/shell.py) as the reduction's input: a SolidFE on 6 dofs per node whose mass is
split into the node-block mass of the mid-surface and the mass points of the fibres' rotary inertia
(solid/__init__.py; docs/equations.md, "Invariants of a body with rotational dofs").

A material point at height z on the fibre of a mid-surface point moves by u = u_0 + z theta x n
(n the element normal, theta the node rotations interpolated like u_0: the shell's kinematics). Its
tensor kernel over the element is
    T_ab = int rho t N^T N e_a e_b^T  +  int rho (t^3 / 12) (N (-n~))_a^T (N (-n~))_b
(the cross terms vanish: int z = 0 over the thickness), the first on the translations (M_s, node
block), the second on the rotations. The second is integrated by the element's mass quadrature
(shell.py: 2 x 2 Gauss, exact for N_i N_j on a parallelogram) and through the thickness by the
two Gauss points z = +-t / (2 sqrt 3), which carry equal and opposite fields; the kernels being
quadratic in the field, one point at z = t / sqrt(12) with both weights stands for them:
    w_p = rho t det J_g,   N_p = (t / sqrt 12) N(xi_g) (-n~)   on the element's node rotations.
Summed with M_s this is the shell's consistent mass (rho t^3/12 N^T N on the two fibre rotations, none
on the drilling rotation, as T^T diag(1, 1, 0) T = I - n n^T): six_dof_fe checks that it adds up.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import MassPoints, SolidFE, six_dof_fe
from .shell import _GAUSS, ShellFE, _shape, element_frame


def shell_body(shell: ShellFE, node_sets=None, source: str = "") -> SolidFE:
    """The SolidFE (6 dofs per node, node-block mass and fibre mass points: module doc) of a shell model."""
    X, Q, t, rho = shell.coords, shell.quads, shell.thickness, shell.material.rho
    n = len(X)
    ms_rows, ms_cols, ms_vals = [], [], []
    p_rows, p_cols, p_vals, weights = [], [], [], []
    skew_rows = np.array([[1, 2], [0, 2], [0, 1]])  # the nonzero columns of row a of n~
    p = 0
    for e, q in enumerate(Q):
        T, xy = element_frame(X[q])
        nrm = T[2]
        nx = np.array([[0.0, -nrm[2], nrm[1]], [nrm[2], 0.0, -nrm[0]], [-nrm[1], nrm[0], 0.0]])
        z = t[e] / np.sqrt(12.0)
        for xi, eta in _GAUSS:
            N, dN = _shape(xi, eta)
            detJ = float(np.linalg.det(dN @ xy))
            ms_rows.append(np.repeat(q, 4)), ms_cols.append(np.tile(q, 4))
            ms_vals.append(rho * t[e] * detJ * np.outer(N, N).ravel())
            for a in range(3):  # N_p row a: z N_i (-n~)[a, c] on rotation c of node i
                c = skew_rows[a]
                p_rows.append(np.full(8, 3 * p + a))
                p_cols.append((6 * q[:, None] + 3 + c).ravel())
                p_vals.append((-z * N[:, None] * nx[a, c]).ravel())
            weights.append(rho * t[e] * detJ)
            p += 1
    Ms = sp.csr_matrix((np.concatenate(ms_vals), (np.concatenate(ms_rows), np.concatenate(ms_cols))), shape=(n, n))
    Np = sp.csr_matrix((np.concatenate(p_vals), (np.concatenate(p_rows), np.concatenate(p_cols))), shape=(3 * p, 6 * n))
    cells = (("quad", np.asarray(Q, dtype=int)),) if len(Q) else ()
    return six_dof_fe(X, shell.K, shell.M, Ms, MassPoints(Np, np.asarray(weights)), node_sets,
                      source or f"{len(Q)} MITC4 shells", cells)
