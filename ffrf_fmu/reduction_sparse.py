"""Sparse superelement reduction of a solid (geradin section 7, eq. 76) on interface frames.

The basis is the one of reduction.py, generalized from boundary nodes to interface frames: the
boundary coordinates are q_B = L z, L (6 n_f, n_z) the frames' operator (rigid frames: their own
6 dofs after the RBE2 elimination u = T z; averaging frames: the least-squares rigid fit W of their
node sets, solid/frames.py). With P = I - M U (U^T M U)^-1 U^T (inertia relief about the CM, U the
rigid modes, eq. 11) and G_e the free flexibility (K x = P b with U^T M x = 0):

    free attachment modes  F = G_e L^T,  F_BB = L F,  Y_B = F F_BB^-1          (L Y_B = I)
    free-free modes        K Xi = M Xi diag(w^2), U^T M Xi = 0, Xi^T M Xi = I
    eq. (76)               Y = [Y_B, Xi - Y_B (L Xi)]                           (L Y = [I, 0])

Every column is mass-orthogonal to the rigid modes (eq. 74). Nothing dense of size n_dof x n_dof is
formed: K and M stay scipy.sparse, and ONE sparse LU (scipy's SuperLU, nested-dissection order,
solid/ordering.py) of K - sigma M, sigma < 0 (positive definite while K is singular), serves both the
modes (ARPACK in shift-invert mode about sigma) and the static solves of G_e (exact on the computed
modes, conjugate gradients preconditioned by the LU on the rest: free_static). Only tall
n_dof x (6 n_f + modes) arrays are dense.

Invariants from the tensor kernels T_ab of the sparse mass (solid/__init__.py: the node-block mass
M_s (x) I_3 of the translations plus the mass points of shell fibres and offset masses), Q_ab = Y^T T_ab Y,
    G_k = Y^T M_k Y = sum_ab e_k~[a, b] Q_ab            (geradin 53)
    W1_j = C_j + C_j^T,  C_j[:, k] = U_r^T M_k Y_j       (Witteveen; invariants.py)
    W2_jl = tr(P_jl) I - P_jl^T,  P_jl[a, b] = Q_ab[j, l]
    J0 = U_r^T M U_r (eq. 13), mass and x_cm from M and the rigid fields (mass_properties).
The result is a runtime SuperelementData of the same form as a beam superelement's: one superelement
whose boundary nodes are the frames.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .runtime.data import SuperelementData
from .runtime.rotation import skew
from .solid import SolidFE, tensor_products
from .solid.constraints import Constraints, constraints, mass_properties
from .solid.ordering import factor

MECHANISM = 1e-12  # an elastic eigenvalue below this x the element scale (median K_ii / M_ii) is a mechanism


def element_scale(K: sp.spmatrix, M: sp.spmatrix) -> float:
    """The median of K_ii / M_ii over the dofs with mass [rad^2/s^2]: the square of a frequency of one
    element's dof. A mode of zero strain energy (a mechanism, a part not connected) has an eigenvalue at
    the round-off of K, about 1e-16 of it; the softest true mode of a structure is many orders above
    (the roof sway of a body on slender pillars, where the Ritz estimate of w_1^2 is 1e4 times too high)."""
    k, m = K.diagonal(), M.diagonal()
    has = m > 0
    return float(np.median(k[has] / m[has]))
SHIFT_FRACTION = 0.1  # sigma = -SHIFT_FRACTION x (estimate of w_1^2): rigid and elastic eigenvalues well apart
DEFLATE = 6  # at least this many modes are computed: the static solves converge on the rest
MAX_MODES = 200  # a frequency cutoff keeps at most this many modes


@dataclass(frozen=True, eq=False)
class SolidReduction:
    """A reduced solid: the runtime data and what reports and result recovery need."""

    data: SuperelementData
    Y: np.ndarray  # (n_dof, n) basis of eq. (76) on the solid's FE dofs
    U: np.ndarray  # (n_dof, 6) rigid modes about the CM
    orthogonality_error: float  # max|U^T M Y| / max|M|
    block_diagonality_error: float  # max|K_bar boundary-modal block| / max|K_bar|
    n_fe_dofs: int
    fe: SolidFE
    frames: tuple
    timings: dict = field(default_factory=dict)  # CPU seconds per stage
    shift: float = 0.0  # sigma of the shift-invert eigensolution [rad^2/s^2]
    lu_fill: int = 0  # entries stored in the LU's factors (its memory: about 12 bytes each)


def shifted_lu(K: sp.spmatrix, M: sp.spmatrix, sigma: float, c: Constraints, coords: np.ndarray):
    """The one sparse LU of K - sigma M (sigma < 0: positive definite) in z, ordered by nested
    dissection of the mesh (solid/ordering.py)."""
    return factor(K - sigma * M, c.dof_node, coords)


def ritz_estimate(fe: SolidFE) -> float:
    """An upper bound of w_1^2 of the free solid that needs no factorization: Rayleigh-Ritz on the
    polynomial displacement fields of degree <= 3 (60 fields, the constant ones included: the 6 rigid
    modes are in the space, give 0 and are passed over, so the 7th Ritz value bounds the first elastic
    eigenvalue; without the constants only the 3 rotations were, and the 7th bounded the 4th elastic one:
    281 Hz against 77.2 Hz on the benchmark bar of docs/solids.md, now 92.3 Hz). Within a few 10 % on a
    bar (a factor on a complex part, which only moves the shift). On 6-dof nodes the rotations get the
    fields of degree <= 2 besides (30 more: the rotations of a bending field of degree <= 3, so a
    shear-deformable plate bends without shear in the space), and the directions the mass does not see
    (a drilling rotation) are left out of the Ritz space."""
    X = fe.coords - fe.coords.mean(0)
    X = X / np.abs(X).max(0).clip(min=1e-300)

    def monomials(degree):
        powers = [(a, b, c) for a in range(4) for b in range(4) for c in range(4) if a + b + c <= degree]
        return np.stack([X[:, 0] ** a * X[:, 1] ** b * X[:, 2] ** c for a, b, c in powers], axis=1)

    parts = [(range(3), monomials(3))] + ([(range(3, 6), monomials(2))] if fe.dofs_per_node == 6 else [])
    V = np.zeros((fe.n_nodes, fe.dofs_per_node, sum(3 * m.shape[1] for _, m in parts)))
    col = 0
    for comps, mono in parts:
        for comp in comps:
            V[:, comp, col : col + mono.shape[1]] = mono
            col += mono.shape[1]
    V, _ = np.linalg.qr(V.reshape(fe.n_dof, -1))
    Mr = V.T @ (fe.M @ V)
    m, E = np.linalg.eigh(0.5 * (Mr + Mr.T))
    E = E[:, m > 1e-10 * m.max()] / np.sqrt(m[m > 1e-10 * m.max()])  # M-orthonormal on what M sees
    Kr = E.T @ (V.T @ (fe.K @ (V @ E)))
    return float(np.linalg.eigvalsh(0.5 * (Kr + Kr.T))[6])


def free_free_modes(K, M, U, A, lu, n_modes: int | None, cutoff_hz: float | None, sigma: float, w2_scale: float):
    """Elastic modes of K x = w^2 M x by ARPACK in shift-invert mode about sigma < 0 with the LU `lu`
    of K - sigma M followed by the projection that removes the rigid modes (M-orthogonal to U): the
    rigid modes map to 0 in the shifted spectrum, so ARPACK never has to resolve their six-fold
    eigenvalue (with a plain shift it missed one of the six on a box). Mass-normalized, U^T M Xi = 0.
    n_modes: this many; cutoff_hz: every mode up to it (at most MAX_MODES). A mode below MECHANISM x
    w2_scale (element_scale) is a mechanism: an error. Returns (Xi (n_z, k), w^2 (k,))."""
    n = K.shape[0]
    MU = np.asarray(M @ U)

    def solve(x):
        y = lu.solve(np.asarray(x, dtype=float))
        return y - U @ np.linalg.solve(A, MU.T @ y)

    op = spla.LinearOperator((n, n), matvec=solve, dtype=float)
    v0 = solve(np.asarray(M @ np.linspace(1.0, 2.0, n)).ravel())  # deterministic start, free of rigid parts
    want = n_modes if n_modes is not None else 8
    while True:
        k = min(want, n - 7)
        w2, X = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, v0=v0, tol=1e-10)
        order = np.argsort(w2)
        w2, X = w2[order], X[:, order]
        if n_modes is not None or w2[-1] > (2 * math.pi * cutoff_hz) ** 2 or k >= min(n - 7, MAX_MODES):
            break
        want *= 2
    if w2[0] < MECHANISM * w2_scale:
        raise ValueError(f"the body has more than 6 rigid modes: free-free eigenvalue {w2[0]:.3g} rad^2/s^2, "
                         f"{w2[0] / w2_scale:.1e} of its elements' K_ii / M_ii (a mechanism, or a part not connected)")
    if cutoff_hz is not None and n_modes is None:
        keep = w2 <= (2 * math.pi * cutoff_hz) ** 2
        w2, X = w2[keep], X[:, keep]
    X = X - U @ np.linalg.solve(A, MU.T @ X)
    X = X / np.sqrt(np.einsum("ij,ij->j", X, M @ X))
    return X, w2


STATIC_TOL = 1e-10  # relative residual of the static solves (round-off stalls them near 1e-12)
ROUND_OFF = 1e3 * np.finfo(float).eps  # |K y - b| below this x | |K| |y| |: as exact as K y can be computed
STATIC_MAXITER = 300


def free_static(K, M, U, lu, Xi, w2, b) -> np.ndarray:
    """x = G_e b: the free (inertia-relief) static response to loads b (n_z, k), U^T M x = 0, from the
    LU of K - sigma M that the modes used (one factorization for the whole reduction). With P the
    inertia-relief projector, K x = P b is solved in the M-orthogonal complement of the rigid modes:
    exactly on the computed modes Xi (x = Xi w^-2 Xi^T P b), and by conjugate gradients on the rest,
    column by column, preconditioned by C = Q (K - sigma M)^-1 Q^T (Q removes the rigid and computed modes;
    C is symmetric and the residuals stay in the range of Q^T). The preconditioned operator's eigenvalues
    are w^2 / (w^2 - sigma) in [w_(m+1)^2 / (w_(m+1)^2 - sigma), 1): its condition number is close to 1,
    and CG's error falls per pass by (sqrt(kappa) - 1) / (sqrt(kappa) + 1), half of the preconditioned
    Richardson iteration's (1 - kappa^-1) that this replaced (measured on the benchmark bar at 8k dofs: 8
    block solves with Richardson, 6 with CG at the same shift)."""
    MU = np.asarray(M @ U)
    AU = U.T @ MU
    b = np.asarray(b, dtype=float).reshape(K.shape[0], -1)
    b = b - MU @ np.linalg.solve(AU, U.T @ b)  # P b: self-equilibrated
    MX = np.asarray(M @ Xi)

    def q(y):  # remove the rigid and the computed modes (M-orthogonal projection)
        y = y - U @ np.linalg.solve(AU, MU.T @ y)
        return y - Xi @ (MX.T @ y)

    def precondition(r):
        return q(lu.solve(np.asfortranarray(r)))

    x = Xi @ ((Xi.T @ b) / w2[:, None]) if Xi.shape[1] else np.zeros_like(b)
    r0 = b - MX @ (Xi.T @ b)  # the load on the remaining modes
    y = np.zeros_like(b)
    r = r0.copy()
    scale = np.linalg.norm(r0, axis=0).max()
    absK = abs(K)

    def converged(r):  # to STATIC_TOL, or to the round-off of K y (dofs of mixed units: mm and rad)
        floor = ROUND_OFF * np.linalg.norm(absK @ np.abs(y), axis=0)
        return bool(np.all(np.linalg.norm(r, axis=0) <= np.maximum(STATIC_TOL * scale, floor)))

    z = precondition(r)
    p = z
    rz = np.einsum("ij,ij->j", r, z)
    for it in range(STATIC_MAXITER):
        if converged(r):
            r = r0 - K @ y  # the recursive residual drifts: confirm with the true one
            if converged(r):
                break
            z = precondition(r)
            p, rz = z, np.einsum("ij,ij->j", r, z)
        Kp = K @ p
        pKp = np.einsum("ij,ij->j", p, Kp)
        alpha = np.divide(rz, pKp, out=np.zeros_like(rz), where=pKp > 0)
        y += alpha * p
        r -= alpha * Kp
        z = precondition(r)
        rz_new = np.einsum("ij,ij->j", r, z)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
        p = z + beta * p
        rz = rz_new
    else:
        raise RuntimeError(f"static solve did not converge in {STATIC_MAXITER} passes (residual "
                           f"{np.linalg.norm(r, axis=0).max() / scale:.1e})")
    x = x + y
    x = x - U @ np.linalg.solve(AU, MU.T @ x)
    return x - U @ np.linalg.solve(AU, MU.T @ x)


def node_kernels(fe: SolidFE, Yf: np.ndarray, Ur: np.ndarray):
    """Q (3, 3, n, n) with Q_ab = Y^T T_ab Y, R (3, 3, 3, n) with R_ab = U_r^T T_ab Y (solid/__init__.py:
    the node-block mass and the mass points)."""
    return tensor_products(fe, Yf, Yf), tensor_products(fe, Ur, Yf)


def inertia_terms(Q, R):
    """G_k (3, n, n), W1 (n, 3, 3), W2 (n, n, 3, 3) from the node kernels (module doc)."""
    E = skew(np.eye(3))  # E[k] = e_k~
    G = np.einsum("kab,abjl->kjl", E, Q)
    C = np.einsum("kab,abrj->jrk", E, R)  # C_j[r, k] = U_r^T M_k Y_j
    P = Q.transpose(2, 3, 0, 1)  # P[j, l, a, b]
    W2 = np.einsum("jlaa->jl", P)[:, :, None, None] * np.eye(3) - P.transpose(0, 1, 3, 2)
    return G, C + C.transpose(0, 2, 1), 0.5 * (W2 + W2.transpose(1, 0, 3, 2))


def reduce_solid(fe: SolidFE, frames, n_modes: int | None = None, cutoff_hz: float | None = None,
                 inertia: bool = False, stiffening: bool = False) -> SolidReduction:
    """One superelement of eq. (76) on the interface frames (module doc). n_modes or cutoff_hz choose
    the free-free modes (every one up to the cutoff); inertia: add W1, W2 (the term set `full`);
    stiffening: geometric stiffening from the mesh (centrifugal correction modes appended to eta, W1,
    the membrane tensors of solid/stiffening.py; needs fe.strain, a mesh assembled here).
    Frames become the boundary nodes 0..n_f-1 in the given order."""
    if stiffening and fe.strain is None:
        raise ValueError("geometric stiffening needs the element stresses of a solid mesh and its material; "
                         f"{fe.source or 'this body'} has none (an export, shells or beams): set stiffening = false")
    if len(frames) < 2:
        raise ValueError(f"a solid needs at least 2 ports (interface frames), got {len(frames)}: with one, its "
                         "attachment modes vanish (the body moves rigidly with that frame)")
    if n_modes is None and cutoff_hz is None:
        raise ValueError("give the number of modes or a frequency cutoff")
    t = {"start": time.process_time()}  # CPU seconds per stage: on a shared machine wall time measures the load
    mass, x_cm = mass_properties(fe)
    c = constraints(fe, frames, x_cm)
    K = (c.T.T @ fe.K @ c.T).tocsr()
    M = (c.T.T @ fe.M @ c.T).tocsr()
    t["constraints"] = time.process_time()
    w2_est = ritz_estimate(fe)
    sigma = -SHIFT_FRACTION * w2_est
    t["shift"] = time.process_time()
    lu = shifted_lu(K, M, sigma, c, fe.coords)
    t["factor"] = time.process_time()
    AU = c.U.T @ (M @ c.U)
    n_keep = n_modes
    Xi_all, w2_all = free_free_modes(K, M, c.U, AU, lu, None if n_modes is None else max(n_modes, DEFLATE),
                                     cutoff_hz, sigma, element_scale(K, M))
    Xi, w2 = (Xi_all[:, :n_keep], w2_all[:n_keep]) if n_keep is not None else (Xi_all, w2_all)
    t["modes"] = time.process_time()
    F = free_static(K, M, c.U, lu, Xi_all, w2_all, c.L.T.toarray())  # free attachment modes F = G_e L^T
    F_BB = c.L @ F
    F_BB = 0.5 * (F_BB + F_BB.T)
    d = 1.0 / np.sqrt(np.abs(np.diag(F_BB)))
    if np.linalg.cond(F_BB * np.outer(d, d)) > 1e10:
        raise ValueError("the frames' flexibility F_BB is singular: two ports on the same nodes, or a port whose "
                         "set moves rigidly with another's")
    YB = np.linalg.solve(F_BB, F.T).T
    t["attachment"] = time.process_time()
    Y = np.concatenate([YB, Xi - YB @ (c.L @ Xi)], axis=1)
    if stiffening:
        from .solid.stiffening import correction_modes

        Uf0 = np.asarray(c.T @ c.U)
        static = lambda b: free_static(K, M, c.U, lu, Xi_all, w2_all, b)  # noqa: E731  G_e b, the same LU
        Y = np.concatenate([Y, correction_modes(fe, M, c, static, YB, Xi, Uf0[:, 3:])], axis=1)
        t["correction"] = time.process_time()
    lu_fill = lu.fill
    del lu
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
    t["invariants"] = time.process_time()
    extra = {"W1": W1, "W2": W2} if inertia else {}
    if stiffening:
        from .solid.stiffening import membrane_tensors

        vk = membrane_tensors(fe.strain, Yf)
        extra.update(W1=W1, vk_a=vk["vk_a"], vk_B=vk["vk_B"])
        t["membrane"] = time.process_time()
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
        **extra,
    )
    names = list(t)
    timings = {b: t[b] - t[a] for a, b in zip(names, names[1:])}
    return SolidReduction(
        data=data, Y=Yf, U=Uf,
        orthogonality_error=float(np.abs(Uf.T @ (fe.M @ Yf)).max() / abs(fe.M).max()),
        block_diagonality_error=float(np.abs(Kb[:nb, nb:]).max(initial=0.0) / np.abs(Kb).max()),
        n_fe_dofs=fe.n_dof, fe=fe, frames=tuple(frames), timings=timings, shift=sigma,
        lu_fill=lu_fill,
    )
