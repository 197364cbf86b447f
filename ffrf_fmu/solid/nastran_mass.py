"""K and M of a Nastran deck as they are assembled (ffrf_fmu/solid/nastran.py), with the mass kept in
the split the 6-dof body needs (solid/__init__.py; docs/nastran.md, "The deck as a body"):
    M = S^T (M_s (x) I_3) S + sum_p w_p N_p^T N_p,
M_s the node-block mass of the translations (every element's rho N_i N_j, lumped translational
masses) and mass points for the rest:
  - a point of mass m at offset d from its node (CONM2): N = [I, -d~] on the node's 6 dofs, w = m
    (its displacement u + theta x d);
  - a rotary inertia J about a node (CONM2's inertia, a lumped beam's torsion, a beam section):
    points that move by theta x e_k, N = -e_k~ on the rotations, at unit distance along the
    eigenvectors e_k of the second moment S = tr(J)/2 I - J with weights its eigenvalues s_k
    (sum_k s_k (I - e_k e_k^T) = tr(S) I - S = J; s_k < 0 is allowed: J need not be a body's own);
  - the consistent beam mass of fe/beam.py: at its 4 Gauss points the centreline point
    (N = N_c, w = m L w_g) and the section's second moments S = R diag(0, m33, m22) R^T as points
    N = -e_k~ N_t, w = s_k L w_g (fe/beam.py's tensor_kernel: int m N_c^T N_c + N_t^T E^T S E N_t).
Every mass goes in through these, so the split adds up to M by construction.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..fe.beam import local_interpolation
from . import MassPoints


def skew(v) -> np.ndarray:
    """v~ with v~ x = v cross x, for v (..., 3)."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


class Assembly:
    """Triplets of K, of M_s and of the mass points of a model on n 6-dof nodes (module doc)."""

    def __init__(self, n_nodes: int):
        self.n = n_nodes
        self.k = ([], [], [])
        self.ms = ([], [], [])
        self.p = ([], [], [])
        self.w = []
        self.n_points = 0
        self.cells = {}  # meshio cell type -> list of node index rows (VTK output)

    def cell(self, kind: str, nodes):
        """Record an element's nodes as a meshio cell of type `kind` (no effect on K or M)."""
        self.cells.setdefault(kind, []).append(np.asarray(nodes, dtype=int))

    def cell_blocks(self) -> tuple:
        return tuple((kind, np.array(rows)) for kind, rows in self.cells.items())

    def stiffness(self, dofs, Ke):
        """Element stiffnesses Ke (ne, k, k) on dofs (ne, k)."""
        dofs, Ke = np.atleast_2d(dofs), np.asarray(Ke).reshape(-1, np.shape(dofs)[-1], np.shape(dofs)[-1])
        k = dofs.shape[1]
        for lst, v in zip(self.k, (np.repeat(dofs, k, axis=1), np.tile(dofs, (1, k)), Ke.reshape(len(Ke), -1))):
            lst.append(np.ravel(v))

    def node_mass(self, nodes, Ms):
        """Node-block masses Ms (ne, k, k) on node indices (ne, k): Ms (x) I_3 on their translations."""
        nodes = np.atleast_2d(nodes)
        k = nodes.shape[1]
        Ms = np.asarray(Ms, dtype=float).reshape(-1, k, k)
        for lst, v in zip(self.ms, (np.repeat(nodes, k, axis=1), np.tile(nodes, (1, k)), Ms.reshape(len(Ms), -1))):
            lst.append(np.ravel(v))

    def points(self, dofs, N, w):
        """Mass points: N (p, 3, k) on dofs (p, k) (or one (k,) row for all), weights w (p,)."""
        N = np.asarray(N, dtype=float)
        dofs = np.broadcast_to(np.asarray(dofs), (N.shape[0], N.shape[2]))
        p0 = self.n_points
        self.n_points += N.shape[0]
        rows = 3 * (p0 + np.arange(N.shape[0]))[:, None, None] + np.arange(3)[None, :, None]
        self.p[0].append(np.broadcast_to(rows, N.shape).ravel())
        self.p[1].append(np.broadcast_to(dofs[:, None, :], N.shape).ravel())
        self.p[2].append(N.ravel())
        self.w.append(np.asarray(w, dtype=float).ravel())

    def inertia(self, node: int, J, scale=1.0):
        """Rotary inertia J (3, 3) about node `node` as points on its rotations (module doc)."""
        J = np.asarray(J, dtype=float)
        s, E = np.linalg.eigh(np.trace(J) / 2 * np.eye(3) - J)
        keep = np.abs(s) > 0.0
        if np.any(keep):
            self.points(6 * node + 3 + np.arange(3), -skew(E.T[keep]), scale * s[keep])

    def offset_mass(self, node: int, m: float, d):
        """A point mass m at offset d from node `node` (module doc)."""
        N = np.concatenate([np.eye(3), -skew(d)], axis=1)[None]
        self.points(6 * node + np.arange(6), N, [m])

    def conm2(self, refuse, mass, X, node: int):
        """A CONM2 on node index `node`: its mass at the offset (CID 0: X the offset in the basic frame,
        -1: X the position) and its inertia about the centre of mass (MSC QRG: I21, I31, I32 enter J with
        a minus sign)."""
        if mass.cid not in (0, -1):
            refuse("CONM2", mass.eid, f"CID = {mass.cid} not supported (0 or -1)")
        self.offset_mass(node, mass.mass, np.asarray(mass.X, float) - (X[node] if mass.cid == -1 else 0.0))
        I11, I21, I22, I31, I32, I33 = mass.I
        self.inertia(node, np.array([[I11, -I21, -I31], [-I21, I22, -I32], [-I31, -I32, I33]]))

    def beam_mass(self, section, L: float, R: np.ndarray, dofs):
        """fe/beam.py's consistent mass of one element (length L, frame columns R) as mass points."""
        Nc, Nt, _ = local_interpolation(section, np.array([L]))
        T = np.kron(np.eye(4), R.T)  # local dofs = T @ model dofs
        Nc = np.einsum("ij,gjk,kl->gil", R, Nc[0], T)
        Nt = np.einsum("ij,gjk,kl->gil", R, Nt[0], T)
        wg = 0.5 * np.polynomial.legendre.leggauss(Nc.shape[0])[1] * L
        self.points(dofs, Nc, section.m * wg)
        for axis, s in ((1, section.m33), (2, section.m22)):  # S = R diag(0, m33, m22) R^T
            if s:
                self.points(dofs, np.einsum("ij,gjk->gik", -skew(R[:, axis]), Nt), s * wg)

    def matrices(self, wtmass: float = 1.0):
        """K, M (6n x 6n), M_s (n x n) and the MassPoints (M scaled by wtmass, module doc)."""
        n6 = 6 * self.n

        def coo(parts, shape):
            r, c, v = (np.concatenate(x) if x else np.zeros(0) for x in parts)
            return sp.csr_matrix((v, (r.astype(int), c.astype(int))), shape=shape)

        K = coo(self.k, (n6, n6))
        Ms = wtmass * coo(self.ms, (self.n, self.n))
        w = wtmass * (np.concatenate(self.w) if self.w else np.zeros(0))
        pts = MassPoints(coo(self.p, (3 * len(w), n6)), w)
        S = sp.csr_matrix((np.ones(3 * self.n), (np.arange(3 * self.n), (6 * np.arange(self.n)[:, None]
                           + np.arange(3)).ravel())), shape=(3 * self.n, n6))
        M = sp.csr_matrix(S.T @ sp.kron(Ms, sp.identity(3)) @ S + pts.matrix())
        return K, M, Ms, pts
