"""The reduced superelement chain linearized at rest, in physical coordinates (formulation.md
section 6 checks: natural frequencies, static tip deflection).

Per superelement the FE displacement is rigid motion of the CM frame plus the reduced elastic
field (eq. 73, 76): u = U w0 + Y q_bar, with q_bar = [q_B; eta] and q_B = u_B - U_B w0 the
boundary displacements seen from the CM frame. In the coordinates z = [u_B, w0, eta]
(u_B shared by adjacent superelements, w0 = CM translation and rotation, eta modal):

    u = T z,  T = [Y1, U - Y1 U_B, Y2] = Y S + U E,
    S = [[I, -U_B, 0], [0, 0, I]],  E = [0, I_6, 0].

Since U^T M Y = 0 (eq. 74) and K U = 0:
    K_z = T^T K T = S^T K_bar S,
    M_z = T^T M T = S^T M_bar S + E^T diag(mass I_3, J0) E,
using only SuperelementData (works on a BodyData loaded from an FMU). U^T M U is block
diagonal because U is taken about the CM.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .runtime.data import BodyData, SuperelementData


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def boundary_rigid_modes(X_B: np.ndarray) -> np.ndarray:
    """U_B: rows of the rigid modes about the CM at the boundary nodes (eq. 11), (6 nb, 6)."""
    blocks = [np.block([[np.eye(3), -_skew(x)], [np.zeros((3, 3)), np.eye(3)]]) for x in X_B]
    return np.vstack(blocks)


def superelement_matrices(se: SuperelementData) -> tuple[np.ndarray, np.ndarray]:
    """K_z, M_z of one superelement in z = [u_B, w0, eta] (module doc)."""
    n_b, n = se.n_boundary, se.n
    n_m = n - n_b
    S = np.zeros((n, n_b + 6 + n_m))
    S[:n_b, :n_b] = np.eye(n_b)
    S[:n_b, n_b : n_b + 6] = -boundary_rigid_modes(se.X_B)
    S[n_b:, n_b + 6 :] = np.eye(n_m)
    K = S.T @ se.K @ S
    M = S.T @ se.M @ S
    M[n_b : n_b + 6, n_b : n_b + 6] += sla.block_diag(se.mass * np.eye(3), se.J0)
    return K, M


def chain_matrices(body: BodyData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Assembled K, M of the chain and node_dofs (n_nodes, 6): the global dofs of each boundary
    node. Boundary node dofs come first; each superelement appends its w0 (6) and eta."""
    n_nodes = len(body.node_positions)
    node_dofs = np.arange(6 * n_nodes).reshape(n_nodes, 6)
    parts, n_dof = [], 6 * n_nodes
    for se in body.superelements:
        Kz, Mz = superelement_matrices(se)
        n_private = Kz.shape[0] - se.n_boundary
        idx = np.concatenate([node_dofs[se.nodes].ravel(), n_dof + np.arange(n_private)])
        parts.append((idx, Kz, Mz))
        n_dof += n_private
    K, M = np.zeros((n_dof, n_dof)), np.zeros((n_dof, n_dof))
    for idx, Kz, Mz in parts:
        K[np.ix_(idx, idx)] += Kz
        M[np.ix_(idx, idx)] += Mz
    return K, M, node_dofs


def motion_fixed_dofs(body: BodyData) -> np.ndarray:
    """Dofs of the boundary nodes held by motion-driven port parts (translation 0-2, rotation 3-5)."""
    dofs = []
    for p in body.ports:
        if p.translation == "motion":
            dofs += [6 * p.node + k for k in range(3)]
        if p.rotation == "motion":
            dofs += [6 * p.node + k for k in range(3, 6)]
    return np.unique(np.array(dofs, dtype=int))


def _free(n_dof: int, fixed) -> np.ndarray:
    return np.setdiff1d(np.arange(n_dof), np.asarray(fixed, dtype=int))


def natural_frequencies(body: BodyData, fixed: np.ndarray | None = None) -> np.ndarray:
    """Natural frequencies (Hz, ascending) of the chain with `fixed` dofs held (default: the
    motion-driven port parts); rigid-body (< 0.01 Hz) ones are left out."""
    K, M, _ = chain_matrices(body)
    free = _free(K.shape[0], motion_fixed_dofs(body) if fixed is None else fixed)
    w2 = sla.eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], eigvals_only=True)
    f = np.sqrt(np.abs(w2)) / (2.0 * np.pi)
    return f[f > 0.01]


def static_displacements(body: BodyData, loads: dict[int, np.ndarray], fixed: np.ndarray | None = None) -> np.ndarray:
    """Boundary node displacements/rotations (n_nodes, 6) under nodal loads {node: [F, M]}
    (world axes) with `fixed` dofs held (default: the motion-driven port parts)."""
    K, _, node_dofs = chain_matrices(body)
    f = np.zeros(K.shape[0])
    for node, load in loads.items():
        f[node_dofs[node]] += np.asarray(load, dtype=float)
    free = _free(K.shape[0], motion_fixed_dofs(body) if fixed is None else fixed)
    Kff = K[np.ix_(free, free)]
    d = 1.0 / np.sqrt(np.abs(np.diag(Kff)))
    # Jacobi-scaled condition: ~1e3..1e5 when held isostatically, ~1e17 with a rigid mode left
    if np.linalg.cond(Kff * np.outer(d, d)) > 1e12:
        raise ValueError("chain stiffness is singular with these fixed dofs: hold the rigid-body motion")
    x = sla.solve(Kff, f[free], assume_a="pos")
    u = np.zeros(K.shape[0])
    u[free] = x
    return u[node_dofs]
