"""RBE2 and RBE3 of a Nastran deck as constraints eliminated by a transformation (docs/nastran.md).

The dependent dofs D are expressed by independent ones, u_D = C u_I; with T the identity on every
other dof, rows D = C and zero columns at D, u = T u holds for every admissible u and the constrained
model is T^T K T, T^T M T on the same numbering (zero rows and columns at D: NastranFE.free_dofs
leaves D out, as it does the SPC dofs). No penalty: the constraint holds exactly.

RBE2 (GN, CM, GM_i): for each dependent GRID m at r = x_m - x_n from GN,
    u_m,c = (u_n + theta_n x r)_c for c in CM among 1, 2, 3;   theta_m,c = theta_n,c for c in CM among 4, 5, 6.
RBE3 (REFGRID, REFC, weight groups WT_k, C_k = 123, G_kj): the reference grid moves with the weighted
least-squares rigid fit of its independent grids' translations, (u, theta) minimizing
sum_j w_j |u_j - u - theta x r_j|^2 (r_j = x_j - x_ref): with B_j = [I, -r_j~],
    [u; theta] = A^-1 sum_j w_j B_j^T u_j,   A = sum_j w_j B_j^T B_j,
whose rows REFC are the dependent dofs; A needs three independent grids not on one line. A force on
the reference goes to the independent grids as T^T f: the same resultant and moment (static
equivalence, tests/test_nastran_continuum.py). Refused, by file and line: rotational independent
components (C_k with 4, 5, 6), UM dependent dofs, thermal ALPHA, a dependent dof that another rigid
element uses (chains) or that an SPC fixes.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .nastran_mass import skew

RIGID_CARDS = ("RBE2", "RBE3")


def rigid_elements(refuse, model, index, X, spc_dofs):
    """(T (6n, 6n) csr or None without rigid elements, dependent dofs): module doc."""
    rows = {}  # dependent dof -> (independent dofs, coefficients, card, eid)
    for eid, elem in sorted(model.rigid_elements.items()):
        if elem.type not in RIGID_CARDS:
            refuse(elem.type, eid, "rigid element not supported (RBE2, RBE3)")
        if getattr(elem, "alpha", 0.0):
            refuse(elem.type, eid, f"thermal expansion ALPHA = {elem.alpha} not supported")
        if elem.type == "RBE2":
            n = index[elem.gn]
            comps = [int(c) for c in str(elem.cm)]
            for g in elem.Gmi:
                m = index[g]
                B = np.concatenate([np.eye(3), -skew(X[m] - X[n])], axis=1)  # u_m = u_n + theta_n x r
                for c in comps:
                    coef = B[c - 1] if c <= 3 else np.eye(6)[c - 1]
                    rows.setdefault(6 * m + c - 1, []).append((6 * n + np.arange(6), coef, "RBE2", eid))
        else:
            if elem.Gmi or elem.Cmi:
                refuse("RBE3", eid, f"UM dependent dofs {elem.Gmi} not supported")
            ref = index[elem.refgrid]
            A, cols, blocks = np.zeros((6, 6)), [], []
            for w, comp, grids in zip(elem.weights, elem.comps, elem.Gijs):
                if str(comp) != "123":
                    refuse("RBE3", eid, f"independent components {comp}: only 123 (translations) supported")
                for g in grids:
                    B = np.concatenate([np.eye(3), -skew(X[index[g]] - X[ref])], axis=1)
                    A += w * B.T @ B
                    cols.append(6 * index[g] + np.arange(3))
                    blocks.append(w * B.T)
            if np.linalg.cond(A) > 1e10:
                refuse("RBE3", eid, "its independent grids do not fix a rigid motion (fewer than three, or "
                       "on one line)")
            C = np.linalg.solve(A, np.concatenate(blocks, axis=1))  # (6, 3 k)
            for c in (int(c) for c in str(elem.refc)):
                rows.setdefault(6 * ref + c - 1, []).append((np.concatenate(cols), C[c - 1], "RBE3", eid))
    if not rows:
        return None, np.zeros(0, dtype=int)
    dep = np.array(sorted(rows))
    for d, defs in rows.items():
        card, eid = defs[0][2], defs[0][3]
        if len(defs) > 1:
            refuse(card, eid, f"dof {d % 6 + 1} of GRID index {d // 6} is dependent in several rigid elements")
        if np.isin(defs[0][0][defs[0][1] != 0], dep).any():
            refuse(card, eid, "an independent dof is dependent in another rigid element (chain): not supported")
        if d in set(np.asarray(spc_dofs).tolist()):
            refuse(card, eid, f"dependent dof {d % 6 + 1} of GRID index {d // 6} is also fixed by an SPC")
    n6 = 6 * len(X)
    keep = np.setdiff1d(np.arange(n6), dep)
    r = [keep] + [np.full(len(rows[d][0][0]), d) for d in dep]
    c = [keep] + [rows[d][0][0] for d in dep]
    v = [np.ones(len(keep))] + [rows[d][0][1] for d in dep]
    T = sp.csr_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(n6, n6))
    T.eliminate_zeros()
    return T, dep
