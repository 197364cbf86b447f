"""The equations of one two-field superelement, written straight from the paper: the test oracle of
the C runtime (runtime/native) and the numpy path's equations (runtime/assembly.py assembles a body
from it).

Equation numbers are those of Geradin's two-field paper; docs/equations.md has the algebra.
Clarity first, one superelement and one boundary node at a time: the fast path is the C runtime's.

One superelement e with boundary nodes P (local layout, runtime/layout.py):
    configuration   x0, R0 (CM frame), eta, and the frames (x_P, R_P) of its boundary nodes
    velocities      v = [v0 (world), Omega0 (body), r_bar]
    rates           zdot = [x0dot, W0, etadot, (x_Pdot, W_P) per node], vdot = [v0dot, Omega0dot, rdot_bar]
Elastic coordinates from the frames, eq. (89):
    rho_P = R0^T (x_P - x0),  d_P = rho_P - X_P,  Q_P = R0^T R_P,  alpha_P = vect(Q_P)
    q_bar = [d_P, alpha_P per node; eta]
and their rates, eq. (91):
    d_Pdot = R0^T (x_Pdot - x0dot) + rho_P x W0,   alpha_Pdot = H(Q_P) (W_P - Q_P^T W0)
Residual rows (`[...]`: gyroscopic term set only; `linear` is Remark 6, eqs. 72a-c):
    k_x   = x0dot - v0                                           (69b)
    k_T   = W0 - Omega0                                          (69d)
    k_q   = M (q_bar_dot - r_bar) [+ G(W0) q_bar]                (79)
    g     = K q_bar + M r_bar_dot [+ G(W0) r_bar] [+ D q_bar_dot] (78), f_e = 0 by (74)
    e_x0  = m v0dot - m g_grav - sum_P R0 g_dP                   (69a) with (91)
    e_T0  = J0 Omega0dot + W0 x (J0 Omega0 [+ s]) [+ sdot]
            - sum_P (rho_P x g_dP + Q_P H_P^T g_aP)              (77) with (91)
    e_eta = g_eta
    e_xP  = R0 g_dP,   e_TP = H_P^T g_aP                         (91), summed over the SEs at P
with G(W) = sum_k W_k G_k (53), s_k = r_bar^T G_k q_bar (55) and sdot_k its time derivative. The two
parts of `[...]` can be switched apart (`parts`, the `full` term set's switches): the inertia coupling
(s, sdot in e_T0) and the elastic Coriolis (G(W0) in k_q and g). D q_bar_dot is the structural damping
(runtime/damping.py), on the co-rotated elastic rates of (91), not on r_bar: in a steady spin of a
deformed body r_bar = q_bar_dot + M^-1 G(W0) q_bar is not zero, the strain rate is.
Loads on the nodes are not part of a superelement (the body adds -f, -R^T t on node rows).

The Jacobian is with respect to the rates (F_ydot) and to the configuration (F_y): variations
dx (world), dTheta (body axes, R <- R exp(skew(dTheta))), deta, and dv. The iteration matrix of the
integrator (runtime/integrator.py) is built from both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rotation import skew, vect, vect_tangent


@dataclass(frozen=True, eq=False)
class Superelement:
    """One superelement's reduced matrices (runtime/data.py SuperelementData has the same fields)."""

    K: np.ndarray  # (n, n) K_bar
    M: np.ndarray  # (n, n) M_bar
    G: np.ndarray  # (3, n, n) G_k (53)
    mass: float
    J0: np.ndarray  # (3, 3)
    X_B: np.ndarray  # (nb, 3) boundary nodes relative to the CM, body axes
    D: np.ndarray | None = None  # (n, n) structural damping on the co-rotated rates (runtime/damping.py), or None


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Everything of eq. (89) and (91) at one configuration and rates, with the derivatives of q_bar
    and q_bar_dot with respect to the local configuration (columns [x0, Theta0, eta, (x_P, Theta_P)...])."""

    R0: np.ndarray
    rho: np.ndarray  # (nb, 3) X_P + d_P
    Q: np.ndarray  # (nb, 3, 3) R0^T R_P
    alpha: np.ndarray  # (nb, 3) vect(Q)
    H: np.ndarray  # (nb, 3, 3) H(Q), the tangent of vect
    q: np.ndarray  # (n,) q_bar
    qdot: np.ndarray  # (n,) q_bar_dot
    Dq: np.ndarray  # (n, nc) dq_bar/d(configuration) = dq_bar_dot/d(zdot)
    Dqdot: np.ndarray  # (n, nc) dq_bar_dot/d(configuration) at fixed rates


def kinematics(se: Superelement, x0, R0, eta, xP, RP, zdot) -> Kinematics:
    """q_bar (89), q_bar_dot (91) and their derivatives, one boundary node at a time."""
    nb, nm = len(se.X_B), len(eta)
    n, nc = 6 * nb + nm, 6 + nm + 6 * nb
    x0dot, W0 = zdot[0:3], zdot[3:6]
    etadot = zdot[6 : 6 + nm]
    q, qdot = np.zeros(n), np.zeros(n)
    Dq, Dqdot = np.zeros((n, nc)), np.zeros((n, nc))
    rho, Q, alpha, H = np.zeros((nb, 3)), np.zeros((nb, 3, 3)), np.zeros((nb, 3)), np.zeros((nb, 3, 3))
    X0, T0 = slice(0, 3), slice(3, 6)
    for p in range(nb):
        XP, TP = slice(6 + nm + 6 * p, 9 + nm + 6 * p), slice(9 + nm + 6 * p, 12 + nm + 6 * p)
        xPdot, WP = zdot[XP], zdot[TP]
        d_rows, a_rows = slice(6 * p, 6 * p + 3), slice(6 * p + 3, 6 * p + 6)
        rho[p] = R0.T @ (xP[p] - x0)
        Q[p] = R0.T @ RP[p]
        alpha[p] = vect(Q[p])
        H[p] = vect_tangent(Q[p])
        u = R0.T @ (xPdot - x0dot)  # relative velocity of P in CM axes
        c = WP - Q[p].T @ W0  # relative angular rate of P, node axes
        q[d_rows], q[a_rows] = rho[p] - se.X_B[p], alpha[p]
        qdot[d_rows] = u + np.cross(rho[p], W0)
        qdot[a_rows] = H[p] @ c
        # d d_P = -R0^T dx0 + skew(rho) dTheta0 + R0^T dx_P
        Dq[d_rows, X0], Dq[d_rows, T0], Dq[d_rows, XP] = -R0.T, skew(rho[p]), R0.T
        # d alpha_P = H eps, eps = dTheta_P - Q^T dTheta0
        Dq[a_rows, T0], Dq[a_rows, TP] = -H[p] @ Q[p].T, H[p]
        # d(d_Pdot) at fixed rates = skew(u) dTheta0 - skew(W0) d(d_P)
        Dqdot[d_rows] = -skew(W0) @ Dq[d_rows]
        Dqdot[d_rows, T0] += skew(u)
        # d(H c) = (-c alpha^T - skew(Q^T c)/2) eps + H dc,  dc = -d(Q^T) W0 = -skew(Q^T W0) eps
        B = -np.outer(c, alpha[p]) - 0.5 * skew(Q[p].T @ c) - H[p] @ skew(Q[p].T @ W0)
        Dqdot[a_rows, TP], Dqdot[a_rows, T0] = B, -B @ Q[p].T
    q[6 * nb :], qdot[6 * nb :] = eta, etadot
    Dq[6 * nb :, 6 : 6 + nm] = np.eye(nm)
    return Kinematics(R0, rho, Q, alpha, H, q, qdot, Dq, Dqdot)


def residual(se: Superelement, terms: str, gravity, x0, R0, eta, xP, RP, v, zdot, vdot) -> np.ndarray:
    """Local residual rows [k_x, k_T, k_q | e_x0, e_T0, e_eta, (e_xP, e_TP) per node] (no loads)."""
    return residual_and_jacobian(se, terms, gravity, x0, R0, eta, xP, RP, v, zdot, vdot)[0]


def residual_and_jacobian(se: Superelement, terms: str, gravity, x0, R0, eta, xP, RP, v, zdot, vdot, g_terms=(), row_terms=(),
                          parts=None):
    """(F, F_ydot, F_y) of one superelement: F (nv + nc,) local rows; F_ydot, F_y (nv + nc, nc + nv)
    with columns [configuration (nc) | velocities (nv)] (rates zdot, vdot for F_ydot).

    parts: which parts of the gyroscopic terms are on, a subset of ("inertia_coupling", "coriolis")
    (default: both for `gyroscopic`, none for `linear`): the coupling s = S(q) r (55) and its rate in
    the CM rotation row (77), the Coriolis G(W0) q in (79) and G(W0) r in (78).

    Hooks for further terms, each a function (se, kin: Kinematics, v, zdot, vdot) -> (value, d/d rates,
    d/d configuration) with derivative columns as above: `g_terms` return a contribution to the elastic
    force g (n,), projected on the CM and node rows like g itself (91); `row_terms` return local rows
    (nv + nc,) directly."""
    if terms not in ("linear", "gyroscopic"):
        raise ValueError(f"unknown term set {terms!r}")
    if parts is None:
        parts = ("inertia_coupling", "coriolis") if terms == "gyroscopic" else ()
    coupling, coriolis = "inertia_coupling" in parts, "coriolis" in parts
    nb, nm = len(se.X_B), len(eta)
    n, nc, nv = 6 * nb + nm, 6 + nm + 6 * nb, 6 + 6 * nb + nm
    kin = kinematics(se, x0, R0, eta, xP, RP, zdot)
    q, qdot, Dq, Dqdot = kin.q, kin.qdot, kin.Dq, kin.Dqdot
    x0dot, W0 = zdot[0:3], zdot[3:6]
    v0, Omega0, r = v[0:3], v[3:6], v[6:]
    v0dot, Omega0dot, rdot = vdot[0:3], vdot[3:6], vdot[6:]
    K, M, G, J0, m = se.K, se.M, se.G, se.J0, se.mass
    I3 = np.eye(3)
    F, Fz, Fy = np.zeros(nv + nc), np.zeros((nv + nc, nc + nv)), np.zeros((nv + nc, nc + nv))
    # columns: configuration [x0, Theta0, eta, nodes], then velocities [v0, Omega0, r]
    cT0, cv0, cOm0, cr = slice(3, 6), slice(nc, nc + 3), slice(nc + 3, nc + 6), slice(nc + 6, nc + nv)
    cfg = slice(0, nc)
    # rows
    kx, kT, kq = slice(0, 3), slice(3, 6), slice(6, nv)
    ex0, eT0, eeta = slice(nv, nv + 3), slice(nv + 3, nv + 6), slice(nv + 6, nv + 6 + nm)

    # kinematic rows (69b), (69d)
    F[kx] = x0dot - v0
    Fz[kx, 0:3], Fy[kx, cv0] = I3, -I3
    F[kT] = W0 - Omega0
    Fz[kT, cT0], Fy[kT, cOm0] = I3, -I3
    # (79): M (q_dot - r) [+ G(W0) q]
    GW = np.einsum("k,kij->ij", W0, G)  # G(W0)
    F[kq] = M @ (qdot - r)
    Fz[kq, cfg] = M @ Dq
    Fy[kq, cfg] = M @ Dqdot
    Fy[kq, cr] = -M
    # elastic force (78): g = K q + M rdot [+ G(W0) r], with its derivatives dg_z (rates), dg_y
    g = K @ q + M @ rdot
    dg_z, dg_y = np.zeros((n, nc + nv)), np.zeros((n, nc + nv))
    dg_y[:, cfg] = K @ Dq
    dg_z[:, cr] = M
    if se.D is not None:  # structural damping D q_bar_dot: q_bar_dot (91) depends on the rates and the configuration
        g += se.D @ qdot
        dg_z[:, cfg] += se.D @ Dq
        dg_y[:, cfg] += se.D @ Dqdot
    # angular momentum h = J0 Omega0 [+ s] and the inertia torque W0 x h [+ sdot] (77)
    h = J0 @ Omega0
    torque = J0 @ Omega0dot
    Fz[eT0, nc + 3 : nc + 6] = J0
    Fy[eT0, cOm0] = skew(W0) @ J0
    if coriolis:
        F[kq] += GW @ q
        Fz[kq, cT0] += np.stack([G[k] @ q for k in range(3)], axis=1)
        Fy[kq, cfg] += GW @ Dq
        g += GW @ r
        dg_z[:, cT0] += np.stack([G[k] @ r for k in range(3)], axis=1)
        dg_y[:, cr] += GW
    if coupling:
        s = np.array([r @ G[k] @ q for k in range(3)])  # (55)
        sdot = np.array([rdot @ G[k] @ q + r @ G[k] @ qdot for k in range(3)])
        h = h + s
        torque = torque + sdot
        ds_dq = np.stack([r @ G[k] for k in range(3)])  # (3, n)
        ds_dr = np.stack([G[k] @ q for k in range(3)])
        Fy[eT0, cfg] += skew(W0) @ ds_dq @ Dq
        Fy[eT0, cr] += skew(W0) @ ds_dr
        # sdot_k = rdot^T G_k q + r^T G_k qdot
        Fz[eT0, cr] += ds_dr  # d/d rdot: (G_k q)^T
        Fy[eT0, cfg] += np.stack([rdot @ G[k] for k in range(3)]) @ Dq
        Fy[eT0, cr] += np.stack([G[k] @ qdot for k in range(3)])
        Fz[eT0, cfg] += ds_dq @ Dq  # d/d qdot: r^T G_k, qdot depends on the rates through Dq
        Fy[eT0, cfg] += ds_dq @ Dqdot
    F[eT0] = torque + np.cross(W0, h)
    Fz[eT0, cT0] += -skew(h)  # d(W0 x h)/dW0
    # (69a): m v0dot - m g_grav
    F[ex0] = m * v0dot - m * np.asarray(gravity, dtype=float)
    Fz[ex0, cv0] = m * I3
    for term in g_terms:  # further elastic forces, e.g. geometric stiffening (docs/background.md, rotating cantilever)
        g_t, dgz_t, dgy_t = term(se, kin, v, zdot, vdot)
        g, dg_z, dg_y = g + g_t, dg_z + dgz_t, dg_y + dgy_t
    F[eeta] = g[6 * nb :]
    Fz[eeta], Fy[eeta] = dg_z[6 * nb :], dg_y[6 * nb :]
    Fb, Fzb, Fyb = project_boundary_force(kin, g, dg_z, dg_y, nv, nm)
    F, Fz, Fy = F + Fb, Fz + Fzb, Fy + Fyb
    for term in row_terms:  # further terms on any local row
        F_t, Fz_t, Fy_t = term(se, kin, v, zdot, vdot)
        F, Fz, Fy = F + F_t, Fz + Fz_t, Fy + Fy_t
    return F, Fz, Fy


def body_residual_and_jacobian(data, layout, terms: str, gravity, xN, RN, x0, R0, eta, v, yd,
                               full_terms=("inertia_W1", "inertia_W2", "inertia_coupling", "coriolis")):
    """Every superelement of a body through `residual_and_jacobian`, one at a time: the assembled
    residual without loads F (ny,) (rows summed Boolean-wise at the shared nodes) and the local blocks
    F_ydot, F_y (E, nv + nc, nc + nv). `data` is a BodyData, `layout` its runtime.layout.Layout,
    yd the global rates; the same quantities as `BodySystem._local`."""
    F = np.zeros(layout.ny)
    Fz, Fy = [], []
    for e in range(len(data.superelements)):
        Fe, Fze, Fye = superelement_residual_and_jacobian(data, layout, terms, gravity, e, xN, RN, x0, R0, eta, v, yd,
                                                          full_terms)
        np.add.at(F, np.concatenate([layout.vel_map[e], layout.cfg_map[e]]), Fe)
        Fz.append(Fze)
        Fy.append(Fye)
    return F, np.stack(Fz), np.stack(Fy)


def superelement_residual_and_jacobian(data, layout, terms: str, gravity, e: int, xN, RN, x0, R0, eta, v, yd,
                                       full_terms=("inertia_W1", "inertia_W2", "inertia_coupling", "coriolis")):
    """Superelement e of a body through `residual_and_jacobian` with the hooks of its term set: its
    local rows F (nv + nc,) and blocks F_ydot, F_y (nv + nc, nc + nv), at the body's configuration
    and global rates yd (arguments as `body_residual_and_jacobian`)."""
    from .damping import damping_matrices, modal_basis
    from .stiffening import plain_hooks

    sd = data.superelements[e]
    damped = data.damping is not None and data.damping.kind != "none"
    D = damping_matrices(data.damping, modal_basis(sd.K[None], sd.M[None])) if damped else None
    se = Superelement(sd.K, sd.M, sd.G, sd.mass, sd.J0, sd.X_B, None if D is None else D[0])
    cfg, vel = layout.cfg_map[e], layout.vel_map[e]
    hooks = {}
    full = terms == "full"
    use_W1 = sd.stiffening or (full and "inertia_W1" in full_terms)
    use_W2 = full and "inertia_W2" in full_terms
    if use_W1 or use_W2:  # geometric stiffening, deformation-dependent inertia (runtime/stiffening.py)
        membrane = (sd.vk_a, sd.vk_B) if sd.stiffening else (None, None)
        g_term, row_term = plain_hooks(sd.W1 * (1.0 if use_W1 else 0.0), *membrane, sd.W2 if use_W2 else None)
        hooks = {"g_terms": (g_term,), "row_terms": (row_term,)}
    parts = tuple(p for p in ("inertia_coupling", "coriolis") if terms == "gyroscopic" or (full and p in full_terms))
    return residual_and_jacobian(se, "linear", gravity, x0[e], R0[e], eta[e], xN[sd.nodes], RN[sd.nodes],
                                 v[e], yd[cfg], yd[vel], parts=parts, **hooks)


def project_boundary_force(kin: Kinematics, g, dg_z, dg_y, nv: int, nm: int):
    """The boundary part g_B of an elastic force g (n,) on the local rows through eq. (91):
    R0 g_dP on node P's translation rows and minus it on the CM's (69a), H_P^T g_aP on node P's
    rotation rows, -(rho_P x g_dP + Q_P H_P^T g_aP) on the CM rotation rows (77). Returns (F, F_ydot,
    F_y) local, given the derivatives dg_z, dg_y (n, nc + nv) of g."""
    # the boundary forces g_B through (91), one node at a time
    nb, R0 = len(kin.rho), kin.R0
    nc, ncv = 6 + nm + 6 * nb, 6 + nm + 6 * nb + nv
    F, Fz, Fy = np.zeros(nv + nc), np.zeros((nv + nc, ncv)), np.zeros((nv + nc, ncv))
    cT0, cfg, Dq = slice(3, 6), slice(0, nc), kin.Dq
    ex0, eT0 = slice(nv, nv + 3), slice(nv + 3, nv + 6)
    for p in range(nb):
        d_rows, a_rows = slice(6 * p, 6 * p + 3), slice(6 * p + 3, 6 * p + 6)
        exP = slice(nv + 6 + nm + 6 * p, nv + 9 + nm + 6 * p)
        eTP = slice(nv + 9 + nm + 6 * p, nv + 12 + nm + 6 * p)
        TP = slice(9 + nm + 6 * p, 12 + nm + 6 * p)
        Qp, Hp, rho = kin.Q[p], kin.H[p], kin.rho[p]
        g_d, g_a = g[d_rows], g[a_rows]
        # R0 g_d on the node (+) and the CM (-) translation rows: d(R0 g_d) = -R0 skew(g_d) dTheta0 + R0 dg_d
        Rg = R0 @ g_d
        F[exP] += Rg
        F[ex0] -= Rg
        for D, dg in ((Fz, dg_z), (Fy, dg_y)):
            D[exP] += R0 @ dg[d_rows]
            D[ex0] -= R0 @ dg[d_rows]
        Fy[exP, cT0] -= R0 @ skew(g_d)
        Fy[ex0, cT0] += R0 @ skew(g_d)
        # H^T g_a on the node rotation rows: d(H^T g_a) = C eps + H^T dg_a, C = -g_a alpha^T + Q skew(g_a)/2
        f_a = Hp.T @ g_a
        C = -np.outer(g_a, kin.alpha[p]) + 0.5 * Qp @ skew(g_a)
        F[eTP] += f_a
        for D, dg in ((Fz, dg_z), (Fy, dg_y)):
            D[eTP] += Hp.T @ dg[a_rows]
        Fy[eTP, TP] += C
        Fy[eTP, cT0] -= C @ Qp.T
        # -(rho x g_d + Q H^T g_a) on the CM rotation rows: d rho = d d_P, d(Q f_a) = Q (skew(eps) f_a + df_a)
        F[eT0] -= np.cross(rho, g_d) + Qp @ f_a
        for D, dg in ((Fz, dg_z), (Fy, dg_y)):
            D[eT0] -= skew(rho) @ dg[d_rows] + Qp @ Hp.T @ dg[a_rows]
        Fy[eT0, cfg] += skew(g_d) @ Dq[d_rows]
        QC = Qp @ (C - skew(f_a))
        Fy[eT0, TP] -= QC
        Fy[eT0, cT0] += QC @ Qp.T
    return F, Fz, Fy
