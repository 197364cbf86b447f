"""Compliant coupling: a spring-damper between a port's nodal frame and a motion input (docs/cosim.md).

A port part declared `compliant` is free inside the body (like a force-driven part) and loaded by
a spring-damper whose far end is the motion input of the port: so the port takes motion in and
gives force out, like a motion-driven port, and an explicit (Jacobi) master can couple it to a
force-driven partner without the one-step lag of the partner's force acting on this body's small
interface inertia (the spring is integrated implicitly with the body).

Translation (world axes, diagonal stiffness and damping per world axis):
    f = K_t (r_in - x_N) + C_t (v_in - xdot_N)
Rotation (nodal axes, diagonal per nodal axis), phi = log(R_N^T R_in) the rotation from the node
frame to the input frame in nodal axes, W_N the nodal angular velocity in nodal axes:
    m = K_r phi + C_r (R_N^T w_in - W_N),   moment on the body in world axes t = R_N m.
The node rows of the body residual receive -f (world) and -m (nodal axes) like force inputs.

Runtime module: numpy only, relative imports.
"""
from __future__ import annotations

import numpy as np

from .rotation import logm, skew, tangent


def spring_force(K, C, r_in, v_in, x, u):
    """Translational spring-damper force on the body (world axes) and its derivatives
    d f / d x = -diag(K), d f / d u = -diag(C)."""
    return K * (r_in - x) + C * (v_in - u)


def spring_moment(K, C, R_in, w_in, R, W):
    """Rotational spring-damper moment on the body in nodal axes, m = K phi + C (R^T w_in - W),
    phi = log(R^T R_in), and its derivative with respect to a right variation R -> R exp(skew(dTheta)):
    dm/dTheta = -K T(-phi)^-1 + C skew(R^T w_in)  (exp(skew(-dTheta)) exp(skew(phi)) =
    exp(skew(phi - T(-phi)^-1 dTheta)): the left tangent of phi); dm/dW = -diag(C)."""
    phi = logm(R.T @ R_in)
    wb = R.T @ w_in
    m = K * phi + C * (wb - W)
    dm_dTheta = -K[:, None] * np.linalg.inv(tangent(-phi)) + C[:, None] * skew(wb)
    return m, dm_dTheta


def port_mass(data, node: int) -> tuple[float, np.ndarray]:
    """Rigid-body mass and inertia tensor (world = reference axes) of the whole body about a node, in
    the reference configuration: the low-frequency apparent mass of the port (its mobility is
    1/(i omega m) there). Sum over superelements of m_e and J0_e + m_e (|d|^2 I - d d^T), d the CM
    offset from the node (parallel axes)."""
    X = np.asarray(data.node_positions[node], dtype=float)
    m, J = 0.0, np.zeros((3, 3))
    for se in data.superelements:
        d = np.asarray(se.x_cm, float) - X
        m += float(se.mass)
        J += np.asarray(se.J0, float) + se.mass * (d @ d * np.eye(3) - np.outer(d, d))
    return m, J


def compliance_rule(data, node: int, H: float, alpha: float = 0.5, zeta: float = 0.5) -> np.ndarray:
    """Default stiffness and damping of a compliant port for the communication step H (the rule of
    docs/cosim.md): coupling frequency omega_c = alpha / H, k = omega_c^2 m_P and c = 2 zeta omega_c m_P
    per axis, m_P the port's rigid-body mass (translation) and the diagonal of its inertia tensor
    about the node (rotation). The partner receives the spring force held over H: the coupling mode
    stays stable while omega_c H = alpha < 1 against an interface mass of the order of m_P, and the
    coupling's own deflection adds an error of order (omega_band / omega_c)^2 below its frequency.
    Returns (4, 3): K_t, C_t, K_r, C_r."""
    m, J = port_mass(data, node)
    w = alpha / H
    mp = np.concatenate([np.full(3, m), np.diag(J)])
    k, c = w * w * mp, 2.0 * zeta * w * mp
    return np.stack([k[:3], c[:3], k[3:], c[3:]])


def add_springs(springs, p, yd, R, F, J, beta, newton_pos, loads):
    """Add the spring-damper loads of compliant ports to the residual F (ny,) and, when J is given,
    their derivatives to the iteration matrix J (Newton order; d config = beta T d rate on rotations).

    springs: [(node, translation: bool, rotation: bool, KC (4, 3), (r_in, v_in, R_in, w_in))]; p the
    configuration source vector, yd the rates, R the node rotations (N+E, 3, 3). loads (N, 2, 3) receives
    the force (world) and moment (world) on each compliant node, for the port outputs."""
    for k, trans, rot, KC, (r_in, v_in, R_in, w_in) in springs:
        i = 6 * k
        if trans:
            f = spring_force(KC[0], KC[1], r_in, v_in, p[i:i + 3], yd[i:i + 3])
            F[i:i + 3] -= f
            loads[k, 0] = f
            if J is not None:
                pos = newton_pos[i:i + 3]
                J[pos, pos] += beta * KC[0] + KC[1]
        if rot:
            m, dm = spring_moment(KC[2], KC[3], R_in, w_in, R[k], yd[i + 3:i + 6])
            F[i + 3:i + 6] -= m
            loads[k, 1] = R[k] @ m
            if J is not None:
                pos = newton_pos[i + 3:i + 6]
                J[np.ix_(pos, pos)] += -beta * dm @ tangent(p[i + 3:i + 6]) + np.diag(KC[3])
