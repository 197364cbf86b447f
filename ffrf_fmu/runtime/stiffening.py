"""Geometric stiffening inside a superelement (docs/equations.md, "Geometric stiffening").

Plain per-term functions, vectorized over the E superelements of a body, returning residual
contributions in a superelement's local rows and their derivatives with respect to the local
variables (q_bar, q_bar_dot, Omega0, Omega0_dot). They are the readable oracle of the body kernel:
`system.py` adds them to g (eq. 78) and to the CM rotation row (77) and chains the derivatives with
Dq (eq. 91) exactly as it does for K q.

Two terms, both from a potential or a kinetic energy, so both enter the energy balance:

1. Second-order (von Karman) membrane strain of the superelement's own deformation, in the r axial
   strain shapes its basis holds (assumed strain: the projection that avoids membrane locking,
   reduction.stiffening_data):
       eps_k = a_k q + 1/2 q^T B_k q        (k = 1..r, E^T W E = I coordinates)
       V2(q) = a.sigma + 1/2 sigma.sigma,   a = a q, sigma_k = 1/2 q^T B_k q
   (the membrane energy 1/2 |a + sigma|^2 beyond the linear 1/2 |a|^2 that K holds). Its gradient
   carries the geometric stiffness sum_k (a + sigma)_k B_k: the axial force of the superelement's
   own stretch times the bending slopes.
2. The inertia tensor's first-order change J(q) = J0 + sum_j q_j W1_j (Witteveen's I0 + W1 q):
       T1 = 1/2 Omega0^T (W1 q) Omega0,
   whose q-derivative is the constant centrifugal load f0_j = 1/2 Omega0^T W1_j Omega0 that
   stretches the superelement about its own CM (into the static correction mode of the reduction),
   and whose Omega0-derivative adds (W1 q) Omega0 to the angular momentum of (77).
"""
from __future__ import annotations

import numpy as np

from .rotation import skew


def von_karman(q: np.ndarray, a: np.ndarray, B: np.ndarray, tangent: bool = True):
    """Second-order membrane energy V2, its gradient and (on request) its Hessian.

    q (E, n), a (E, r, n), B (E, r, n, n) symmetric. With e = a q, Bq_k = B_k q, sigma_k = q.Bq_k / 2:
        V2 = e.sigma + sigma.sigma / 2
        f  = dV2/dq  = a^T sigma + Bq^T (e + sigma)
        Kt = d2V2/dq2 = a^T Bq + Bq^T a + Bq^T Bq + sum_k (e + sigma)_k B_k
    Returns V2 (E,), f (E, n), Kt (E, n, n) or None.
    """
    e = np.einsum("ekn,en->ek", a, q)
    Bq = np.einsum("ekmn,en->ekm", B, q)  # (E, r, n)
    sigma = 0.5 * np.einsum("ekm,em->ek", Bq, q)
    N = e + sigma
    V2 = np.einsum("ek,ek->e", e + 0.5 * sigma, sigma)
    f = np.einsum("ekn,ek->en", a, sigma) + np.einsum("ekn,ek->en", Bq, N)
    if not tangent:
        return V2, f, None
    aT, BqT = np.swapaxes(a, 1, 2), np.swapaxes(Bq, 1, 2)
    Kt = aT @ Bq + BqT @ (a + Bq) + np.einsum("ek,ekmn->emn", N, B)
    return V2, f, Kt


def deformed_inertia(q, qd, Om, Omd, W1, jacobian: bool = True):
    """The W1 terms of T1 = 1/2 Om^T (W1 q) Om in the two-field equations of one superelement.

    q, qd (E, n) = q_bar, q_bar_dot; Om, Omd (E, 3) = Omega0, Omega0_dot; W1 (E, n, 3, 3).
    Returns (g, h, e, T1, d):
        g = -f0 = -1/2 Z(Om)^T Om       added to g (78)          Z(w)[:, j] = W1_j w  (3, n)
        h = (W1 q) Om = Z(Om) q          added to the angular momentum J0 Om (77): W0 x h
        e = (W1 q) Omd + (W1 qd) Om      added to the CM rotation row (77): d/dt of h without W0 x
        T1 (E,) kinetic energy of the term
        d: derivatives {"g_Om", "h_q", "h_Om", "e_q", "e_qd", "e_Om", "e_Omd"} (E, rows, cols)
    """
    Z = np.einsum("ejab,eb->eaj", W1, Om)  # (E, 3, n)
    Jq = np.einsum("ej,ejab->eab", q, W1)  # W1 q (E, 3, 3), symmetric
    Jqd = np.einsum("ej,ejab->eab", qd, W1)
    h = np.einsum("eaj,ej->ea", Z, q)
    g = -0.5 * np.einsum("eaj,ea->ej", Z, Om)
    e = np.einsum("eab,eb->ea", Jq, Omd) + np.einsum("eaj,ej->ea", Z, qd)
    T1 = 0.5 * np.einsum("ea,ea->e", h, Om)
    if not jacobian:
        return g, h, e, T1, None
    ZT = np.swapaxes(Z, 1, 2)
    d = {
        "g_Om": -ZT,  # W1_j symmetric: d(1/2 Om^T W1_j Om)/dOm = (W1_j Om)^T
        "h_q": Z,
        "h_Om": Jq,
        "e_q": np.einsum("ejab,eb->eaj", W1, Omd),
        "e_qd": Z,
        "e_Om": Jqd,
        "e_Omd": Jq,
    }
    return g, h, e, T1, d


def elastic_force(q, Om, W1, a, B, Dq=None):
    """The stiffening contribution to the elastic force g (78): f_vk(q) - f0(Omega0), stacked on E.

    Returns (g (E, n), dg_z, dg_y) with derivative columns [configuration (nc) | velocities (nv)]
    (None without Dq): dg_y = Kt Dq on the configuration, -Z(Omega0)^T on the Omega0 columns; no rate
    dependence (dg_z = 0)."""
    _, f, Kt = von_karman(q, a, B, tangent=Dq is not None)
    g, _, _, _, d = deformed_inertia(q, q, Om, Om, W1, jacobian=Dq is not None)
    if Dq is None:
        return f + g, None, None
    E, n, nc = Dq.shape
    nv = 6 + n
    dg_y = np.zeros((E, n, nc + nv))
    dg_y[:, :, :nc] = Kt @ Dq
    dg_y[:, :, nc + 3 : nc + 6] = d["g_Om"]
    return f + g, np.zeros_like(dg_y), dg_y


def rotation_rows(q, qd, Om, Omd, W0, W1, nc: int, Dq=None, Dqdot=None):
    """The W1 terms on the CM rotation rows (77): W0 x ((W1 q) Omega0) + (W1 q) Omega0dot + (W1 qdot) Omega0,
    as local rows [kinematic (nv) | dynamic (nc)], stacked on E.

    Returns (F (E, nv + nc), F_ydot, F_y) with columns [configuration/rates (nc) | velocities (nv)]
    (None, None without Dq)."""
    _, h, e, _, d = deformed_inertia(q, qd, Om, Omd, W1, jacobian=Dq is not None)
    E, n = q.shape
    nv = 6 + n
    rows = slice(nv + 3, nv + 6)
    F = np.zeros((E, nv + nc))
    F[:, rows] = np.cross(W0, h) + e
    if Dq is None:
        return F, None, None
    Fz, Fy = np.zeros((2, E, nv + nc, nc + nv))
    W0x = skew(W0)
    Fz[:, rows, 3:6] = -skew(h)  # d(W0 x h)/dW0
    Fz[:, rows, :nc] += d["e_qd"] @ Dq
    Fz[:, rows, nc + 3 : nc + 6] = d["e_Omd"]
    Fy[:, rows, :nc] = (W0x @ d["h_q"] + d["e_q"]) @ Dq + d["e_qd"] @ Dqdot
    Fy[:, rows, nc + 3 : nc + 6] = W0x @ d["h_Om"] + d["e_Om"]
    return F, Fz, Fy


def fused_hooks(W1, a, B, nc: int):
    """(g_term, row_term) for runtime.fused.FusedResidual: the stiffening terms over all superelements
    from the stacked reduced data W1 (E, n, 3, 3), a (E, r, n), B (E, r, n, n)."""

    def g_term(s, D):
        return elastic_force(s["q"], s["Om0"], W1, a, B, None if D is None else D["Dq"])

    def row_term(s, D):
        if D is None:
            return rotation_rows(s["q"], s["qd"], s["Om0"], s["Om0d"], s["W0"], W1, nc)
        return rotation_rows(s["q"], s["qd"], s["Om0"], s["Om0d"], s["W0"], W1, nc, D["Dq"], D["Dqdot"])

    return g_term, row_term


def plain_hooks(sd):
    """(g_term, row_term) for runtime.equations.residual_and_jacobian: the same terms for ONE
    superelement (SuperelementData sd), written on its Kinematics (the oracle's hook signature)."""
    W1, a, B = sd.W1[None], sd.vk_a[None], sd.vk_B[None]

    def g_term(se, kin, v, zdot, vdot):
        g, dz, dy = elastic_force(kin.q[None], v[None, 3:6], W1, a, B, kin.Dq[None])
        return g[0], dz[0], dy[0]

    def row_term(se, kin, v, zdot, vdot):
        F, Fz, Fy = rotation_rows(kin.q[None], kin.qdot[None], v[None, 3:6], vdot[None, 3:6], zdot[None, 3:6], W1,
                                  kin.Dq.shape[1], kin.Dq[None], kin.Dqdot[None])
        return F[0], Fz[0], Fy[0]

    return g_term, row_term
