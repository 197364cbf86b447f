"""Sparse superelement reduction of a solid (geradin section 7, eq. 76) on interface frames.

The basis is the one of reduction.py, generalized from boundary nodes to interface frames: the
boundary coordinates are q_B = L z, L (6 n_f, n_z) the frames' operator (rigid frames: their own
6 dofs after the RBE2 elimination u = T z; averaging frames: the least-squares rigid fit W of their
node sets, solid/frames.py). With P = I - M U (U^T M U)^-1 U^T (inertia relief about the CM, U the
rigid modes, eq. 11) and G_e = P^T G_c P the free flexibility (G_c: any isostatic support):

    free attachment modes  F = G_e L^T,  F_BB = L F,  Y_B = F F_BB^-1          (L Y_B = I)
    free-free modes        K Xi = M Xi diag(w^2), U^T M Xi = 0, Xi^T M Xi = I
    eq. (76)               Y = [Y_B, Xi - Y_B (L Xi)]                           (L Y = [I, 0])

Every column is mass-orthogonal to the rigid modes (eq. 74). Nothing dense of size n_dof x n_dof is
formed: K and M stay scipy.sparse, G_c is one sparse LU (scipy's SuperLU) of K with 6 isostatic dofs
held, the modes come from ARPACK in shift-invert mode about a negative shift sigma (K - sigma M is
positive definite while K is singular), a second sparse LU. Only tall n_dof x (6 n_f + modes)
arrays are dense.

Invariants from the sparse node-block mass M = M_s (x) I_3 (solid/__init__.py): with Y_n the basis as
(n_nodes, 3, n), Q_ab = Y_n[:, a]^T M_s Y_n[:, b] (= Y^T T_ab Y),
    G_k = Y^T M_k Y = sum_ab e_k~[a, b] Q_ab            (geradin 53)
    W1_j = C_j + C_j^T,  C_j[:, k] = U_r^T M_k Y_j       (Witteveen; invariants.py)
    W2_jl = tr(P_jl) I - P_jl^T,  P_jl[a, b] = Q_ab[j, l]
    J0 = U_r^T M U_r (eq. 13), mass = 1^T M_s 1, x_cm = M_s-weighted mean of the nodes.
The result is a runtime SuperelementData of the same form as a beam superelement's: one superelement
whose boundary nodes are the frames.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .runtime.data import SuperelementData
from .runtime.rotation import skew
from .solid import SolidFE
from .solid.frames import Frame, averaging_weights, check_set

RIGID_GAP = 1e-4  # the 6 lowest eigenvalues must lie below this x the 7th: else not a free body with 6 rigid modes
SHIFT_FRACTION = 0.1  # sigma = -SHIFT_FRACTION x (estimate of w_1^2): rigid and elastic eigenvalues well apart
MAX_MODES = 200  # a frequency cutoff keeps at most this many modes


@dataclass(frozen=True, eq=False)
class Constraints:
    """u = T z (RBE2 frames eliminated), q_B = L z, rigid modes U_z about the CM in z."""

    T: sp.csr_matrix  # (3n, n_z)
    L: sp.csr_matrix  # (6 n_f, n_z)
    U: np.ndarray  # (n_z, 6)


@dataclass(frozen=True, eq=False)
class SolidReduction:
    """A reduced solid: the runtime data and what reports and result recovery need."""

    data: SuperelementData
    Y: np.ndarray  # (3 n_nodes, n) basis of eq. (76) on the solid's FE dofs
    U: np.ndarray  # (3 n_nodes, 6) rigid modes about the CM
    orthogonality_error: float  # max|U^T M Y| / max|M|
    block_diagonality_error: float  # max|K_bar boundary-modal block| / max|K_bar|
    n_fe_dofs: int
    fe: SolidFE
    frames: tuple
    timings: dict = field(default_factory=dict)  # seconds per stage
    shift: float = 0.0  # sigma of the shift-invert eigensolution [rad^2/s^2]


def mass_properties(fe: SolidFE) -> tuple[float, np.ndarray]:
    """Mass and CM from the node mass: m = 1^T M_s 1, m x_cm = 1^T M_s X."""
    w = np.asarray(fe.M_scalar.sum(axis=0)).ravel()
    mass = float(w.sum())
    return mass, (w @ fe.coords) / mass


def rigid_rows(X: np.ndarray) -> np.ndarray:
    """(k, 3, 6): the displacement of nodes at X (from the origin of the rotations) in the 6 rigid modes."""
    out = np.zeros((len(X), 3, 6))
    out[:, :, :3] = np.eye(3)
    out[:, :, 3:] = -skew(X)
    return out


def constraints(fe: SolidFE, frames, x_cm) -> Constraints:
    """T, L and U_z (module doc). Rigid sets are eliminated; averaging sets act on the remaining dofs.
    A node in two rigid sets, or in a rigid and an averaging set, is an error naming both ports."""
    n = fe.n_nodes
    owner = -np.ones(n, dtype=int)
    for f, fr in enumerate(frames):
        check_set(fr, fe.coords)
        if fr.coupling == "rigid":
            clash = fr.nodes[owner[fr.nodes] >= 0]
            if clash.size:
                raise ValueError(f"ports {frames[owner[clash[0]]].name!r} and {fr.name!r}: node {clash[0]} is in two "
                                 "rigid sets")
            owner[fr.nodes] = f
    free = np.flatnonzero(owner < 0)
    zfree = -np.ones(n, dtype=int)
    zfree[free] = 3 * np.arange(free.size)
    rigid = [f for f, fr in enumerate(frames) if fr.coupling == "rigid"]
    zframe = {f: 3 * free.size + 6 * i for i, f in enumerate(rigid)}
    n_z = 3 * free.size + 6 * len(rigid)
    rows, cols, vals = [np.repeat(3 * free, 3) + np.tile(np.arange(3), free.size)], \
        [np.repeat(zfree[free], 3) + np.tile(np.arange(3), free.size)], [np.ones(3 * free.size)]
    for f in rigid:
        nodes = frames[f].nodes
        B = np.concatenate([np.broadcast_to(np.eye(3), (len(nodes), 3, 3)),
                            -skew(fe.coords[nodes] - frames[f].point)], axis=2)  # (k, 3, 6)
        rows.append(np.repeat(3 * nodes[:, None] + np.arange(3), 6).ravel())
        cols.append(np.tile(zframe[f] + np.arange(6), 3 * len(nodes)))
        vals.append(B.ravel())
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * n, n_z))
    Lr, Lc, Lv = [], [], []
    for f, fr in enumerate(frames):
        if fr.coupling == "rigid":
            Lr.append(6 * f + np.arange(6)), Lc.append(zframe[f] + np.arange(6)), Lv.append(np.ones(6))
        else:
            clash = fr.nodes[owner[fr.nodes] >= 0]
            if clash.size:
                raise ValueError(f"port {fr.name!r} (averaging) shares node {clash[0]} with the rigid set of port "
                                 f"{frames[owner[clash[0]]].name!r}")
            W = averaging_weights(fe.coords, fr)  # (6, 3k)
            zc = (zfree[fr.nodes][:, None] + np.arange(3)).ravel()
            Lr.append(np.repeat(6 * f + np.arange(6), zc.size)), Lc.append(np.tile(zc, 6)), Lv.append(W.ravel())
    L = sp.csr_matrix((np.concatenate(Lv), (np.concatenate(Lr), np.concatenate(Lc))), shape=(6 * len(frames), n_z))
    Uz = np.zeros((n_z, 6))
    Uz[: 3 * free.size] = rigid_rows(fe.coords[free] - x_cm).reshape(-1, 6)
    for f in rigid:
        Uz[zframe[f] : zframe[f] + 3] = rigid_rows((frames[f].point - x_cm)[None])[0]
        Uz[zframe[f] + 3 : zframe[f] + 6, 3:] = np.eye(3)
    return Constraints(T, L, Uz)


def _splu(A: sp.spmatrix):
    """Sparse LU of a symmetric matrix: symmetric ordering, diagonal pivots (SuperLU's symmetric mode)."""
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def isostatic_support(U: np.ndarray) -> np.ndarray:
    """6 dofs that hold the rigid modes exactly once (U[support] nonsingular, best conditioned by
    pivoted QR of U^T): holding them is an isostatic support."""
    _, _, piv = sla.qr(U.T, mode="economic", pivoting=True)
    return np.sort(piv[:6])


class FreeFlexibility:
    """x = G_e b = P^T G_c P b: the free (inertia-relief) static response to loads b (n_z, k), with
    G_c one sparse LU of K with an isostatic support; U^T M x = 0 (P^T applied twice, reduction.py)."""

    def __init__(self, K: sp.spmatrix, M: sp.spmatrix, U: np.ndarray):
        self.M, self.U = M, U
        self.MU = np.asarray(M @ U)
        self.A = U.T @ self.MU
        support = isostatic_support(U)
        self.free = np.setdiff1d(np.arange(K.shape[0]), support)
        self.lu = _splu(sp.csr_matrix(K)[self.free][:, self.free])

    def project_load(self, b):  # P b: the load minus its rigid (inertia-relief) resultant
        return b - self.MU @ np.linalg.solve(self.A, self.U.T @ b)

    def project_shape(self, x):  # P^T x: the shape made mass-orthogonal to the rigid modes
        return x - self.U @ np.linalg.solve(self.A, self.MU.T @ x)

    def __call__(self, b):
        b = self.project_load(np.asarray(b, dtype=float).reshape(self.M.shape[0], -1))
        x = np.zeros_like(b)
        x[self.free] = self.lu.solve(np.ascontiguousarray(b[self.free]))
        return self.project_shape(self.project_shape(x))


def lowest_eigenvalue_estimate(G: FreeFlexibility, K, M, start, iterations: int = 4) -> float:
    """Rayleigh quotient after a few inverse iterations x <- G_e M x: an upper bound of w_1^2 close to it."""
    x = G(start[:, None])[:, 0]
    for _ in range(iterations):
        x = G((M @ x)[:, None])[:, 0]
        x /= np.abs(x).max()
    return float(x @ (K @ x) / (x @ (M @ x)))


def free_free_modes(K, M, U, A, n_modes: int | None, cutoff_hz: float | None, sigma: float):
    """Elastic modes of K x = w^2 M x by shift-invert about sigma < 0 (one sparse LU of K - sigma M),
    the 6 rigid ones dropped (checked: below RIGID_GAP x the first elastic one), projected against U
    and mass-normalized. n_modes: this many; cutoff_hz: every mode up to it (at most MAX_MODES).
    Returns (Xi (n_z, k), w^2 (k,))."""
    n = K.shape[0]
    lu = _splu(K - sigma * M)
    op = spla.LinearOperator((n, n), matvec=lu.solve, dtype=float)
    v0 = np.asarray(M @ np.ones(n)).ravel() + np.linspace(0.0, 1.0, n)  # deterministic start
    want = 6 + (n_modes if n_modes is not None else 8)
    while True:
        k = min(want, n - 2)
        w2, X = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, v0=v0, tol=1e-10)
        order = np.argsort(w2)
        w2, X = w2[order], X[:, order]
        if n_modes is not None or w2[-1] > (2 * math.pi * cutoff_hz) ** 2 or k >= min(n - 2, MAX_MODES + 6):
            break
        want *= 2
    if w2.size > 6 and np.abs(w2[:6]).max() > RIGID_GAP * w2[6]:
        raise ValueError(f"the body does not have exactly 6 rigid modes: eigenvalues {w2[:7]} (a mechanism, or "
                         "constrained dofs in the export)")
    w2, X = w2[6:], X[:, 6:]
    if cutoff_hz is not None and n_modes is None:
        keep = w2 <= (2 * math.pi * cutoff_hz) ** 2
        w2, X = w2[keep], X[:, keep]
    X = X - U @ np.linalg.solve(A, (M @ U).T @ X)
    X = X / np.sqrt(np.einsum("ij,ij->j", X, M @ X))
    return X, w2


def node_kernels(fe: SolidFE, Yf: np.ndarray, Ur: np.ndarray):
    """Q (3, 3, n, n) with Q_ab = Y_n[:, a]^T M_s Y_n[:, b], R (3, 3, 3, n) with R_ab = U_r,n[:, a]^T M_s Y_n[:, b]."""
    n = Yf.shape[1]
    Yn = Yf.reshape(fe.n_nodes, 3, n)
    Un = Ur.reshape(fe.n_nodes, 3, 3)
    MsY = np.stack([fe.M_scalar @ Yn[:, b, :] for b in range(3)])  # (3, n_nodes, n)
    Q = np.einsum("iaj,bil->abjl", Yn, MsY, optimize=True)
    R = np.einsum("iar,bil->abrl", Un, MsY, optimize=True)
    return Q, R


def inertia_terms(Q, R):
    """G_k (3, n, n), W1 (n, 3, 3), W2 (n, n, 3, 3) from the node kernels (module doc)."""
    E = skew(np.eye(3))  # E[k] = e_k~
    G = np.einsum("kab,abjl->kjl", E, Q)
    C = np.einsum("kab,abrj->jrk", E, R)  # C_j[r, k] = U_r^T M_k Y_j
    P = Q.transpose(2, 3, 0, 1)  # P[j, l, a, b]
    W2 = np.einsum("jlaa->jl", P)[:, :, None, None] * np.eye(3) - P.transpose(0, 1, 3, 2)
    return G, C + C.transpose(0, 2, 1), 0.5 * (W2 + W2.transpose(1, 0, 3, 2))


def reduce_solid(fe: SolidFE, frames, n_modes: int | None = None, cutoff_hz: float | None = None,
                 inertia: bool = False) -> SolidReduction:
    """One superelement of eq. (76) on the interface frames (module doc). n_modes or cutoff_hz choose
    the free-free modes (every one up to the cutoff); inertia: add W1, W2 (the term set `full`).
    Frames become the boundary nodes 0..n_f-1 in the given order."""
    if len(frames) < 2:
        raise ValueError(f"a solid needs at least 2 ports (interface frames), got {len(frames)}: with one, its "
                         "attachment modes vanish (the body moves rigidly with that frame)")
    if n_modes is None and cutoff_hz is None:
        raise ValueError("give the number of modes or a frequency cutoff")
    t = {"start": time.perf_counter()}
    mass, x_cm = mass_properties(fe)
    c = constraints(fe, frames, x_cm)
    K = (c.T.T @ fe.K @ c.T).tocsr()
    M = (c.T.T @ fe.M @ c.T).tocsr()
    t["constraints"] = time.perf_counter()
    G = FreeFlexibility(K, M, c.U)
    t["factor_static"] = time.perf_counter()
    F = G(c.L.T.toarray())  # free attachment modes F = G_e L^T
    F_BB = c.L @ F
    F_BB = 0.5 * (F_BB + F_BB.T)
    d = 1.0 / np.sqrt(np.abs(np.diag(F_BB)))
    if np.linalg.cond(F_BB * np.outer(d, d)) > 1e10:
        raise ValueError("the frames' flexibility F_BB is singular: two ports on the same nodes, or a port whose "
                         "set moves rigidly with another's")
    YB = np.linalg.solve(F_BB, F.T).T
    t["attachment"] = time.perf_counter()
    lam = lowest_eigenvalue_estimate(G, K, M, np.asarray(M @ c.U[:, 3:].sum(axis=1)).ravel()
                                     + np.asarray(M @ np.linspace(-1.0, 1.0, K.shape[0])).ravel())
    del G
    sigma = -SHIFT_FRACTION * lam
    Xi, w2 = free_free_modes(K, M, c.U, c.U.T @ (M @ c.U), n_modes, cutoff_hz, sigma)
    t["modes"] = time.perf_counter()
    Y = np.concatenate([YB, Xi - YB @ (c.L @ Xi)], axis=1)
    Kb, Mb = Y.T @ (K @ Y), Y.T @ (M @ Y)
    dm = 1.0 / np.sqrt(np.diag(Mb))
    if np.linalg.cond(Mb * np.outer(dm, dm)) > 1e10:
        raise ValueError(f"the {Xi.shape[1]} kept modes are not independent of the frames' attachment modes on this "
                         "mesh: fewer modes or a finer mesh")
    Yf = np.asarray(c.T @ Y)
    Uf = np.asarray(c.T @ c.U)
    Ur = Uf[:, 3:]
    Q, R = node_kernels(fe, Yf, Ur)
    Gk, W1, W2 = inertia_terms(Q, R)
    J0 = Ur.T @ (fe.M @ Ur)
    t["invariants"] = time.perf_counter()
    nb = 6 * len(frames)
    data = SuperelementData(
        mass=mass,
        J0=0.5 * (J0 + J0.T),
        x_cm=x_cm,
        X_B=np.array([fr.point for fr in frames]) - x_cm,
        nodes=np.arange(len(frames)),
        K=0.5 * (Kb + Kb.T),
        M=0.5 * (Mb + Mb.T),
        G=0.5 * (Gk - Gk.transpose(0, 2, 1)),
        frequencies_hz=np.sqrt(np.maximum(w2, 0.0)) / (2.0 * math.pi),
        **({"W1": W1, "W2": W2} if inertia else {}),
    )
    names = list(t)
    timings = {b: t[b] - t[a] for a, b in zip(names, names[1:])}
    return SolidReduction(
        data=data, Y=Yf, U=Uf,
        orthogonality_error=float(np.abs(Uf.T @ (fe.M @ Yf)).max() / abs(fe.M).max()),
        block_diagonality_error=float(np.abs(Kb[:nb, nb:]).max(initial=0.0) / np.abs(Kb).max()),
        n_fe_dofs=fe.n_dof, fe=fe, frames=tuple(frames), timings=timings, shift=sigma,
    )


def solid_invariants(red: SolidReduction):
    """Witteveen's invariants (invariants.Invariants) of a reduced solid on its pseudo free-free modes
    Phi = Y V, K_bar V = M_bar V diag(w^2) (as invariants.superelement_invariants for a beam), from the
    sparse node mass. Its length is the diagonal of the nodes' bounding box (not the largest node
    distance: that is O(n^2) on a mesh)."""
    from .invariants import DEFLECTION, Invariants

    fe = red.fe
    w2, V = sla.eigh(red.data.K, red.data.M)
    Phi = red.Y @ V
    n = Phi.shape[1]
    Ur = red.U[:, 3:]
    Q, R = node_kernels(fe, Phi, Ur)
    G, W1, W2 = inertia_terms(Q, R)
    mass = float(red.data.mass)
    disp = np.maximum(np.linalg.norm(Phi.reshape(fe.n_nodes, 3, n), axis=1).max(0), 1.0 / math.sqrt(mass))
    length = float(np.linalg.norm(fe.coords.max(0) - fe.coords.min(0)))
    return Invariants(
        Phi=Phi, omega=np.sqrt(np.maximum(w2, 0.0)), n_vibration=len(red.data.frequencies_hz), mass=mass,
        length=length, I0=red.data.J0, W1=W1, W2=W2, W3=G.transpose(2, 0, 1), C0=Ur.T @ (fe.M @ Phi),
        G=0.5 * (G - G.transpose(0, 2, 1)), P=Q.transpose(2, 3, 0, 1), amplitude=DEFLECTION * length / disp,
        dofs_per_node=3,
    )
