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
