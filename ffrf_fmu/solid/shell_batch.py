"""MITC4 shells assembled for many elements at once: the element of solid/shell.py (its plain, one
element at a time twin and oracle: tests/test_shell_body.py compares them entry by entry) written as
array operations over blocks of elements, so that a mesh of 200,000 dofs assembles in seconds (a
Python loop over elements spent 2.2 ms per quad; docs/shells.md, "Scale").

Same formulation, symbols and dof order as shell.py: per element the frame T (rows e1, e2, e3), the
in-plane corners xy, at each of the 2 x 2 Gauss points J = dN xy, the membrane, bending and
Bathe-Dvorkin shear strains Bm, Bb, Bs, K = sum (Bm^T Cm Bm + Bb^T Cb Bb + Bs^T Cs Bs) det J, the
drilling penalty at the centre, the consistent mass, then K_global = R^T K R with R = I_8 (x) T.
Also the fibres' mass points of shell_body.py (one point per Gauss point at z = t / sqrt 12).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .mesh import Material
from .shell import _ETA, _GAUSS, _XI, DRILL, SHEAR_FACTOR, ShellFE, _shape

BLOCK = 4096  # elements per block: (BLOCK, 24, 24) arrays of 19 MB, a few of them alive at once


def element_frames(X: np.ndarray):
    """(T (e, 3, 3) rows e1, e2, e3; xy (e, 4, 2)) of quads with corners X (e, 4, 3), as shell.element_frame."""
    c = X.mean(axis=1)
    g1 = (X[:, 1] + X[:, 2] - X[:, 0] - X[:, 3]) / 2
    g2 = (X[:, 2] + X[:, 3] - X[:, 0] - X[:, 1]) / 2
    e3 = np.cross(g1, g2)
    n3 = np.linalg.norm(e3, axis=1)
    bad = n3 <= 1e-14 * np.linalg.norm(g1, axis=1) * np.linalg.norm(g2, axis=1) + 1e-300
    if bad.any():
        raise ValueError(f"degenerate quad {int(np.flatnonzero(bad)[0])}: its mid-side vectors are parallel")
    e3 = e3 / n3[:, None]
    e1 = g1 / np.linalg.norm(g1, axis=1)[:, None]
    e2 = np.cross(e3, e1)
    T = np.stack([e1, e2, e3], axis=1)
    return T, np.einsum("eij,ekj->eik", X - c[:, None], T[:, :2])


def _inv2(J):
    det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
    inv = np.stack([np.stack([J[:, 1, 1], -J[:, 0, 1]], -1), np.stack([-J[:, 1, 0], J[:, 0, 0]], -1)], 1)
    return inv / det[:, None, None], det


@dataclass(frozen=True)
class SectionBlock:
    """Per-element section matrices in the element frames (shell_section.PlateSection's, stacked):
    A, B, D (e, 3, 3), H (e, 2, 2) and the inertia per area (m0, m1, m2) (e, 3)."""

    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    H: np.ndarray
    inertia: np.ndarray


def local_matrices(xy: np.ndarray, t: np.ndarray, mat: Material, first: int = 0, sections: SectionBlock | None = None):
    """(K, M) (e, 24, 24) in the element frames, as shell.element_matrices for each element; `first`
    numbers the elements in messages; `sections` (a laminate's, turned to each element's frame) in
    place of the isotropic plate of t and mat."""
    E, nu, rho = mat.E, mat.nu, mat.rho
    ne = len(xy)
    C0 = E / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    kG = SHEAR_FACTOR * E / (2 * (1 + nu))
    iu, iv, iw, irx, iry, irz = (np.arange(4) * 6 + k for k in range(6))
    K = np.zeros((ne, 24, 24))
    M = np.zeros((ne, 24, 24))

    def covariant_shear(xi, eta):  # (e, 2, 24): rows gamma_xi, gamma_eta
        N, dN = _shape(xi, eta)
        J = np.einsum("rk,ekj->erj", dN, xy)
        B = np.zeros((ne, 2, 24))
        B[:, :, iw] = dN
        B[:, :, iry] += N[None, None, :] * J[:, :, 0:1]
        B[:, :, irx] -= N[None, None, :] * J[:, :, 1:2]
        return B

    gA, gC = covariant_shear(0, 1)[:, 0], covariant_shear(0, -1)[:, 0]
    gB, gD = covariant_shear(-1, 0)[:, 1], covariant_shear(1, 0)[:, 1]
    for xi, eta in _GAUSS:
        N, dN = _shape(xi, eta)
        J = np.einsum("rk,ekj->erj", dN, xy)
        Jinv, detJ = _inv2(J)
        if np.any(detJ <= 0):
            e = int(np.flatnonzero(detJ <= 0)[0])
            raise ValueError(f"quad {first + e} with corners {xy[e].tolist()} is inverted or not convex "
                             f"(det J = {detJ[e]:.3g})")
        dNx = np.einsum("eij,jk->eik", Jinv, dN)  # (e, 2, 4)
        Bm = np.zeros((ne, 3, 24))
        Bm[:, 0, iu], Bm[:, 1, iv], Bm[:, 2, iu], Bm[:, 2, iv] = dNx[:, 0], dNx[:, 1], dNx[:, 1], dNx[:, 0]
        Bb = np.zeros((ne, 3, 24))
        Bb[:, 0, iry], Bb[:, 1, irx], Bb[:, 2, iry], Bb[:, 2, irx] = dNx[:, 0], -dNx[:, 1], dNx[:, 1], -dNx[:, 0]
        g_nat = np.stack([0.5 * (1 + eta) * gA + 0.5 * (1 - eta) * gC, 0.5 * (1 + xi) * gD + 0.5 * (1 - xi) * gB], 1)
        Bs = np.einsum("eij,ejk->eik", Jinv, g_nat)
        w = detJ[:, None, None]
        BmT, BbT = Bm.transpose(0, 2, 1), Bb.transpose(0, 2, 1)
        NN = np.outer(N, N)[None] * w
        if sections is None:
            K += (t[:, None, None] * (BmT @ (C0 @ Bm)) + (t**3 / 12)[:, None, None] * (BbT @ (C0 @ Bb))
                  + (kG * t)[:, None, None] * (Bs.transpose(0, 2, 1) @ Bs)) * w
            inertia = ((iu, rho * t), (iv, rho * t), (iw, rho * t), (irx, rho * t**3 / 12), (iry, rho * t**3 / 12))
        else:
            S = sections
            K += (BmT @ (S.A @ Bm) + BbT @ (S.D @ Bb) + BmT @ (S.B @ Bb) + BbT @ (S.B @ Bm)
                  + Bs.transpose(0, 2, 1) @ (S.H @ Bs)) * w
            m0, m1, m2 = S.inertia.T
            inertia = ((iu, m0), (iv, m0), (iw, m0), (irx, m2), (iry, m2))
            for a, b, sign in ((iu, iry, 1.0), (iv, irx, -1.0)):  # shell_section.add_section_mass
                M[:, a[:, None], b[None, :]] += sign * m1[:, None, None] * NN
                M[:, b[:, None], a[None, :]] += sign * m1[:, None, None] * NN
        for idx, m in inertia:
            M[:, idx[:, None], idx[None, :]] += m[:, None, None] * NN
    diag = np.einsum("eii->ei", K)
    kd = DRILL * np.min(diag[:, np.concatenate([iu, iv])], axis=1)
    _, dN0 = _shape(0, 0)
    Jinv0, _ = _inv2(np.einsum("rk,ekj->erj", dN0, xy))
    dNx0 = np.einsum("eij,jk->eik", Jinv0, dN0)
    omega = np.zeros((ne, 24))
    omega[:, iv] = 0.5 * dNx0[:, 0]
    omega[:, iu] = -0.5 * dNx0[:, 1]
    for i in range(4):
        b = -omega.copy()
        b[:, irz[i]] += 1.0
        K += kd[:, None, None] * (b[:, :, None] * b[:, None, :])
    return K, M


def to_global(A: np.ndarray, T: np.ndarray) -> np.ndarray:
    """R^T A R for R = I_8 (x) T, (e, 24, 24): translations and rotations of the 4 nodes."""
    A = A.reshape(-1, 8, 3, 8, 3).transpose(0, 1, 3, 2, 4)  # (e, 8, 8, 3, 3) node blocks
    T5 = T[:, None, None]
    return (T5.transpose(0, 1, 2, 4, 3) @ A @ T5).transpose(0, 1, 3, 2, 4).reshape(-1, 24, 24)


def assemble_mitc4(nodes, quads, thickness, material: Material) -> ShellFE:
    """The ShellFE of shell.assemble_shells (same K and M), assembled block by block (module doc)."""
    X = np.asarray(nodes, dtype=float)
    Q = np.asarray(quads, dtype=int)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"nodes: shape {X.shape}, expected (n, 3)")
    if Q.ndim != 2 or Q.shape[1] != 4:
        raise ValueError(f"quads: shape {Q.shape}, expected (e, 4)")
    if Q.size and (Q.min() < 0 or Q.max() >= len(X)):
        raise ValueError(f"quads: node index out of range 0..{len(X) - 1}")
    t = np.broadcast_to(np.asarray(thickness, dtype=float), (len(Q),)).copy()
    if np.any(t <= 0):
        raise ValueError(f"thickness: element {int(np.argmin(t))} has t = {t.min():g} <= 0")
    n = 6 * len(X)
    K = sp.csr_matrix((n, n))
    M = sp.csr_matrix((n, n))
    for s in range(0, len(Q), BLOCK):
        q = Q[s : s + BLOCK]
        T, xy = element_frames(X[q])
        Kl, Ml = local_matrices(xy, t[s : s + BLOCK], material, first=s)
        d = (6 * q[:, :, None] + np.arange(6)).reshape(len(q), 24)
        r, c = np.repeat(d, 24, axis=1).ravel(), np.tile(d, (1, 24)).ravel()
        K = K + sp.csr_matrix((to_global(Kl, T).ravel(), (r, c)), shape=(n, n))
        M = M + sp.csr_matrix((to_global(Ml, T).ravel(), (r, c)), shape=(n, n))
    return ShellFE(X, Q, t, material, K, M)


def _fibre_points(conn, t, normals, N, w, rho, n):
    """(M_s, N (3p, 6n), w (p,)) of one element type (shell_body.py's module doc): conn (e, k) nodes,
    t (e,), normals (e, 3), N (g, k) the shape functions at the mass rule's points, w (e, g) their
    weights det J w_g (areas)."""
    ne, k = conn.shape
    g = N.shape[0]
    nx = np.zeros((ne, 3, 3))  # n~
    nx[:, 0, 1], nx[:, 0, 2], nx[:, 1, 0] = -normals[:, 2], normals[:, 1], normals[:, 2]
    nx[:, 1, 2], nx[:, 2, 0], nx[:, 2, 1] = -normals[:, 0], -normals[:, 1], normals[:, 0]
    NN = np.einsum("gi,gj->gij", N, N).reshape(g, k * k)
    ms = rho * np.einsum("e,eg,gq->eq", t, w, NN)
    Ms = sp.csr_matrix((ms.ravel(), (np.repeat(conn, k, axis=1).ravel(), np.tile(conn, (1, k)).ravel())), shape=(n, n))
    z = t / np.sqrt(12.0)
    P = -z[:, None, None, None, None] * N[None, :, None, :, None] * nx[:, None, :, None, :]  # (e, g, a, node, c)
    p = g * ne
    rows = np.broadcast_to(3 * np.arange(p).reshape(ne, g)[:, :, None, None, None]
                           + np.arange(3)[None, None, :, None, None], P.shape)
    cols = np.broadcast_to(6 * conn[:, None, None, :, None] + 3 + np.arange(3), P.shape)
    Np = sp.csr_matrix((P.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * p, 6 * n))
    Np.eliminate_zeros()
    return Ms, Np, (rho * t[:, None] * w).ravel()


def fibre_mass(shell: ShellFE):
    """(M_s (n, n), N (3p, 6n), w (p,)): the mid-surface's node-block mass and the fibres' mass points of
    shell_body.py's module doc, for all MITC4 quads and DKT triangles at once, each on its element's
    mass rule (2 x 2 Gauss; shell_tri.MASS_RULE)."""
    from .shell_tri import MASS_RULE

    X, rho, n = shell.coords, shell.material.rho, len(shell.coords)
    Q, T3 = np.asarray(shell.quads, dtype=int), np.asarray(getattr(shell, "trias", np.zeros((0, 3))), dtype=int)
    t = np.asarray(shell.thickness, dtype=float)
    parts = []
    if len(Q):
        T, xy = element_frames(X[Q])
        shapes = [_shape(xi, eta) for xi, eta in _GAUSS]
        N = np.array([Nq for Nq, _ in shapes])
        w = np.stack([np.linalg.det(np.einsum("rk,ekj->erj", dN, xy)) for _, dN in shapes], axis=1)
        parts.append(_fibre_points(Q, t[: len(Q)], T[:, 2], N, w, rho, n))
    if len(T3):
        c = np.cross(X[T3[:, 1]] - X[T3[:, 0]], X[T3[:, 2]] - X[T3[:, 0]])
        area2 = np.linalg.norm(c, axis=1)
        w = 0.5 * area2[:, None] * MASS_RULE.weights[None, :]
        parts.append(_fibre_points(T3, t[len(Q) : len(Q) + len(T3)], c / area2[:, None], MASS_RULE.shape(), w, rho, n))
    if not parts:
        return sp.csr_matrix((n, n)), sp.csr_matrix((0, 6 * n)), np.zeros(0)
    return (sum(m for m, _, _ in parts), sp.vstack([q for _, q, _ in parts], format="csr"),
            np.concatenate([w for _, _, w in parts]))
