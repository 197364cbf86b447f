"""Geometric stiffening of a solid superelement from the element stresses of its mesh
(docs/equations.md, "Geometric stiffening of a solid"): the centrifugal correction modes the sparse
reduction appends (correction_modes) and the second-order strain energy of the basis (membrane_tensors).

The Green-Lagrange strain of the superelement's own deformation u = Y q (Y the basis of eq. 76 on
the FE dofs, q = q_bar) is E(u) = eps(u) + 1/2 grad u^T grad u, eps the linear strain. Its strain
energy beyond the linear 1/2 q^T K q is

    V2 = int sigma(eps) : E2 + 1/2 int E2 : C : E2,   E2 = 1/2 grad u^T grad u.

In the energy inner product <e1, e2> = int e1 : C : e2 the linear strains of the basis, S q, span an
r-dimensional space (r = n: every column of Y deforms). With an orthonormal basis E_k of it (E_k =
S T_k, T = V L^-1/2 from K_bar = S^T C S = V L V^T),

    a = L^1/2 V^T (r, n)      (a^T a = K_bar: the linear strain in the coordinates of E)
    B_k = sum_j T_jk G_j,     G_j[i, l] = int sigma_j : sym(grad u_i^T grad u_l),  sigma_j = C eps(Y_j)

so that sigma_k = 1/2 q^T B_k q = <E_k, E2(q)> and the beam's form holds exactly for the cubic term:
    a q . sigma = 1/2 q^T (sum_j q_j G_j) q = int sigma(u) : E2(u)
(G_j is the FE geometric stiffness of the stress of column j, projected on the basis). The quartic
term 1/2 sigma . sigma is int E2 : C : E2 with E2 projected on span(S q) (the assumed strain of the
beam: a basis of a few shapes cannot cancel an arbitrary E2 without locking). The steady-spin
stiffness K_bar + sum_k (a q0)_k B_k is the FE model's K + K_G(sigma(Y q0)) on the basis.
"""
from __future__ import annotations

import numpy as np

from . import SolidFE

CORRECTION_THRESHOLD = 1e-3  # as reduction.CORRECTION_THRESHOLD: a centrifugal shape kept above this (M-norm)


def centrifugal_loads(fe: SolidFE, Ur: np.ndarray) -> np.ndarray:
    """(3 N, 6) the FE loads F_ab of the centrifugal field about the CM, one per product w_a w_b
    (pairs 00, 11, 22, 01, 02, 12), as reduction.centrifugal_loads: F_ab = -(M_b U_ra + M_a U_rb) / 2,
    M_k = M_s (x) e_k~ (solid/__init__.py), so that Y^T F_ab = W1[:, a, b] / 2."""
    from ..runtime.rotation import skew

    E = skew(np.eye(3))

    def Mk(k, x):
        xn = x.reshape(-1, 3)
        return np.asarray(fe.M_scalar @ (xn @ E[k].T)).reshape(-1)

    pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    return np.stack([-0.5 * (Mk(b, Ur[:, a]) + Mk(a, Ur[:, b])) for a, b in pairs], axis=1)


def correction_modes(fe, M, c, static, YB, Xi, Ur) -> np.ndarray:
    """Static correction modes for the centrifugal load about the CM (reduction.correction_modes, on the
    sparse model; c the reduction's Constraints, M its mass in z, static(b) = G_e b the free static solve
    of reduction_sparse.free_static): the free static responses x_ab = G_e F_ab, made zero on the frames with the
    attachment columns (x - Y_B L x), M-orthogonalized against the kept modes and M-orthonormalized
    (eigen-decomposition of their 6 x 6 M-Gram matrix); a shape is kept when its M-norm exceeds
    CORRECTION_THRESHOLD of the largest response's. Returns (n_z, k)."""
    F = c.T.T @ centrifugal_loads(fe, Ur)
    x = static(F)
    r = x - YB @ (c.L @ x)
    Ym = Xi - YB @ (c.L @ Xi)
    if Ym.shape[1]:
        MYm = np.asarray(M @ Ym)
        r -= Ym @ np.linalg.solve(Ym.T @ MYm, MYm.T @ r)
    scale = np.sqrt(np.einsum("ij,ij->j", x, np.asarray(M @ x))).max()
    if scale == 0.0:
        return np.zeros((M.shape[0], 0))
    g, V = np.linalg.eigh(r.T @ np.asarray(M @ r))
    sv = np.sqrt(np.maximum(g, 0.0))
    keep = sv > CORRECTION_THRESHOLD * scale
    return r @ V[:, keep] / sv[keep]


POINTS = 8192  # quadrature points per batch of membrane_tensors (n = 24: 8192 x 576 doubles = 38 MB per product)
STRAIN_RANK_TOL = 1e-9  # energy eigenvalues below this fraction of the largest are round-off (rigid content)


def membrane_tensors(strain, Yf: np.ndarray) -> dict:
    """{"vk_a" (r, n), "vk_B" (r, n, n)} of the basis Yf (3 N, n) on the mesh of `strain`
    (mesh.MeshStrain): module doc. Also "K_strain" (n, n) = S^T C S, which equals Y^T K Y (a check)."""
    from .mesh import _element, element_geometry, lame, quadrature_order

    lam, mu = lame(strain.material)
    n = Yf.shape[1]
    _, _, N, chunks = element_geometry(strain.mesh, _element(strain.element), quadrature_order(strain.element))
    if 3 * N != Yf.shape[0]:
        raise ValueError(f"basis has {Yf.shape[0]} rows, the mesh {3 * N} dofs")
    Ks = np.zeros((n, n))
    G = np.zeros((n, n, n))
    for _, vd_c, dphi_c, dx_c in chunks:
        nq = dphi_c.shape[1]
        step = max(1, POINTS // nq)  # elements per batch: the (points, n^2) products stay ~POINTS x n^2 doubles
        for e0 in range(0, len(vd_c), step):
            vd, dphi, dx = vd_c[e0 : e0 + step], dphi_c[e0 : e0 + step], dx_c[e0 : e0 + step]
            ne, _, nloc, _ = dphi.shape
            Ue = Yf[vd].reshape(ne, nloc, 3, n)
            Gu = np.einsum("eiaj,eqib->eqjab", Ue, dphi, optimize=True).reshape(ne * nq, n, 3, 3)  # du_a/dX_b
            w = dx.reshape(-1)
            eps = 0.5 * (Gu + Gu.transpose(0, 1, 3, 2))
            tr = np.einsum("gjaa->gj", eps)
            sig = 2.0 * mu * eps + lam * tr[:, :, None, None] * np.eye(3)  # (g, n, 3, 3)
            sw = sig * w[:, None, None, None]
            Ks += np.einsum("gjab,giab->ji", sw, eps, optimize=True)
            for b in range(3):  # G_j[i, l] = sum_g sum_bc (w sigma_j)[b, c] (Gu_i^T Gu_l)[b, c]
                Gb = np.ascontiguousarray(Gu[:, :, :, b])  # (g, n, 3): column b of each grad u_i
                for cc in range(3):
                    P = np.matmul(Gb, Gu[:, :, :, cc].transpose(0, 2, 1)).reshape(len(w), n * n)  # (Gu_i^T Gu_l)[b, c]
                    G += (sw[:, :, b, cc].T @ P).reshape(n, n, n)
    Ks = 0.5 * (Ks + Ks.T)
    G = 0.5 * (G + G.transpose(0, 2, 1))
    lam_k, V = np.linalg.eigh(Ks)
    keep = lam_k > STRAIN_RANK_TOL * lam_k.max()
    lam_k, V = lam_k[keep], V[:, keep]
    T = V / np.sqrt(lam_k)
    a = np.sqrt(lam_k)[:, None] * V.T
    B = np.einsum("jk,jil->kil", T, G)
    return {"vk_a": a, "vk_B": 0.5 * (B + B.transpose(0, 2, 1)), "K_strain": Ks, "G_modes": G}


def geometric_stiffness(strain, u: np.ndarray):
    """The FE geometric stiffness K_G(sigma(u)) (3 N, 3 N, sparse) of the stress of the displacement
    u (3 N,) on the mesh of `strain`: K_G[(i a), (l a)] = int grad phi_i . sigma grad phi_l (the full
    model's stress stiffening, against which the reduced one is checked)."""
    import scipy.sparse as sp

    from .mesh import _element, element_geometry, lame, quadrature_order

    lam, mu = lame(strain.material)
    _, _, N, chunks = element_geometry(strain.mesh, _element(strain.element), quadrature_order(strain.element))
    rows, cols, vals = [], [], []
    for _, vd, dphi, dx in chunks:
        ne, nq, nloc, _ = dphi.shape
        Ue = u[vd].reshape(ne, nloc, 3)
        Gu = np.einsum("eia,eqib->eqab", Ue, dphi)
        eps = 0.5 * (Gu + Gu.transpose(0, 1, 3, 2))
        sig = 2.0 * mu * eps + lam * np.einsum("eqaa->eq", eps)[:, :, None, None] * np.eye(3)
        Ke = np.einsum("eqib,eqbc,eqlc,eq->eil", dphi, sig, dphi, dx, optimize=True)  # (ne, nloc, nloc)
        nodes = vd[:, 0::3] // 3
        for a in range(3):
            rows.append(np.repeat(3 * nodes + a, nloc, axis=1).ravel())
            cols.append(np.tile(3 * nodes + a, (1, nloc)).ravel())
            vals.append(Ke.ravel())
    return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(3 * N, 3 * N)).tocsr()
