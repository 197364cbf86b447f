"""Geometric stiffening inside a superelement (docs/equations.md, "Geometric stiffening").

Plain per-term functions, vectorized over the E superelements of a body, returning residual
contributions in a superelement's local rows and their derivatives with respect to the local
variables (q_bar, q_bar_dot, Omega0, Omega0_dot). They are the readable oracle of the C runtime
(runtime/native/superelement.c): runtime/equations.py adds them to g (eq. 78) and to the CM rotation
row (77) and chains the derivatives with Dq (eq. 91) exactly as it does for K q.

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


def inertia_change(q, W1, W2=None) -> np.ndarray:
    """J(q) - J0 = W1 q [+ q W2 q] (E, 3, 3), in superelement axes: Witteveen's change of the
    superelement's inertia tensor about its CM with its deformation (q (E, n), W1 (E, n, 3, 3),
    W2 (E, n, n, 3, 3) or None)."""
    Jq = np.einsum("ej,ejab->eab", q, W1)
    if W2 is not None:
        Jq = Jq + np.einsum("ej,ejlab,el->eab", q, W2, q)
    return Jq


def deformed_inertia(q, qd, Om, Omd, W1, jacobian: bool = True, W2=None):
    """Witteveen's deformation-dependent inertia J(q) = J0 + W1 q [+ q W2 q] in the two-field
    equations: the terms of T = 1/2 Om^T (W1 q [+ q W2 q]) Om beyond 1/2 Om^T J0 Om.

    q, qd (E, n) = q_bar, q_bar_dot; Om, Omd (E, 3) = Omega0, Omega0_dot; W1 (E, n, 3, 3);
    W2 (E, n, n, 3, 3) or None, W2[l, j] = W2[j, l]^T (docs/inertia-terms.md).
    With Z(w)[:, j] = W1_j w (3, n), Jq = W1 q [+ q W2 q] (3 x 3, symmetric), V_j = sum_l q_l (W2_jl + W2_lj):
        g = -dT/dq = -1/2 Z(Om)^T Om [- Kc(Om) q]     added to g (78); Kc_jl = Om^T W2_jl Om: the
                                                      elastic centrifugal force (softening)
        h = Jq Om                                     added to the angular momentum of (77): W0 x h
        e = Jq Omd + (dJq/dt) Om                      added to the CM rotation row (77),
                                                      dJq/dt = W1 qd [+ sum_j qd_j V_j]
        T (E,) the kinetic energy of these terms
    Returns (g, h, e, T, d), d the derivatives {"g_q", "g_Om", "h_q", "h_Om", "e_q", "e_qd", "e_Om",
    "e_Omd"} (E, rows, cols) or None.
    """
    Z = np.einsum("ejab,eb->eaj", W1, Om)  # (E, 3, n)
    Jq = inertia_change(q, W1, W2)  # (E, 3, 3), symmetric
    Jqd = np.einsum("ej,ejab->eab", qd, W1)
    g = -0.5 * np.einsum("eaj,ea->ej", Z, Om)
    if W2 is not None:
        W2q = np.einsum("ejlab,el->ejab", W2, q)  # sum_l q_l W2_jl
        V = W2q + np.einsum("eljab,el->ejab", W2, q)  # sum_l q_l (W2_jl + W2_lj), symmetric 3 x 3
        Jqd = Jqd + np.einsum("ej,ejab->eab", qd, V)
        Kc = np.einsum("ea,ejlab,eb->ejl", Om, W2, Om)
        g = g - np.einsum("ejl,el->ej", Kc, q)
    h = np.einsum("eab,eb->ea", Jq, Om)
    e = np.einsum("eab,eb->ea", Jq, Omd) + np.einsum("eab,eb->ea", Jqd, Om)
    T = 0.5 * np.einsum("ea,ea->e", h, Om)
    if not jacobian:
        return g, h, e, T, None
    ZT = np.swapaxes(Z, 1, 2)
    n = q.shape[1]
    d = {
        "g_q": np.zeros((q.shape[0], n, n)),
        "g_Om": -ZT,  # W1_j symmetric: d(1/2 Om^T W1_j Om)/dOm = (W1_j Om)^T
        "h_q": Z.copy(),
        "h_Om": Jq,
        "e_q": np.einsum("ejab,eb->eaj", W1, Omd),
        "e_qd": Z.copy(),
        "e_Om": Jqd,
        "e_Omd": Jq,
    }
    if W2 is not None:
        VOm = np.einsum("ejab,eb->eaj", V, Om)  # column j = V_j Om
        S = W2 + np.swapaxes(W2, 1, 2)  # S_ij = W2_ij + W2_ji = dV_i/dq_j
        d["g_q"] = -Kc
        d["g_Om"] = d["g_Om"] - np.einsum("ejab,eb->eja", V, Om)  # -(V_j Om)^T
        d["h_q"] += VOm
        d["e_q"] += np.einsum("ejab,eb->eaj", V, Omd) + np.einsum("ei,eijab,eb->eaj", qd, S, Om)
        d["e_qd"] += VOm
    return g, h, e, T, d


def gyroscopic_part_of_W2(G, M):
    """C_jl[a, b] = (G_a^T M^-1 G_b)[j, l] (E, n, n, 3, 3): the part of W2 that the gyroscopic terms
    already hold. With the independent velocity field, (79) makes r = qdot + M^-1 G(W0) q, so the
    elastic kinetic energy 1/2 r^T M r contains 1/2 q^T G^T M^-1 G q = 1/2 Omega^T (q C q) Omega: the
    centrifugal softening of the part of w x u that the basis spans (docs/inertia-terms.md, Bessel).
    The term set `full` adds only W2 - C on top of them (else the softening counts twice)."""
    MiG = np.linalg.solve(M[:, None], G)  # (E, 3, n, n): M^-1 G_b
    return np.einsum("eaij,ebik->ejkab", G, MiG)


def elastic_force(q, Om, W1, a=None, B=None, Dq=None, W2=None):
    """The contribution to the elastic force g (78), stacked on E: the membrane force f_vk(q) (when a,
    B are given: geometric stiffening) and -dT/dq of the deformation-dependent inertia (W1, W2).

    Returns (g (E, n), dg_z, dg_y) with derivative columns [configuration (nc) | velocities (nv)]
    (None without Dq): dg_y = (Kt - Kc) Dq on the configuration, dg/dOmega0 on the Omega0 columns;
    no rate dependence (dg_z = 0)."""
    jac = Dq is not None
    g, _, _, _, d = deformed_inertia(q, q, Om, Om, W1, jacobian=jac, W2=W2)
    Kt = None
    if a is not None:
        _, f, Kt = von_karman(q, a, B, tangent=jac)
        g = g + f
    if not jac:
        return g, None, None
    E, n, nc = Dq.shape
    nv = 6 + n
    Kq = d["g_q"] if Kt is None else d["g_q"] + Kt
    dg_y = np.zeros((E, n, nc + nv))
    dg_y[:, :, :nc] = Kq @ Dq
    dg_y[:, :, nc + 3 : nc + 6] = d["g_Om"]
    return g, np.zeros_like(dg_y), dg_y


def rotation_rows(q, qd, Om, Omd, W0, W1, nc: int, Dq=None, Dqdot=None, W2=None):
    """The deformation-dependent inertia on the CM rotation rows (77): W0 x (Jq Omega0) + Jq Omega0dot
    + (dJq/dt) Omega0, Jq = W1 q [+ q W2 q], as local rows [kinematic (nv) | dynamic (nc)], stacked on E.

    Returns (F (E, nv + nc), F_ydot, F_y) with columns [configuration/rates (nc) | velocities (nv)]
    (None, None without Dq)."""
    _, h, e, _, d = deformed_inertia(q, qd, Om, Omd, W1, jacobian=Dq is not None, W2=W2)
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


def plain_hooks(W1, a=None, B=None, W2=None):
    """(g_term, row_term) for runtime.equations.residual_and_jacobian: the terms above for ONE
    superelement, written on its Kinematics (the oracle's hook signature), from its W1 (n, 3, 3),
    [a (r, n), B (r, n, n): the membrane strain], [W2 (n, n, 3, 3)]."""
    W1 = W1[None]
    a, B = (None, None) if a is None else (a[None], B[None])
    W2 = None if W2 is None else W2[None]

    def g_term(se, kin, v, zdot, vdot):
        g, dz, dy = elastic_force(kin.q[None], v[None, 3:6], W1, a, B, kin.Dq[None], W2)
        return g[0], dz[0], dy[0]

    def row_term(se, kin, v, zdot, vdot):
        F, Fz, Fy = rotation_rows(kin.q[None], kin.qdot[None], v[None, 3:6], vdot[None, 3:6], zdot[None, 3:6], W1,
                                  kin.Dq.shape[1], kin.Dq[None], kin.Dqdot[None], W2)
        return F[0], Fz[0], Fy[0]

    return g_term, row_term
