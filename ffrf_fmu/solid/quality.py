"""Reduction quality of a solid (docs/solids.md, "Quality report"): what an FE analyst checks beside a
reduced body.

- Frequencies: the free-free modes of the full FE model (rigid frames eliminated, as reduced) up to a
  cutoff against the reduced body's (the Ritz values of K_bar, M_bar), paired by the mass-weighted MAC
      MAC(a, b) = (a^T M b)^2 / ((a^T M a)(b^T M b)).
  The kept modes are exact (MAC 1, error at round-off); the attachment modes add approximations of
  the next ones. For a repeated frequency the MAC is taken with the reduced eigenspace (CLUSTER).
- Effective mass per port direction: the reduced body clamped at one port (its frame fixed), its modes
  v_j (M-normalized), and the rigid motion z_d in which that frame moves by a unit translation or
  rotation d: Gamma_j = v_j^T M z_d, effective mass Gamma_j^2, its sum over the modes up to the cutoff
  as a fraction of z_d^T M z_d (the mass for a translation, the inertia about the frame for a
  rotation). What the fraction misses is the motion no kept shape carries under base excitation.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla

from ..reduction_sparse import (SHIFT_FRACTION, constraints, free_free_modes, mass_properties, rigid_rows,
                                ritz_estimate, shifted_lu)


CLUSTER = 1e-6  # reduced frequencies this close (relative) form one eigenspace for the MAC


def full_modes(fe, frames, cutoff_hz: float, max_modes: int = 40):
    """Free-free modes of the full model (rigid frames eliminated) up to cutoff_hz: (f [Hz], modes on
    the FE dofs (3n, k))."""
    mass, x_cm = mass_properties(fe)
    c = constraints(fe, frames, x_cm)
    K, M = (c.T.T @ fe.K @ c.T).tocsr(), (c.T.T @ fe.M @ c.T).tocsr()
    w2_est = ritz_estimate(fe)
    sigma = -SHIFT_FRACTION * w2_est
    lu = shifted_lu(K, M, sigma, c, fe.coords)
    X, w2 = free_free_modes(K, M, c.U, c.U.T @ (M @ c.U), lu, None, cutoff_hz, sigma, w2_est)
    X, w2 = X[:, :max_modes], w2[:max_modes]
    return np.sqrt(w2) / (2 * math.pi), np.asarray(c.T @ X)


def frequency_report(red, cutoff_hz: float) -> list[dict]:
    """Full against reduced free-free modes up to cutoff_hz (module doc): one row per full mode."""
    f_full, X = full_modes(red.fe, red.frames, cutoff_hz)
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
        T = np.vstack([-np.linalg.solve(Rp, Ep), np.eye(n)])  # frame f held: R_p r + q_Bp = 0, r eliminated
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
