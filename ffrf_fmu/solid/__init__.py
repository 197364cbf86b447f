"""Linear solid bodies: a sparse FE model on 3-dof nodes (from a mesh assembled with scikit-fem, or
from a partner's exported mass and stiffness matrices), interface frames on node sets, and the
sparse reduction to one superelement (ffrf_fmu/reduction_sparse.py; docs/solids.md).

Dofs are node-major, 3 translations per node: dof 3 i + c is component c of node i. The mass
matrix of every solid here has the node-block structure M = M_s (x) I_3 (each 3 x 3 node block is a
multiple of the identity: the same scalar shape functions for the three displacement components, or
a lumped mass); the scalar node matrix M_s carries the translational mass kernel and the tensor
kernel the invariants need (geradin eq. 53, Witteveen's W1/W2):
    M_k = M_s (x) e_k~,   T_ab = M_s (x) e_a e_b^T.

A body of shells, beams or offset point masses has 6 dofs per node (dof 6 i + c: ux uy uz rx ry rz;
a node's rotations that no element stiffens, e.g. of a brick's corner, are left out by the reduction)
and a mass that is not node-block: the rotary inertia of a shell's fibres, a CONM2's offset and
inertia tensor. Its mass is split into the node-block mass of the translations and mass points,
    M = S^T (M_s (x) I_3) S + sum_p w_p N_p^T N_p,
S (3n, n_dof) picking the translation dofs, N_p (3, n_dof) the displacement of a material point p
(a quadrature point through a shell's thickness: u = u_0 + z theta x n) and w_p its weight [kg]. The
same split gives every tensor kernel the invariants need, exactly as the mass does:
    T_ab = S^T (M_s (x) e_a e_b^T) S + sum_p w_p N_p,a^T N_p,b        (SolidFE.kernel)
(docs/equations.md, "Invariants of a body with rotational dofs").
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

NODE_BLOCK_TOL = 1e-9  # |M - M_s (x) I_3| / max|M| above this: not a node-block mass (say so, do not guess)


@dataclass(frozen=True, eq=False)
class MassPoints:
    """The part of a mass matrix that is not node-block, as material points (module doc):
    sum_p w_p N_p^T N_p, N_p = rows 3 p .. 3 p + 2 of N."""

    N: sp.csr_matrix  # (3 p, n_dof): row 3 p + a is displacement component a at point p
    w: np.ndarray  # (p,) [kg]; a rotary inertia without mass may need a negative weight

    def matrix(self) -> sp.csr_matrix:
        """sum_p w_p N_p^T N_p (n_dof, n_dof)."""
        return sp.csr_matrix(self.N.T @ sp.diags(np.repeat(self.w, 3)) @ self.N)


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
    dofs_per_node: int = 3  # 3 (translations) or 6 (translations, then rotations: shells, beams)
    mass_points: MassPoints | None = None  # the mass beyond S^T (M_s (x) I_3) S (module doc); None: none

    @property
    def n_nodes(self) -> int:
        return self.coords.shape[0]

    @property
    def n_dof(self) -> int:
        return self.dofs_per_node * self.coords.shape[0]

    def translation_dofs(self) -> np.ndarray:
        """(n_nodes, 3) the dof index of each node's ux, uy, uz."""
        return self.dofs_per_node * np.arange(self.n_nodes)[:, None] + np.arange(3)

    def translations(self, Y: np.ndarray) -> np.ndarray:
        """(n_nodes, 3, k) the node translations of the fields Y (n_dof, k)."""
        Y = np.asarray(Y)
        return Y.reshape(self.n_nodes, self.dofs_per_node, -1)[:, :3]

    def field(self, u: np.ndarray) -> np.ndarray:
        """(n_dof,) the field with node translations u (n_nodes, 3) and no rotation."""
        x = np.zeros((self.n_nodes, self.dofs_per_node))
        x[:, :3] = u
        return x.reshape(-1)

    def kernel(self, A) -> sp.csr_matrix:
        """sum_ab A_ab T_ab (n_dof, n_dof): the tensor kernel of the mass (module doc) for a 3 x 3 A:
        A = I gives M, A = e_k~ the translational kernel M_k (geradin 53), A = I - a a^T the spin
        softening about the axis a."""
        A = sp.csr_matrix(np.asarray(A, dtype=float))
        S = _translation_selector(self)
        out = S.T @ sp.kron(self.M_scalar, A, format="csr") @ S
        if self.mass_points is not None:
            out = out + self.mass_points.N.T @ sp.kron(sp.diags(self.mass_points.w), A, format="csr") \
                @ self.mass_points.N
        return sp.csr_matrix(out)


def _translation_selector(fe: SolidFE) -> sp.csr_matrix:
    """S (3n, n_dof): S x = the node translations of x (module doc)."""
    cols = fe.translation_dofs().reshape(-1)
    return sp.csr_matrix((np.ones(cols.size), (np.arange(cols.size), cols)), shape=(cols.size, fe.n_dof))


def tensor_products(fe: SolidFE, Y: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Q (3, 3, k, l), Q_ab = Y^T T_ab Z for fields Y (n_dof, k), Z (n_dof, l): the kernels of
    reduction_sparse.node_kernels, from the node-block mass and the mass points (module doc)."""
    Yn, Zn = fe.translations(Y), fe.translations(Z)
    MsZ = np.stack([fe.M_scalar @ Zn[:, b, :] for b in range(3)])  # (3, n_nodes, l)
    Q = np.einsum("iaj,bil->abjl", Yn, MsZ, optimize=True)
    if fe.mass_points is not None:
        p = len(fe.mass_points.w)
        NY = np.asarray(fe.mass_points.N @ Y).reshape(p, 3, -1)
        NZ = np.asarray(fe.mass_points.N @ Z).reshape(p, 3, -1)
        Q = Q + np.einsum("paj,p,pbl->abjl", NY, fe.mass_points.w, NZ, optimize=True)
    return Q


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


def six_dof_fe(coords, K, M, M_scalar, mass_points: MassPoints | None, node_sets=None, source: str = "",
               cells=()) -> SolidFE:
    """A SolidFE on 6 dofs per node (shells, beams, offset masses; module doc), checked: K and M of
    shape (6n, 6n) and M = S^T (M_s (x) I_3) S + mass points to NODE_BLOCK_TOL of max|M| (the
    invariants are built from that split, so a split that does not add up to M is refused)."""
    coords = np.asarray(coords, dtype=float)
    n = coords.shape[0]
    K, M, Ms = sp.csr_matrix(K), sp.csr_matrix(M), sp.csr_matrix(M_scalar)
    for name, A, shape in (("stiffness", K, (6 * n, 6 * n)), ("mass", M, (6 * n, 6 * n)), ("node mass", Ms, (n, n))):
        if A.shape != shape:
            raise ValueError(f"{source}: {name} matrix is {A.shape}, expected {shape} for {n} nodes x 6 dofs")
    fe = SolidFE(coords, K, M, Ms, {k: np.asarray(v, dtype=int) for k, v in (node_sets or {}).items()}, source,
                 tuple(cells), dofs_per_node=6, mass_points=mass_points)
    dev = (fe.kernel(np.eye(3)) - M).tocoo()
    scale = abs(M).max()
    if dev.nnz and np.abs(dev.data).max() > NODE_BLOCK_TOL * scale:
        k = int(np.argmax(np.abs(dev.data)))
        raise ValueError(f"{source}: the node mass and mass points do not add up to the mass matrix: entry "
                         f"({dev.row[k]}, {dev.col[k]}) deviates by {abs(dev.data[k]) / scale:.1e} of max|M|")
    return fe
