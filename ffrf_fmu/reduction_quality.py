"""Reduction quality of a solid (docs/solids.md, "Quality report"): what an FE analyst checks beside a
reduced body.

- Frequencies: the free-free modes of the full FE model (rigid frames eliminated, as reduced) up to a
  cutoff against the reduced body's (the Ritz values of K_bar, M_bar), paired by the mass-weighted MAC
      MAC(a, b) = (a^T M b)^2 / ((a^T M a)(b^T M b)).
  The kept modes are exact (MAC 1, error at round-off); the attachment modes add approximations of
  the next ones. For a repeated frequency the MAC is taken with the reduced eigenspace (CLUSTER).
- Effective mass per port direction, of the full FE model and of the reduced body, each clamped at one
  port (its frame fixed: L_p z = 0, the Craig-Bampton fixed-interface modes about that port): with the
  clamped model's modes v_j (M-normalized) and the rigid motion z_d in which the frame moves by a unit
  translation or rotation d (L_p z_d = e_d), the participation Gamma_j = v_j^T M z_d and the effective
  mass Gamma_j^2. Its sum over the modes up to the cutoff is reported as a fraction of
  z_d^T M z_d (the mass for a translation, the inertia about the frame for a rotation). Over ALL modes
  (they span ker L_p, M-orthogonally) the sum is z_d^T M z_d minus what the clamped port carries itself,
      sum_j Gamma_j^2 = z_d^T M z_d - e_d^T (L_p M^-1 L_p^T)^-1 e_d,
  the mass of the port's own set in the M-metric (the rigid set of an RBE2 frame; the set of an
  averaging frame): it shrinks with the set's share of the mesh, so the sum tends to the rigid mass and
  inertia about the port. What the fraction up to the cutoff misses beyond that is the motion no mode
  below the cutoff carries under base excitation: the reduced body's fraction against the full
  model's shows what the reduction keeps of it.
  The full model's clamped modes come from the same LU as its free-free ones: on ker L_p the shifted
  inverse is G = A^-1 - W S^-1 W^T, A = K - sigma M, W = A^-1 L_p^T, S = L_p W (a bordered solve).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from .reduction_sparse import MAX_MODES, SHIFT_FRACTION, element_scale, free_free_modes, ritz_estimate, shifted_lu
from .solid.constraints import Constraints, constraints, mass_properties, rigid_rows


CLUSTER = 1e-6  # reduced frequencies this close (relative) form one eigenspace for the MAC


@dataclass(frozen=True, eq=False)
class FullModel:
    """The full FE model as reduced (rigid frames eliminated, u = T z) and the LU of K - sigma M in z."""

    c: Constraints
    K: object  # (n_z, n_z) sparse
    M: object
    lu: object  # solid.ordering.PermutedLU
    sigma: float
    w2_est: float


def full_model(fe, frames) -> FullModel:
    """K, M in z and their one shifted LU (as reduction_sparse.reduce_solid builds them)."""
    c = constraints(fe, frames, mass_properties(fe)[1])
    K, M = (c.T.T @ fe.K @ c.T).tocsr(), (c.T.T @ fe.M @ c.T).tocsr()
    w2_est = ritz_estimate(fe)
    sigma = -SHIFT_FRACTION * w2_est
    return FullModel(c, K, M, shifted_lu(K, M, sigma, c, fe.coords), sigma, w2_est)


def full_modes(fe, frames, cutoff_hz: float, max_modes: int = 40, full: FullModel | None = None):
    """Free-free modes of the full model (rigid frames eliminated) up to cutoff_hz: (f [Hz], modes on
    the FE dofs (3n, k))."""
    m = full or full_model(fe, frames)
    X, w2 = free_free_modes(m.K, m.M, m.c.U, m.c.U.T @ (m.M @ m.c.U), m.lu, None, cutoff_hz, m.sigma,
                           element_scale(m.K, m.M))
    X, w2 = X[:, :max_modes], w2[:max_modes]
    return np.sqrt(w2) / (2 * math.pi), np.asarray(m.c.T @ X)


def frequency_report(red, cutoff_hz: float, full: FullModel | None = None) -> list[dict]:
    """Full against reduced free-free modes up to cutoff_hz (module doc): one row per full mode."""
    f_full, X = full_modes(red.fe, red.frames, cutoff_hz, full=full)
    w2, V = sla.eigh(red.data.K, red.data.M)
    f_red = np.sqrt(np.maximum(w2, 0.0)) / (2 * math.pi)
    Phi = red.Y @ V  # M-normalized reduced modes on the FE dofs
    MX = red.fe.M @ X
    mac = (MX.T @ Phi) ** 2 / np.outer(np.einsum("ij,ij->j", X, MX), np.ones(Phi.shape[1]))
    rows = []
    for i, f in enumerate(f_full):
        j = int(np.argmax(mac[i]))
        # a repeated frequency (a shaft's bending pair) has no unique basis: MAC with its whole eigenspace
        cluster = np.abs(f_red - f_red[j]) <= CLUSTER * f_red[j]
        rows.append({"full_hz": float(f), "reduced_hz": float(f_red[j]), "error": float(f_red[j] / f - 1.0),
                     "mac": float(mac[i, cluster].sum()), "kept": bool(i < len(red.data.frequencies_hz))})
    return rows


def effective_mass(red, cutoff_hz: float | None = None) -> dict:
    """{port: [fraction per direction x, y, z, rx, ry, rz]} of the reduced body clamped at that port, modes
    up to cutoff_hz (all when None) (module doc)."""
    d = red.data
    n = d.n
    mass, J0 = d.mass, d.J0
    MZ = np.zeros((6 + n, 6 + n))
    MZ[:3, :3] = mass * np.eye(3)
    MZ[3:6, 3:6] = J0
    MZ[6:, 6:] = d.M
    KZ = np.zeros_like(MZ)
    KZ[6:, 6:] = d.K
    out = {}
    for f, fr in enumerate(red.frames):
        Rp = np.zeros((6, 6))  # frame f's 6 dofs in the rigid modes about the CM
        Rp[:3] = rigid_rows((fr.point - d.x_cm)[None])[0]
        Rp[3:, 3:] = np.eye(3)
        Ep = np.zeros((6, n))
        Ep[:, 6 * f : 6 * f + 6] = np.eye(6)
        T = np.vstack([-np.linalg.solve(Rp, Ep), np.eye(n)])  # frame f clamped: R_p r + q_Bp = 0, r eliminated
        w2, V = sla.eigh(T.T @ KZ @ T, T.T @ MZ @ T)
        keep = slice(None) if cutoff_hz is None else np.sqrt(np.maximum(w2, 0.0)) / (2 * math.pi) <= cutoff_hz
        Phi = T @ V[:, keep]
        fractions = []
        for k in range(6):
            z = np.zeros(6 + n)
            z[:6] = np.linalg.solve(Rp, np.eye(6)[k])
            total = z @ MZ @ z
            fractions.append(float(np.sum((Phi.T @ MZ @ z) ** 2) / total))
        out[fr.name] = fractions
    return out


def port_motion(c: Constraints, f: int) -> np.ndarray:
    """Z (n_z, 6): the rigid motions z_d in which frame f moves by a unit translation or rotation d about
    its own point (L_f Z = I; module doc)."""
    U = c.U
    return U @ np.linalg.solve(np.asarray(c.L[6 * f : 6 * f + 6] @ U), np.eye(6))


def clamped_modes(m: FullModel, f: int, cutoff_hz: float, max_modes: int = MAX_MODES):
    """The full model clamped at frame f (L_f z = 0) up to cutoff_hz (at most max_modes): (w^2 (k,), modes
    (n_z, k) M-normalized), by ARPACK with the free model's LU and the bordered solve of the module doc."""
    Lf = m.c.L[6 * f : 6 * f + 6]
    n = m.K.shape[0]
    W = m.lu.solve(Lf.T.toarray())
    S = np.asarray(Lf @ W)

    def solve(b):  # the shifted inverse on ker L_f (the Lagrange multipliers of L_f z = 0 eliminated)
        y = m.lu.solve(np.asarray(b, dtype=float))
        return y - W @ np.linalg.solve(S, Lf @ y)

    op = spla.LinearOperator((n, n), matvec=solve, dtype=float)
    v0 = solve(np.asarray(m.M @ np.linspace(1.0, 2.0, n)).ravel())
    top = (2 * math.pi * cutoff_hz) ** 2
    k = 8
    while True:
        k = min(k, n - 7, max_modes)
        w2, V = spla.eigsh(m.K, k=k, M=m.M, sigma=m.sigma, which="LM", OPinv=op, v0=v0, tol=1e-10)
        order = np.argsort(w2)
        w2, V = w2[order], V[:, order]
        if w2[-1] > top or k >= min(n - 7, max_modes):
            break
        k *= 2
    keep = w2 <= top
    V = V[:, keep]
    return w2[keep], V / np.sqrt(np.einsum("ij,ij->j", V, m.M @ V))


def full_effective_mass(red, cutoff_hz: float, full: FullModel | None = None) -> dict:
    """{port: {"fraction": [x, y, z, rx, ry, rz], "rigid": the same directions' z_d^T M z_d (mass [kg],
    inertia about the frame [kg m^2])}} of the full FE model clamped at that port, modes up to cutoff_hz
    (module doc)."""
    m = full or full_model(red.fe, red.frames)
    out = {}
    for f, fr in enumerate(red.frames):
        Z = port_motion(m.c, f)
        MZ = np.asarray(m.M @ Z)
        rigid = np.einsum("ij,ij->j", Z, MZ)
        _, V = clamped_modes(m, f, cutoff_hz)
        gamma = V.T @ MZ  # (k, 6) participation factors
        out[fr.name] = {"fraction": (np.sum(gamma**2, axis=0) / rigid).tolist(), "rigid": rigid.tolist()}
    return out


def quality_report(red, cutoff_hz: float | None) -> dict:
    """What `ffrf-fmu info` reports on a solid (module doc), the full model factored once: the frequency
    table up to cutoff_hz, and the effective mass per port direction of the reduced body (all its modes
    when cutoff_hz is None) and, with a cutoff, of the full model."""
    out = {"cutoff_hz": cutoff_hz, "modes": [], "effective_mass_fraction": effective_mass(red, cutoff_hz)}
    if cutoff_hz:
        full = full_model(red.fe, red.frames)
        out["modes"] = frequency_report(red, cutoff_hz, full)
        out["full_effective_mass"] = full_effective_mass(red, cutoff_hz, full)
    return out
