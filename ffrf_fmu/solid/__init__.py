"""Linear solid bodies: a sparse FE model on 3-dof nodes (from a mesh assembled with scikit-fem, or
from a partner's exported mass and stiffness matrices), interface frames on node sets, and the
sparse reduction to one superelement (ffrf_fmu/reduction_sparse.py; docs/solids.md).

Dofs are node-major, 3 translations per node: dof 3 i + c is component c of node i. The mass
matrix of every solid here has the node-block structure M = M_s (x) I_3 (each 3 x 3 node block is a
multiple of the identity: the same scalar shape functions for the three displacement components, or
a lumped mass); the scalar node matrix M_s carries the translational mass kernel and the tensor
kernel the invariants need (geradin eq. 53, Witteveen's W1/W2):
    M_k = M_s (x) e_k~,   T_ab = M_s (x) e_a e_b^T.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

NODE_BLOCK_TOL = 1e-9  # |M - M_s (x) I_3| / max|M| above this: not a node-block mass (say so, do not guess)


@dataclass(frozen=True, eq=False)
class SolidFE:
    """A linear FE solid: node coordinates, sparse K and M (node-major, 3 dofs per node) and the
    scalar node mass M_s with M = M_s (x) I_3 (module doc), named node sets (0-based node indices)."""

    coords: np.ndarray  # (n, 3) [m]
    K: sp.csr_matrix  # (3n, 3n) [N/m]
    M: sp.csr_matrix  # (3n, 3n) [kg]
    M_scalar: sp.csr_matrix  # (n, n) [kg]
    node_sets: dict = field(default_factory=dict)  # name -> (k,) int node indices
    source: str = ""  # where it came from (messages, reports)
    cells: tuple = ()  # ((meshio cell type, (n_cells, k) node indices), ...) for VTK output; () if none
    strain: object = None  # mesh.MeshStrain of a mesh assembled here (geometric stiffening); None for an export

    @property
    def n_nodes(self) -> int:
        return self.coords.shape[0]

    @property
    def n_dof(self) -> int:
        return 3 * self.coords.shape[0]


def node_block_mass(M: sp.spmatrix, what: str = "the mass matrix") -> sp.csr_matrix:
    """The scalar node mass M_s of a node-major 3-dof mass matrix M = M_s (x) I_3, checked to hold:
    every 3 x 3 node block a multiple of the identity to NODE_BLOCK_TOL of max|M|. Raises ValueError
    naming the worst block otherwise (the invariants need this structure, module doc)."""
    M = sp.csr_matrix(M)
    n = M.shape[0] // 3
    if M.shape != (3 * n, 3 * n):
        raise ValueError(f"{what}: shape {M.shape} is not 3 dofs per node")
    Ms = sp.csr_matrix(M[0::3, 0::3])
    dev = (M - sp.kron(Ms, sp.identity(3), format="csr")).tocoo()
    scale = abs(M).max()
    if dev.nnz and np.abs(dev.data).max() > NODE_BLOCK_TOL * scale:
        k = int(np.argmax(np.abs(dev.data)))
        i, j = dev.row[k], dev.col[k]
        raise ValueError(f"{what} is not of node-block form M_s (x) I_3: block of nodes ({i // 3}, {j // 3}), entry "
                         f"({i % 3}, {j % 3}) deviates by {abs(dev.data[k]) / scale:.1e} of max|M| "
                         f"(> {NODE_BLOCK_TOL:g}); a solid's translational mass kernel needs it")
    return Ms


def solid_fe(coords, K, M, node_sets=None, source: str = "", cells=()) -> SolidFE:
    """A SolidFE with K, M symmetric sparse and M_s from M (node_block_mass); checks shapes."""
    coords = np.asarray(coords, dtype=float)
    n = coords.shape[0]
    K, M = sp.csr_matrix(K), sp.csr_matrix(M)
    for name, A in (("stiffness", K), ("mass", M)):
        if A.shape != (3 * n, 3 * n):
            raise ValueError(f"{source}: {name} matrix is {A.shape}, expected {(3 * n, 3 * n)} for {n} nodes x 3 dofs")
    return SolidFE(coords, K, M, node_block_mass(M, f"{source}: the mass matrix"),
                   {k: np.asarray(v, dtype=int) for k, v in (node_sets or {}).items()}, source, tuple(cells))
