"""The reduced superelement chain linearized at rest, in physical coordinates (docs/background.md
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

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .runtime.data import BodyData, SuperelementData
from .runtime.rotation import skew


def boundary_rigid_modes(X_B: np.ndarray) -> np.ndarray:
    """U_B: rows of the rigid modes about the CM at the boundary nodes (eq. 11), (6 nb, 6)."""
    blocks = [np.block([[np.eye(3), -skew(x)], [np.zeros((3, 3)), np.eye(3)]]) for x in X_B]
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
    """Dofs of the boundary nodes fixed by motion-driven port parts (translation 0-2, rotation 3-5)."""
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
    """Natural frequencies (Hz, ascending) of the chain with `fixed` dofs removed (default: the
    motion-driven port parts); rigid-body (< 0.01 Hz) ones are left out."""
    K, M, _ = chain_matrices(body)
    free = _free(K.shape[0], motion_fixed_dofs(body) if fixed is None else fixed)
    w2 = sla.eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], eigvals_only=True)
    f = np.sqrt(np.abs(w2)) / (2.0 * np.pi)
    return f[f > 0.01]


def static_displacements(body: BodyData, loads: dict[int, np.ndarray], fixed: np.ndarray | None = None) -> np.ndarray:
    """Boundary node displacements/rotations (n_nodes, 6) under nodal loads {node: [F, M]}
    (world axes) with `fixed` dofs removed (default: the motion-driven port parts)."""
    K, _, node_dofs = chain_matrices(body)
    f = np.zeros(K.shape[0])
    for node, load in loads.items():
        f[node_dofs[node]] += np.asarray(load, dtype=float)
    free = _free(K.shape[0], motion_fixed_dofs(body) if fixed is None else fixed)
    Kff = K[np.ix_(free, free)]
    d = 1.0 / np.sqrt(np.abs(np.diag(Kff)))
    # Jacobi-scaled condition: ~1e3..1e5 when fixed isostatically, ~1e17 with a rigid mode left
    if np.linalg.cond(Kff * np.outer(d, d)) > 1e12:
        raise ValueError("chain stiffness is singular with these fixed dofs: hold the rigid-body motion")
    x = sla.solve(Kff, f[free], assume_a="pos")
    u = np.zeros(K.shape[0])
    u[free] = x
    return u[node_dofs]


# ---------------------------------------------------------------------------------------------
# The runtime equations linearized about a steady spin (docs/background.md, rotating cantilever)
#
# A body whose motion-driven ports spin at a constant world rate w (about an axis through the world
# origin) has a relative equilibrium: in the spinning frame nothing moves. With the unknowns of
# runtime/layout.py seen from that frame (world vectors x, v0 rotated back, body-axes rotation
# increments dTheta: R <- R exp(dTheta)), the rates of a perturbed motion are
#     d(xdot) = xi' + skew(w) xi        (node and CM positions, CM velocity v0: world vectors)
#     d(W)    = dTheta' + skew(W) dTheta (W = R^T w the body-axes rate of the steady motion)
#     the rest: xi'                      (eta, Omega0, r_bar are body quantities)
# i.e. d(ydot) = xi' + P xi. The runtime's F_ydot, F_y then give the time-invariant system
#     F_ydot xi' + (F_y + F_ydot P) xi = 0,
# whose matrix J = F_y + F_ydot P is also the Newton matrix of the steady state (rates = P-rule).
# Eigenvalues lambda of J xi = -lambda F_ydot xi: frequencies |Im lambda| / 2 pi in the spinning frame.
# ---------------------------------------------------------------------------------------------


def _spin_rates(system, w: np.ndarray) -> np.ndarray:
    """Global ydot of the steady spin at the system's current configuration (layout.py order)."""
    L = system.layout
    yd = np.zeros(L.ny)
    zN, zS, vd = system.split_rates(yd)
    zN[:, 0:3] = np.cross(w, system.xN)
    zN[:, 3:6] = w @ system.RN  # R^T w
    zS[:, 0:3] = np.cross(w, system.x0)
    zS[:, 3:6] = w @ system.R0
    vd[:, 0:3] = np.cross(w, system.v[:, 0:3])
    return yd


def _spin_operator(system, w: np.ndarray) -> np.ndarray:
    """P (ny, ny): d(ydot) = xi' + P xi about the steady spin (block comment above)."""
    L = system.layout
    P = np.zeros((L.ny, L.ny))
    W = skew(w)
    for i in range(L.n_nodes):
        P[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = W
        P[6 * i + 3 : 6 * i + 6, 6 * i + 3 : 6 * i + 6] = skew(system.RN[i].T @ w)
    nN, nS = 6 * L.n_nodes, 6 + L.nm
    for e in range(L.n_se):
        c, v = nN + e * nS, nN + L.n_se * nS + e * L.nv
        P[c : c + 3, c : c + 3] = W
        P[c + 3 : c + 6, c + 3 : c + 6] = skew(system.R0[e].T @ w)
        P[v : v + 3, v : v + 3] = W
    return P


def _spin_system(system, w):
    """(F, J, F_ydot) on the unknowns at the current configuration with the steady-spin rates."""
    system.yd = _spin_rates(system, w)
    fi = system.unknowns
    F = system.residual(system.yd)
    Fz, Fy = system.linearization()
    P = _spin_operator(system, w)[np.ix_(fi, fi)]
    return F, Fy + Fz @ P, Fz


def correction(system, d: np.ndarray) -> float:
    """The size of a Newton correction d (ydot layout, `BodySystem.move`) of a relative equilibrium: the
    largest |d_i| / (1 + |y_i|), y the unknowns' values (positions, eta and velocities; rotations 0). A
    fast spin makes some unknowns large (a solid at 200 rad/s: an elastic velocity r_bar of 77, whose
    corrections settle at 1e-9 where the Newton matrix's conditioning leaves round-off), so an absolute
    bound would ask more digits of them than the arithmetic holds; on O(1) unknowns it is the absolute one."""
    y = system.layout.stage(system.xN, system.x0, system.eta, system.v)
    return float(np.max(np.abs(d) / (1.0 + np.abs(y))))


def steady_spin(system, omega: float, axis=(0.0, 0.0, 1.0), tol: float = 1e-10, max_iter: int = 30):
    """Bring `system` (a runtime.body.BodySystem, no loads, gravity along the axis or none; its motion-driven ports at
    their reference frames, R = I) to its relative equilibrium at the constant spin omega about
    `axis` through the world origin: Newton on F(y, ydot(y)) = 0 with the matrix J (block comment),
    until a correction is below tol (`correction`). Returns the system (state set: configuration,
    velocities, rates)."""
    w = omega * np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    L = system.layout
    system.reset_reference()
    system.v[:, 0:3] = np.cross(w, system.x0)
    system.v[:, 3:6] = w @ system.R0
    for _ in range(max_iter):
        F, J, _ = _spin_system(system, w)
        d = np.zeros(L.ny)
        d[system.unknowns] = np.linalg.solve(J, -F)
        step = correction(system, d)
        system.move(d)
        if step < tol:
            system.yd = _spin_rates(system, w)
            return system
    raise RuntimeError(f"steady spin at {omega} rad/s: Newton did not converge (last correction {step:.3g})")


def spin_modes(system, omega: float, axis=(0.0, 0.0, 1.0), f_max: float = 50.0):
    """Small vibrations about the steady spin (the system is brought there first): frequencies [Hz]
    in the spinning frame, ascending, up to f_max, and the eigenvectors on the unknowns (columns).
    An eigenvalue with a positive real part (divergence) is returned as a NaN frequency."""
    steady_spin(system, omega, axis)
    w = omega * np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    _, J, Fz = _spin_system(system, w)
    lam, vec = sla.eig(-J, Fz)
    ok = np.isfinite(lam)
    lam, vec = lam[ok], vec[:, ok]
    unstable = lam.real > 1e-6 * np.maximum(1.0, np.abs(lam))
    f = np.abs(lam.imag) / (2.0 * np.pi)
    keep = ((lam.imag > 1e-9) & (f < f_max)) | unstable & (np.abs(lam) / (2 * np.pi) < f_max) & (lam.imag >= 0)
    f = np.where(unstable, np.nan, f)[keep]
    vec = vec[:, keep]
    order = np.argsort(np.nan_to_num(f, nan=-1.0))
    return f[order], vec[:, order]


# ---------------------------------------------------------------------------------------------
# Each mode about the steady spin with its direction (docs/background.md: out of the plane of
# rotation omega^2 = omega_0^2 + K Omega^2, in the plane omega^2 = omega_0^2 + (K - 1) Omega^2; the
# two first frequencies differ by the centrifugal softening Omega^2 of the in-plane motion, 1.6 x at
# 4 rad/s on B1). A mode's direction is where its boundary nodes move, relative to the spin axis a
# and the beam axis e: along a (out-of-plane, flap), along a x e (in-plane, lead-lag), along e
# (axial), or rotating about e (torsion).
# ---------------------------------------------------------------------------------------------

DIRECTIONS = ("in-plane", "out-of-plane", "axial", "torsion")


@dataclass(frozen=True)
class SpinMode:
    """One small vibration about the steady spin: its frequency in the spinning frame [Hz] (NaN:
    divergent), its direction (one of DIRECTIONS) and the share of the boundary nodes' motion in each
    direction (translations, and rotations times the beam length)."""

    frequency_hz: float
    direction: str
    shares: dict


def mode_directions(system, vectors: np.ndarray, axis, beam_direction, length: float) -> list[tuple[str, dict]]:
    """(direction, shares) of each eigenvector (columns on the system's unknowns, spin_modes): the squared
    motion of the boundary nodes projected on the spin axis a (out-of-plane), a x e (in-plane), the beam
    axis e (axial) and the rotation about e times `length` (torsion); bending rotations count with their
    plane (a rotation about a moves the beam in the plane of rotation). A spin about the beam's own axis
    has no plane of rotation: every bending mode is then called in-plane."""
    from .directions import spin_plane

    e = np.asarray(beam_direction, dtype=float) / np.linalg.norm(beam_direction)
    t, a_n = spin_plane(axis, e)  # in-plane; out-of-plane (the part of a normal to the beam)
    n_nodes = system.layout.n_nodes
    out = []
    for v in np.atleast_2d(vectors.T):
        full = np.zeros(system.layout.ny, dtype=complex)
        full[system.unknowns] = v
        node = full[: 6 * n_nodes].reshape(n_nodes, 6)
        u, r = node[:, 0:3], node[:, 3:6] * length
        power = lambda x, d: float(np.sum(np.abs(x @ d) ** 2))  # noqa: E731
        parts = {"in-plane": power(u, t) + power(r, a_n), "out-of-plane": power(u, a_n) + power(r, t),
                 "axial": power(u, e), "torsion": power(r, e)}
        total = sum(parts.values()) or 1.0
        shares = {k: v / total for k, v in parts.items()}
        out.append((max(shares, key=shares.get), shares))
    return out


def directional_spin_modes(system, omega: float, axis=(0.0, 0.0, 1.0), *, beam_direction=(1.0, 0.0, 0.0),
                           length: float = 1.0, f_max: float = 50.0) -> list[SpinMode]:
    """spin_modes with each mode's direction (mode_directions), ascending in frequency."""
    f, V = spin_modes(system, omega, axis, f_max)
    dirs = mode_directions(system, V, axis, beam_direction, length) if len(f) else []
    return [SpinMode(float(fi), d, s) for fi, (d, s) in zip(f, dirs)]


def first_by_direction(modes: list[SpinMode]) -> dict:
    """The lowest frequency [Hz] of each direction that has a mode (NaN when its first mode diverges)."""
    out: dict = {}
    for m in modes:
        out.setdefault(m.direction, m.frequency_hz)
    return out
