"""Linear finite element models behind a small interface (docs/background.md).

Reduction (ffrf_fmu.reduction) only sees `FEModel`: node coordinates, K, M and the
translational mass kernel. Beams are one producer (fe.beam); imported K/M of solids or
shells would be another, as long as they use 6 dofs per node in the same order.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.rotation import skew

DOFS_PER_NODE = 6


@dataclass(frozen=True, eq=False)
class FEModel:
    """Linear FE model behind a small interface so reduction never depends on beams."""

    coords: np.ndarray  # (n_nodes, 3) node positions, model/world axes
    K: np.ndarray  # (n_dof, n_dof), 6 dofs per node [ux uy uz rx ry rz], dof = 6*node + k, model axes
    M: np.ndarray  # (n_dof, n_dof) consistent mass
    M_kernel: np.ndarray  # (3, n_dof, n_dof): M_k = int N_t^T skew(e_k) N_t rho dV (translational mass kernel), skew-symmetric

    @property
    def n_nodes(self) -> int:
        return self.coords.shape[0]

    @property
    def n_dof(self) -> int:
        return self.K.shape[0]


def node_dofs(nodes) -> np.ndarray:
    """Global dof indices of `nodes`, node-major: (len(nodes) * 6,)."""
    return (DOFS_PER_NODE * np.asarray(nodes, dtype=int)[:, None] + np.arange(DOFS_PER_NODE)).ravel()


def rigid_modes(coords: np.ndarray, origin) -> np.ndarray:
    """Rigid-body modes about `origin` (geradin eq. 11), (6 n_nodes, 6).

    Node at X (relative to origin): translation rows [I, -skew(X)], rotation rows [0, I],
    i.e. columns = unit translations then unit (small) rotations about the model axes.
    """
    X = np.asarray(coords, dtype=float) - np.asarray(origin, dtype=float)
    n = X.shape[0]
    U = np.zeros((n, 2, 3, 2, 3))  # node, (trans|rot row), comp, (trans|rot col), comp
    U[:, 0, :, 0, :] = np.eye(3)
    U[:, 0, :, 1, :] = -skew(X)
    U[:, 1, :, 1, :] = np.eye(3)
    return U.reshape(6 * n, 6)


def lumped_kernels(mass: float, J: np.ndarray):
    """The 6 x 6 nodal blocks of M, M_k (k = 1..3) and T_ab (a, b = 1..3) of a rigid body lumped at a
    node: mass at the node, inertia J (3, 3, model axes) about it. Its points move as
    u = u_node + theta x y (y from the node, int rho y = 0), so with S = int rho y y^T = tr(J)/2 I - J
    the blocks are those of the beam section (fe.beam.element_matrices, fe.beam.tensor_kernel):
        M = diag(m I, J),  M_k = diag(m e_k~, skew(S e_k)),  T_ab = diag(m e_a e_b^T, e_a~^T S e_b~).
    Returns (M (6, 6), M_k (3, 6, 6), T (3, 3, 6, 6))."""
    J = np.asarray(J, dtype=float)
    S = 0.5 * np.trace(J) * np.eye(3) - J
    E = skew(np.eye(3))
    M = np.zeros((6, 6))
    M[:3, :3], M[3:, 3:] = mass * np.eye(3), J
    Mk = np.zeros((3, 6, 6))
    Mk[:, :3, :3] = mass * E
    Mk[:, 3:, 3:] = skew(S.T)  # row k: skew(S e_k) (S symmetric)
    T = np.zeros((3, 3, 6, 6))
    for a in range(3):
        for b in range(3):
            T[a, b, a, b] = mass  # m e_a e_b^T
    T[:, :, 3:, 3:] = np.einsum("aji,jk,bkl->abil", E, S, E)
    return M, Mk, T


def with_lumped_masses(fe: FEModel, lumped) -> FEModel:
    """`fe` with rigid bodies lumped at nodes added to M and M_kernel (`lumped_kernels`); lumped is a
    sequence of (node, mass, J (3, 3) model axes about the node). K is unchanged."""
    M, Mk = fe.M.copy(), fe.M_kernel.copy()
    for node, mass, J in lumped:
        i = node_dofs([node])
        Mn, Mkn, _ = lumped_kernels(mass, J)
        M[np.ix_(i, i)] += Mn
        Mk[:, i[:, None], i[None, :]] += Mkn
    return FEModel(coords=fe.coords, K=fe.K, M=M, M_kernel=Mk)
