"""The accelerations of the ports' nodes at the end of a step: the columns `a` and `dw` of a body's
output row (runtime/outputs.py OUTPUT_FIELDS), numpy twin of the C runtime's accel.c.

Which accelerations. The first-order generalized-alpha integrator (runtime/integrator.py) carries an
acceleration-like variable `a` per rate; it is a weighted mean of the rates over the step (am a_{n+1} +
(1 - am) a_n = af ydot_{n+1} + (1 - af) ydot_n), not the acceleration at t_{n+1}. What is reported here
is the TRUE acceleration at t_{n+1}: the time derivative of the node's velocity along the solution,
written with the rates of the velocity field that the step solved for (vdot = [v0dot, Omega0dot, r_bar_dot]
of the superelement that holds the node, its first superelement in the body's order) and the kinematics
of eq. (89)-(91) differentiated once more. With rho_P = R0^T (x_P - x0), d_P = rho_P - X_P (geradin 89):

    x_P'  = v0 + R0 (W0 x rho_P + d_P')                                              (91)
    x_P'' = v0dot + R0 [Omega0dot x rho_P + W0 x (W0 x rho_P) + 2 W0 x d_P' + d_P'']
    w_P   = R_P W_P = R0 W0 + R_P c_P,   c_P = W_P - Q_P^T W0 = H(Q_P)^-1 alpha_P'      (91)
    dw_P  = R0 Omega0dot + R_P (W_P x c_P + c_P'),   c_P' = H^-1 (alpha_P'' - H' c_P),
            H' c_P = -c_P (alpha_P . c_P) + c_P x (Q_P^T c_P) / 2

with q_bar' from the rates (eq. 91, `equations.kinematics`) and q_bar'' from the time derivative of the
kinematic row (79), M (q_bar' - r_bar) [+ G(W0) q_bar] = 0:

    q_bar'' = r_bar_dot [- M^-1 (G(Omega0dot) q_bar + G(W0) q_bar')]     ([...]: the Coriolis part on)

Every quantity is the step's solution at t_{n+1} (x0' = v0 and W0 = Omega0 hold there to the Newton
tolerance), so a and dw are consistent with the reported v and w to the integrator's order:
tests/test_accelerations.py checks them against central differences of v and w over a run (O(h^2)).
Runtime module: ships inside FMUs.
"""
from __future__ import annotations

import numpy as np

from .equations import Superelement, kinematics


def port_owners(se_nodes: np.ndarray, port_nodes: np.ndarray) -> np.ndarray:
    """(n_ports, 2) the superelement e and its local boundary node p of each port's node: the first in
    the body's order (accel.c scans se_nodes the same way)."""
    flat = np.asarray(se_nodes).ravel()
    nb = np.asarray(se_nodes).shape[1]
    first = np.array([int(np.flatnonzero(flat == k)[0]) for k in port_nodes], dtype=int)
    return np.stack([first // nb, first % nb], axis=1)


def port_accelerations(body) -> np.ndarray:
    """(n_ports, 6): per port [a (m/s2), dw (rad/s2)], world axes, at the body's current state (see the
    module docstring). body: a runtime.body.BodySystem."""
    L = body.layout
    owners = port_owners(body.se_nodes, body._port_nodes)
    out = np.zeros((len(owners), 6))
    for j, ((e, p), k) in enumerate(zip(owners, body._port_nodes)):
        nodes = body.se_nodes[e]
        se = Superelement(body.K[e], body.M[e], body.G[e], float(body.mass[e]), body.J0[e], body.X_B[e])
        zdot = body.yd[L.cfg_map[e]]  # [x0dot, W0, etadot, (x_Pdot, W_P) ...]
        vdot = body.yd[L.vel_map[e]]  # [v0dot, Omega0dot, r_bar_dot]
        R0 = body.R0[e]
        kin = kinematics(se, body.x0[e], R0, body.eta[e], body.xN[nodes], body.RN[nodes], zdot)
        W0, v0dot, Omdot = zdot[3:6], vdot[0:3], vdot[3:6]
        qdd = vdot[6:].copy()
        if body.coriolis:  # d/dt of (79): M q_bar'' = M r_bar_dot - G(Omega0dot) q_bar - G(W0) q_bar'
            G = body.G[e]
            rhs = np.einsum("k,kij->ij", Omdot, G) @ kin.q + np.einsum("k,kij->ij", W0, G) @ kin.qdot
            qdd -= np.linalg.solve(body.M[e], rhs)
        d, al = slice(6 * p, 6 * p + 3), slice(6 * p + 3, 6 * p + 6)
        rho, qd = kin.rho[p], kin.qdot[d]
        out[j, 0:3] = v0dot + R0 @ (np.cross(Omdot, rho) + np.cross(W0, np.cross(W0, rho)) + 2.0 * np.cross(W0, qd)
                                    + qdd[d])
        Q, alpha, H = kin.Q[p], kin.alpha[p], kin.H[p]
        WP = body.yd[6 * k + 3 : 6 * k + 6]
        c = WP - Q.T @ W0
        Hdot_c = -c * (alpha @ c) + 0.5 * np.cross(c, Q.T @ c)
        cdot = np.linalg.solve(H, qdd[al] - Hdot_c)
        out[j, 3:6] = R0 @ Omdot + body.RN[k] @ (np.cross(WP, c) + cdot)
    return out
