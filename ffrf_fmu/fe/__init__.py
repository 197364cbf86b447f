"""Linear finite element models behind a small interface (formulation.md section 1).

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
