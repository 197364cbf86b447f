"""The sparse factorization of a solid's K - sigma M (reduction_sparse.py): SuperLU in symmetric mode
on a fill-reducing ordering by geometric nested dissection of the mesh's node graph
(docs/solids.md, "Scale").

Nested dissection (George 1973): split the nodes by a plane normal to the longest extent of their
bounding box, take as separator S the nodes on the lower side coupled to a node on the upper side,
order the two halves first (recursively) and S last. Eliminating a half then creates fill only inside
it and in S, so the factor of a 3D mesh grows as n^(4/3) and its work as n^2 (measured n^1.4 and
n^1.7 to n^2.0 on the benchmark bar from 56k to 230k dofs). Any mesh: the planes come from the node
coordinates, the separators from the matrix's couplings (tetrahedra, partners' exports). The plane is
chosen among the node coordinates between the 40 % and 60 % quantiles of the set as the one with the
smallest separator: on a quadratic mesh a plane through element faces cuts one layer of nodes, a
plane through mid-nodes two.
Measured on the benchmark bar of hex27 (docs/solids.md, "Scale") against SuperLU's MMD_AT_PLUS_A
ordering: 38,475 dofs, LU 11.2 -> 6.8 CPU s; 107,163 dofs, LU 159 -> 52 CPU s, factors 2.95e8 -> 1.98e8
entries.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

LEAF = 16  # nodes: a set this small is not split (measured: 8 to 24 within 15 % of each other, 256 twice the LU)
CANDIDATES = 32  # cut planes tried per split


def node_graph(A: sp.spmatrix, dof_node: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """The node adjacency of a matrix on node dofs: nodes i, j adjacent when any dof of i couples to any
    dof of j. dof_node (n,): the node of each dof, -1 for a dof without one (left out)."""
    has = dof_node >= 0
    P = sp.csr_matrix((np.ones(int(has.sum())), (dof_node[has], np.flatnonzero(has))), shape=(n_nodes, A.shape[0]))
    B = sp.csr_matrix(A, copy=True)
    B.data = np.ones_like(B.data)
    G = (P @ B @ P.T).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    return G


def _split(G: sp.csr_matrix, X: np.ndarray, idx: np.ndarray, inset: np.ndarray):
    """(lower, upper, separator) node indices of idx (module doc), or None when idx cannot be cut."""
    P = X[idx]
    ax = int(np.argmax(P.max(0) - P.min(0)))
    x = P[:, ax]
    cands = np.unique(np.quantile(x, np.linspace(0.4, 0.6, CANDIDATES), method="nearest"))
    cands = cands[cands > x.min()]
    if cands.size == 0:
        return None
    sub = G[idx]
    cols = sub.indices
    reach = np.where(inset[cols], X[cols, ax], -np.inf)  # neighbours outside the set do not count
    starts = sub.indptr[:-1]
    top = np.full(idx.size, -np.inf)
    nonempty = np.diff(sub.indptr) > 0
    top[nonempty] = np.maximum.reduceat(reach, starts[nonempty])  # the highest coordinate each node reaches
    lower = x[None, :] < cands[:, None]
    sizes = (lower & (top[None, :] >= cands[:, None])).sum(1)
    best = int(np.argmin(sizes))
    low = lower[best]
    sep = low & (top >= cands[best])
    return idx[low & ~sep], idx[~low], idx[sep]


def nested_dissection(G: sp.csr_matrix, X: np.ndarray) -> np.ndarray:
    """A node ordering of the graph G (n, n) with node positions X (n, 3): module doc."""
    n = G.shape[0]
    inset = np.zeros(n, dtype=bool)
    out = []

    def order(idx):
        if idx.size <= LEAF:
            out.append(idx)
            return
        inset[idx] = True
        parts = _split(G, X, idx, inset)
        inset[idx] = False
        if parts is None or parts[2].size == idx.size:
            out.append(idx)
            return
        order(parts[0])
        order(parts[1])
        out.append(parts[2])

    order(np.arange(n))
    perm = np.concatenate(out)
    assert perm.size == n and np.unique(perm).size == n
    return perm


@dataclass(frozen=True, eq=False)
class PermutedLU:
    """The LU of P A P^T (SuperLU, symmetric mode, natural order): solve(b) = A^-1 b."""

    lu: object  # scipy.sparse.linalg.SuperLU
    perm: np.ndarray  # (n,) new -> old dof

    def solve(self, b):
        b = np.asarray(b, dtype=float)
        x = np.empty_like(b)
        x[self.perm] = self.lu.solve(np.asfortranarray(b[self.perm]))
        return x

    @property
    def fill(self) -> int:
        """Stored entries of L and U (memory: 8 bytes and an index each)."""
        return int(self.lu.nnz)


ORDERINGS = ("nested_dissection", "MMD_AT_PLUS_A")


def factor(A: sp.spmatrix, dof_node: np.ndarray, coords: np.ndarray, ordering: str = "nested_dissection") -> PermutedLU:
    """Sparse LU of the symmetric positive definite A on node dofs, ordered by nested dissection of its
    node graph (module doc); dofs without a node (dof_node -1: a rigid frame's own 6, coupled to its
    whole set) come last. Diagonal pivots (A is positive definite). ordering "MMD_AT_PLUS_A": SuperLU's
    own minimum degree on A^T + A instead (what the reduction used before; kept for comparison)."""
    if ordering not in ORDERINGS:
        raise ValueError(f"ordering {ordering!r}: expected one of {', '.join(ORDERINGS)}")
    if ordering != "nested_dissection":
        lu = spla.splu(sp.csc_matrix(A), permc_spec=ordering, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        return PermutedLU(lu, np.arange(A.shape[0]))
    dof_node = np.asarray(dof_node)
    G = node_graph(A, dof_node, coords.shape[0])
    nodes = np.unique(dof_node[dof_node >= 0])
    sub = G[nodes][:, nodes].tocsr()
    node_order = nodes[nested_dissection(sub, coords[nodes])]
    rank = np.full(coords.shape[0], -1)
    rank[node_order] = np.arange(node_order.size)
    key = np.where(dof_node >= 0, rank[np.maximum(dof_node, 0)], node_order.size)
    perm = np.lexsort((np.arange(dof_node.size), key))
    Ap = sp.csc_matrix(A)[perm][:, perm].tocsc()
    lu = spla.splu(Ap, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return PermutedLU(lu, perm)
