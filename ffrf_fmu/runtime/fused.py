"""The residual of all superelements evaluated at once, fused into few numpy calls: the numpy path's
evaluation (backend numpy, the reference run the C runtime is checked against; runtime/equations.py is
its plain twin and test oracle, one superelement at a time). It stays beside the C runtime because the
numpy path and the set-up use it where the C runtime has no entry point: the reference runs of the tests,
BodySystem.initialize (the rigid field's elastic rates, the static equilibrium of displaced ports) and
the linearizations of linear.py (frequencies, stability, the advisor); evaluated one superelement at a
time by the oracle instead, those would run about E times more numpy calls.

The body is small (E superelements of n ~ 20 dofs), so an evaluation costs numpy calls, not flops.
Everything is evaluated for all superelements at once: the per-node quantities of (89) and (91) as
stacked 3 x 3 products, then every term linear in the local vector
    u = [q_bar, qdot_bar, r_bar, rdot_bar, x0dot, W0, v0, Omega0, v0dot, Omega0dot, 1]
(k_x, k_T, k_q, m v0dot, J0 Omega0dot, e_eta, g_B) by ONE matmul with a constant operator L made of
K_bar, M_bar, J0, m; then the bilinear rest (R0 g_d, H^T g_alpha, Q H^T g_alpha, rho x g_d,
W0 x h) as stacked products; and the assembly with the loads as one bincount. The analytic
Jacobian blocks (`local_jacobian`) follow docs/equations.md, all boundary nodes at once.

Names (docs/equations.md): Q = R0^T R_P, H = H(Q) the tangent of vect, rho = X_P + d_P,
g = [g_d, g_alpha per node; g_eta] the elastic force (78), h the angular momentum J0 Omega0 [+ s].

Over 400 lines: one class whose evaluation and Jacobian templates are built together from the same index
arrays (gathers, scatters); split, both halves would rebuild them.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .layout import Layout, Segments, SuperelementStack, view
from .rotation import _CROSS, skew, vect, vect_tangent


class FusedResidual:
    """Buffers, index maps and constant operators of the fused evaluation of one body.

    `buf` (a namespace of views into two persistent flat buffers) is written by the caller:
    `buf.p` (configuration in the ydot layout, rotation slots holding the increments h Delta),
    `buf.yd` (rates), `buf.load` (-f, -R^T t on node rows), `buf.weight` (-m g on CM rows); `torque`
    is -t on the nodes (N, 1, 3) when a torque input is non-zero, else None.

    Hooks for further terms (the fused twins of runtime/equations.py's `g_terms`, `row_terms`), each a
    function term(s, D) -> (value, d/d rates, d/d configuration) over all superelements at once: s is
    the dict of stacked intermediates of `evaluate` (R0, Q, H, rho, alpha, W0, q, qd (q_bar_dot),
    rb (r_bar), rbd (r_bar_dot), ...), D None when only the value is needed (the derivatives may then
    be None), else {"Dq": dq_bar/d(configuration) = dq_bar_dot/d(zdot), "Dqdot": dq_bar_dot/d(configuration)},
    each (E, n, nc). Derivative columns are local [configuration (nc) | velocities (nv)].
    A `g_terms` value (E, n) adds to the elastic force g (78) before its projection (91) on the CM and
    node rows; a `row_terms` value (E, nv + nc) adds to the local rows [kinematic | dynamic] directly.
    """

    def __init__(self, layout: Layout, stack: SuperelementStack, inertia_coupling: bool, coriolis: bool, g_terms=(),
                 row_terms=(), D=None):
        """inertia_coupling, coriolis: the two parts of the gyroscopic terms (docs/inertia-terms.md, switches):
        the inertia coupling s = S(q) r (55) in the angular momentum of (77), and the elastic Coriolis
        G(W0) (53) in (78)-(79). The term set `gyroscopic` has both. D (E, n, n): the structural damping
        (runtime/damping.py), D q_bar_dot added to g (78), or None."""
        self.layout, self.inertia_coupling, self.coriolis = layout, inertia_coupling, coriolis
        self.D = D
        self._G_terms = inertia_coupling or coriolis  # G_k q, G_k r: read by either part
        self.g_terms, self.row_terms = tuple(g_terms), tuple(row_terms)
        self.K, self.M, self.G, self.mass, self.J0, self.X_B = stack.K, stack.M, stack.G, stack.mass, stack.J0, stack.X_B
        self.se_nodes = stack.nodes
        self.torque = None
        self._build_evaluation()
        self._build_jacobian_templates()

    # ------------------------------------------------------- evaluation setup
    def _build_evaluation(self):
        """Index maps, constant operators, buffers and their views for the residual evaluation (`evaluate`).

        Everything the residual reads is gathered from ONE flat source vector
            src = [p (ny) | ydot (ny) | 1 | HB (E, nb, [H | alpha | -Q^T]) | NB (E, nb, [d | d_dot | alpha_dot])]
        with p the configuration in the ydot layout (node and CM positions, eta, velocities v; the
        rotation slots hold the increments h Delta) and HB, NB the per-node quantities of eq. (89)/(91)
        written by `evaluate`. Everything the residual writes goes into ONE flat vector W whose
        entries each carry a global row (a dummy row ny for intermediates): F = bincount(rows, W).
        The buffers persist, so every view of them is made once, here (namespace `buf`).
        """
        L = self.layout
        E, N, nb, nm, n, ny = L.n_se, L.n_nodes, L.nb, L.nm, L.n, L.ny
        nodes = self.se_nodes
        node_x = 6 * np.arange(N)[:, None] + np.arange(3)
        node_T = node_x + 3
        cfg, vel = L.cfg_map, L.vel_map  # (E, nc): [x0, Theta0, eta, node p (x, Theta)], (E, nv): [v0, Omega0, r]
        se_x, se_T, se_eta = cfg[:, 0:3], cfg[:, 3:6], cfg[:, 6 : 6 + nm]
        self.rot_slots = np.concatenate([node_T, se_T])  # (N + E, 3) == L.rot_cols: nodes then SEs
        # linear configuration slots, in the order of concat(xN, x0, eta, v)
        self.lin_slots = np.concatenate([node_x.ravel(), se_x.ravel(), se_eta.ravel(), vel.ravel()])
        lin = Segments(xN=(N, 3), x0=(E, 3), eta=(E, nm), v=vel.shape)
        self.lin_views = [(lin[k], lin.shapes[k]) for k in ("xN", "x0", "eta", "v")]
        b = self.buf = SimpleNamespace()

        # ---- source vector
        hb = Segments(H=(3, 3), alpha=3, mQT=(3, 3))
        nbk = Segments(d=3, dd=3, ad=3)
        s = Segments(p=ny, yd=ny, one=1, HB=(E, nb, hb.size), NB=(E, nb, nbk.size))
        b.src = np.zeros(s.size)
        b.src[s["one"]] = 1.0
        b.p, b.yd = b.src[s["p"]], b.src[s["yd"]]
        HB, NB = s.view(b.src, "HB"), s.view(b.src, "NB")
        b.HB2 = view(HB, (E * nb, hb.size))
        b.H, b.alpha, b.mQT = hb.view(HB, "H"), hb.view(HB, "alpha"), hb.view(HB, "mQT")
        b.d, b.dd = nbk.view(NB, "d"), nbk.view(NB, "dd")
        b.ad_col = nbk.view(NB, "ad")[..., None]
        YD, ONE = s["yd"].start, s["one"].start

        def src_index(region, segs, seg, e, p):
            base = s[region].start + (e * nb + p) * segs.size
            return base + np.arange(segs[seg].start, segs[seg].stop)

        # ---- per node p of SE e: S = [R_P^T (3 rows), x_P - x0, xdot_P - x0dot] (world); T = R0^T S
        b.S = np.zeros((E, nb, 5, 3))
        b.S_RT, b.S_X, b.S2 = b.S[:, :, 0:3], b.S[:, :, 3:5], b.S.reshape(E, 5 * nb, 3)
        xP = node_x[nodes]  # (E, nb, 3)
        x0b = np.broadcast_to(se_x[:, None, :], xP.shape)
        self._X_idx = np.stack([np.stack([xP, YD + xP], 2), np.stack([x0b, YD + x0b], 2)])  # (2, E, nb, 2, 3)
        self._W_idx = YD + np.concatenate([se_T[:, None, :], node_T[nodes]], axis=1)  # (E, 1 + nb, 3): W0, W_P
        b.T = np.zeros((E, nb, 5, 3))  # rows Q^T, rho = X_P + d_P, R0^T (xdot_P - x0dot)
        b.T2, b.QT_rho = b.T.reshape(E, 5 * nb, 3), b.T[:, :, 0:4]
        b.QT, b.rho, b.ru = b.T[:, :, 0:3], b.T[:, :, 3], b.T[:, :, 4]
        b.QT2 = view(b.QT, (E * nb, 9))
        # QT.ravel() @ _vect_op = [H(Q), vect(Q), -Q^T] (all linear in Q: rotation.vect_tangent, rotation.vect)
        basis_Q = np.swapaxes(np.eye(9).reshape(9, 3, 3), -1, -2)  # Q of each unit QT.ravel()
        self._vect_op = np.concatenate([vect_tangent(basis_Q).reshape(9, 9), vect(basis_Q), -np.eye(9)], axis=1)
        # [Q^T; rho^T] [skew(W0) | W0]: Q^T W0 in the last column, (rho x W0)^T in the rho row
        b.W0_hat = np.zeros((E, 1, 3, 4))
        b.W0_hat_flat = view(b.W0_hat, (E, 12))
        self._W0_hat_op = np.stack([np.concatenate([skew(e), e[:, None]], axis=1).ravel() for e in np.eye(3)])
        b.TW = np.zeros((E, nb, 4, 4))
        b.QTW0, b.rhoxW0 = b.TW[:, :, 0:3, 3], b.TW[:, :, 3, 0:3]
        b.c = np.zeros((E, nb, 3))  # W_P - Q^T W0
        b.c_col = b.c[..., None]

        # ---- u: the local vector of each SE that the linear operator acts on
        u = self._u = Segments(
            q=n, qd=n, rb=n, rbd=n, x0d=3, W0=3, v0=3, Om0=3, v0d=3, Om0d=3, one=1,
            **({"Gq": n, "Gr": n, "s": 3, "sdot": 3} if self._G_terms else {}),
        )
        uidx = np.full((E, u.size), ONE)
        for e in range(E):
            for p in range(nb):  # q_B of node p: d, alpha; qdot_B: d_dot, alpha_dot
                q0, qd0 = u["q"].start + 6 * p, u["qd"].start + 6 * p
                uidx[e, q0 : q0 + 3] = src_index("NB", nbk, "d", e, p)
                uidx[e, q0 + 3 : q0 + 6] = src_index("HB", hb, "alpha", e, p)
                uidx[e, qd0 : qd0 + 3] = src_index("NB", nbk, "dd", e, p)
                uidx[e, qd0 + 3 : qd0 + 6] = src_index("NB", nbk, "ad", e, p)
        uidx[:, u["q"].start + 6 * nb : u["q"].stop] = se_eta
        uidx[:, u["qd"].start + 6 * nb : u["qd"].stop] = YD + se_eta
        uidx[:, u["rb"]], uidx[:, u["rbd"]] = vel[:, 6:], YD + vel[:, 6:]
        uidx[:, u["x0d"]], uidx[:, u["W0"]] = YD + se_x, YD + se_T
        uidx[:, u["v0"]], uidx[:, u["Om0"]] = vel[:, 0:3], vel[:, 3:6]
        uidx[:, u["v0d"]], uidx[:, u["Om0d"]] = YD + vel[:, 0:3], YD + vel[:, 3:6]
        self._u_idx = uidx

        # ---- O = u @ L (the constant linear operator): the residual rows linear in u, then g_B and the operands of the cross products
        o = self._o = Segments(
            kx=3, kT=3, kq=n, ex0=3, eT0=3, eeta=nm,
            gd=(nb, 3), mgd=(nb, 3), h_ang=3, rho=(nb, 3), W0=3, ga=(nb, 3),
        )
        L_op = np.zeros((E, u.size, o.size))
        I3 = np.eye(3)
        d_rows = (6 * np.arange(nb)[:, None] + np.arange(3)).ravel()  # rows of q_bar: d of every node
        a_rows = d_rows + 3
        col = np.arange(3 * nb)
        gsel = np.zeros((n, o.size))  # g (n) -> its blocks in O: e_eta, g_d, -g_d, g_alpha
        gsel[6 * nb :, o["eeta"]] = np.eye(nm)
        gsel[d_rows, o["gd"].start + col] = 1.0
        gsel[d_rows, o["mgd"].start + col] = -1.0
        gsel[a_rows, o["ga"].start + col] = 1.0
        self._g_to_O = gsel
        self._local_rows = np.concatenate([L.vel_map, L.cfg_map], axis=1).ravel()  # local row -> global row
        for e in range(E):
            Le = L_op[e]
            Le[u["x0d"], o["kx"]], Le[u["v0"], o["kx"]] = I3, -I3  # (69b)
            Le[u["W0"], o["kT"]], Le[u["Om0"], o["kT"]] = I3, -I3  # (69d)
            Le[u["qd"], o["kq"]], Le[u["rb"], o["kq"]] = self.M[e].T, -self.M[e].T  # (79)
            Le[u["q"]] += self.K[e].T @ gsel  # g = K q + M rdot (78)
            Le[u["rbd"]] += self.M[e].T @ gsel
            if self.D is not None:  # + D q_bar_dot, the structural damping on the co-rotated rates (91)
                Le[u["qd"]] += self.D[e].T @ gsel
            Le[u["v0d"], o["ex0"]] = self.mass[e] * I3  # (69a): m v0dot (- m g: the `weight` block of W)
            Le[u["Om0d"], o["eT0"]] = self.J0[e].T  # (77): J0 Omega0dot
            Le[u["Om0"], o["h_ang"]] = self.J0[e].T  # h = J0 Omega0 [+ s]
            Le[u["q"].start + d_rows, o["rho"].start + col] = 1.0  # rho_P = X_P + d_P
            Le[u["one"], o["rho"]] = self.X_B[e].ravel()
            Le[u["W0"], o["W0"]] = I3
            if self.coriolis:
                Le[u["Gq"], o["kq"]] = np.eye(n)  # + G(W0) q
                Le[u["Gr"]] += gsel  # g + G(W0) r
            if self.inertia_coupling:
                Le[u["s"], o["h_ang"]] = I3
                Le[u["sdot"], o["eT0"]] = I3
        # SEs with bitwise-equal data share one operator: one 2D matmul instead of a per-SE stack
        self._linear_op = L_op[0].copy() if all(np.array_equal(L_op[0], Le) for Le in L_op) else L_op

        # ---- W: everything the residual adds into global rows
        w = Segments(O=(E, o.size), Fd=(E, 2 * nb, 3), Fa=(E, nb, 1, 3), QFa=(E, nb, 1, 3),
                      cross=(E, nb + 1, 3, 1), weight=(E, 3), load=(N, 2, 3))
        b.W = np.zeros(w.size)
        b.WO = w.view(b.W, "O")
        b.WO3 = b.WO[:, None, :]
        b.gd, b.ga, b.h_ang = o.view(b.WO, "gd"), o.view(b.WO, "ga"), o.view(b.WO, "h_ang")
        b.gd_mgd = view(b.WO[:, o["gd"].start : o["mgd"].stop], (E, 2 * nb, 3))  # [g_d; -g_d]
        b.ga_row = b.ga[:, :, None, :]
        # cross products -(a x b) of a = [-g_d, h], b = [rho, W0] (rows of O): (a outer b).ravel() @ -_CROSS
        a = view(b.WO[:, o["mgd"].start : o["h_ang"].stop], (E, nb + 1, 3, 1))
        c = view(b.WO[:, o["rho"].start : o["W0"].stop], (E, nb + 1, 1, 3))
        b.cross_a, b.cross_b = a, c
        b.outer = np.zeros((E, nb + 1, 3, 3))
        b.outer2 = b.outer.reshape(E * (nb + 1), 9)
        self._mCROSS = -_CROSS
        b.Fd, b.Fa, b.QFa = w.view(b.W, "Fd"), w.view(b.W, "Fa"), w.view(b.W, "QFa")
        b.cross = view(w.view(b.W, "cross"), (E * (nb + 1), 3))
        b.load = w.view(b.W, "load")  # (N, 2, 3): -f, -R^T t
        b.load_t = b.load[:, 1:2]
        b.weight = w.view(b.W, "weight")  # -m g on the CM translation rows
        wrows = np.full(w.size, ny)  # dummy row ny for intermediates
        Orows = np.full((E, o.size), ny)
        Orows[:, o["kx"]], Orows[:, o["kT"]], Orows[:, o["kq"]] = vel[:, 0:3], vel[:, 3:6], vel[:, 6:]
        Orows[:, o["ex0"]], Orows[:, o["eT0"]], Orows[:, o["eeta"]] = se_x, se_T, se_eta
        wrows[w["O"]] = Orows.ravel()
        node_cfg = cfg[:, 6 + nm :].reshape(E, nb, 2, 3)  # node p: x rows, Theta rows
        wrows[w["Fd"]] = np.concatenate([node_cfg[:, :, 0], np.repeat(se_x[:, None], nb, 1)], axis=1).ravel()
        wrows[w["Fa"]] = node_cfg[:, :, 1].ravel()
        wrows[w["QFa"]] = np.repeat(se_T[:, None], nb, 1).ravel()
        wrows[w["cross"]] = np.repeat(se_T[:, None], nb + 1, 1).ravel()
        wrows[w["weight"]] = se_x.ravel()
        wrows[w["load"]] = np.arange(6 * N)
        self._W_rows = wrows

    def _build_jacobian_templates(self):
        """Constant entries of the local Jacobian stacks and the (row, column) index pairs of the
        per-node blocks that sit on node-specific columns (`local_jacobian`)."""
        L = self.layout
        E, nb, nm, n, nc, nv = L.n_se, L.nb, L.nm, L.n, L.nc, L.nv
        V, I3 = nc, np.eye(3)
        vr = slice(V + 6, V + 6 + n)
        FF = np.zeros((2, E, nv + nc, nc + nv))  # [F_y, F_ydot]
        FF[1, :, 0:3, 0:3], FF[0, :, 0:3, V : V + 3] = I3, -I3  # x0dot - v0
        FF[1, :, 3:6, 3:6], FF[0, :, 3:6, V + 3 : V + 6] = I3, -I3  # W0 - Omega0
        FF[0, :, 6 : 6 + n, vr] = -self.M  # k_q = M (q_dot - r)
        FF[1, :, nv : nv + 3, V : V + 3] = self.mass[:, None, None] * I3  # m v0dot
        FF[1, :, nv + 3 : nv + 6, V + 3 : V + 6] = self.J0  # J0 Omega0dot
        dg = np.zeros((2, E, n, nc + nv))  # [dg_y, dg_z]
        dg[1, :, :, vr] = self.M  # M rdot
        self._jac_FF0, self._jac_dg0 = FF, dg

        def pairs(row0, col0):  # (rows, cols) of the 3 x 3 block of every node p, C order (p, i, j)
            p, i, j = np.meshgrid(np.arange(nb), np.arange(3), np.arange(3), indexing="ij")
            return (row0(p) + i).ravel(), (col0(p) + j).ravel()

        xP, TP = (lambda p: 6 + nm + 6 * p), (lambda p: 6 + nm + 6 * p + 3)  # node columns
        self._jac_idx = {
            "d_xP": pairs(lambda p: 6 * p, xP),  # d_P rows, x_P columns
            "a_TP": pairs(lambda p: 6 * p + 3, TP),  # alpha_P rows, Theta_P columns
            "T_TP": pairs(lambda p: nv + 6 + nm + 6 * p + 3, TP),  # node Theta rows, Theta_P columns
            "T0_TP": pairs(lambda p: nv + 3 + 0 * p, TP),  # e_T0 rows, Theta_P columns
        }

    def evaluate(self, R, jacobian: bool = False):
        """Residual of the assembled equations (loads included) at the configuration in the source
        vector (p, ydot; see `_build_evaluation`) and the rotation stack R (nodes then SEs).

        Returns F (ny,) and, on request (else None), the dict of intermediates `local_jacobian` needs.
        Row forms throughout: for stacks of row vectors, x @ R = R^T x and x @ R^T = R x.
        """
        b, N = self.buf, self.layout.n_nodes
        src = b.src
        R0 = R[N:]
        b.S_RT[...] = np.swapaxes(R[self.se_nodes], -1, -2)  # R_P^T
        X = src[self._X_idx]
        np.subtract(X[0], X[1], out=b.S_X)  # x_P - x0, xdot_P - x0dot
        np.matmul(b.S2, R0, out=b.T2)  # R0^T S: Q^T = R_P^T R0, rho, R0^T (xdot_P - x0dot)
        np.dot(b.QT2, self._vect_op, out=b.HB2)  # H(Q), alpha = vect(Q), -Q^T
        np.subtract(b.rho, self.X_B, out=b.d)  # d_P (89)
        # q_dot of eq. (91) at the rates: d_dot = R0^T (xdot_P - x0dot) + rho x W0, alpha_dot = H (W_P - Q^T W0)
        Wg = src[self._W_idx]
        W0, WP = Wg[:, 0], Wg[:, 1:]
        np.dot(W0, self._W0_hat_op, out=b.W0_hat_flat)
        np.matmul(b.QT_rho, b.W0_hat, out=b.TW)
        np.add(b.ru, b.rhoxW0, out=b.dd)
        np.subtract(WP, b.QTW0, out=b.c)
        np.matmul(b.H, b.c_col, out=b.ad_col)
        # every term linear in u = [q, qdot, r, rdot, x0dot, W0, v0, Omega0, v0dot, Omega0dot, 1]: kinematic
        # rows (69b, 69d, 79), m v0dot, J0 Omega0dot, e_eta and g_B = K q + M rdot (78), h = J0 Omega0, rho
        u = src[self._u_idx]
        if self._G_terms:
            gy = self._gyroscopic(u, W0, jacobian)
        if self._linear_op.ndim == 2:
            np.dot(u, self._linear_op, out=b.WO)
        else:
            np.matmul(u[:, None, :], self._linear_op, out=b.WO3)
        s = None
        if jacobian or self.g_terms or self.row_terms:
            s = self._intermediates(R0, W0, u, gy if self._G_terms else None)
        for term in self.g_terms:  # further elastic forces: into g's blocks before the projection (91)
            b.WO += term(s, None)[0] @ self._g_to_O
        # g_B to the CM and the nodes (91): R0 g_d on node and (minus) CM rows, H^T g_alpha on node rows,
        # -Q H^T g_alpha, -rho x g_d and W0 x h on the CM rotation rows (77)
        np.matmul(b.gd_mgd, np.swapaxes(R0, -1, -2), out=b.Fd)
        np.matmul(b.ga_row, b.H, out=b.Fa)
        np.matmul(b.Fa, b.mQT, out=b.QFa)
        np.multiply(b.cross_a, b.cross_b, out=b.outer)
        np.dot(b.outer2, self._mCROSS, out=b.cross)
        if self.torque is not None:  # -R^T t on the nodes
            np.matmul(self.torque, R[:N], out=b.load_t)
        F = np.bincount(self._W_rows, b.W, minlength=self.layout.ny + 1)[:-1]
        for term in self.row_terms:
            F += np.bincount(self._local_rows, term(s, None)[0].ravel(), minlength=self.layout.ny)
        return F, s

    def _intermediates(self, R0, W0, u, gy):
        """The stacked quantities of eqs. (89), (91) and the evaluation that the Jacobian and the term
        hooks read (views of the buffers: g_d, g_alpha, h hold their final values once F is done)."""
        b, us = self.buf, self._u
        s = {
            "R0": R0, "R0T": np.swapaxes(R0, -1, -2), "Q": np.swapaxes(b.QT, -1, -2), "QT": b.QT, "H": b.H,
            "rho": b.rho, "alpha": b.alpha, "W0": W0, "c": b.c, "ru": b.ru, "gd": b.gd, "ga": b.ga,
            "Fa": b.Fa[:, :, 0], "h_ang": b.h_ang, "QTW0": b.QTW0,
            "q": us.view(u, "q"), "qd": us.view(u, "qd"), "rb": us.view(u, "rb"), "rbd": us.view(u, "rbd"),
            "Om0": us.view(u, "Om0"), "Om0d": us.view(u, "Om0d"),
        }
        if gy is not None:
            s.update(gy)
        return s

    def _gyroscopic(self, u, W0, jacobian):
        """The `gyroscopic` terms, written into u: G(W0) q, G(W0) r, s (55) and sdot (Remark 6 drops them)."""
        us = self._u
        q, qd, rb, rbd = us.view(u, "q"), us.view(u, "qd"), us.view(u, "rb"), us.view(u, "rbd")
        Gq = np.einsum("ekij,ej->eik", self.G, q)  # (E, n, 3): column k = G_k q
        Gr = np.einsum("ekij,ej->eik", self.G, rb)
        us.view(u, "Gq")[...] = (Gq @ W0[..., None])[..., 0]  # G(W0) q = sum_k W0_k G_k q
        us.view(u, "Gr")[...] = (Gr @ W0[..., None])[..., 0]
        us.view(u, "s")[...] = np.einsum("ei,eik->ek", rb, Gq)  # s_k = r^T G_k q
        us.view(u, "sdot")[...] = np.einsum("ei,eik->ek", rbd, Gq) - np.einsum("ei,eik->ek", qd, Gr)
        out = {"Gq": Gq, "Gr": Gr}
        if jacobian:
            out["Gw"] = np.einsum("ek,ekij->eij", W0, self.G)
        return out

    def local_jacobian(self, s):
        """Analytic derivatives of `_local` (the algebra is spelled out in docs/equations.md), for all
        boundary nodes at once. F_y and F_ydot are one stack FF = [F_y, F_ydot], the derivatives of g
        one stack dg = [dg_y, dg_z], wherever both get the same projection; per-node blocks of
        matrices are views (SE, node p, part d / alpha or x / Theta, 3 rows, columns)."""
        L = self.layout
        E, nb, nm, n, nc, nv = L.n_se, L.nb, L.nm, L.n, L.nc, L.nv
        R0, R0T, Q, QT, H, rho, alpha = s["R0"], s["R0T"], s["Q"], s["QT"], s["H"], s["rho"], s["alpha"]
        W0, c, ru, gd, ga, Fa = s["W0"], s["c"], s["ru"], s["gd"], s["ga"], s["Fa"]
        K, M, ix = self.K, self.M, self._jac_idx
        ncv, nB = nc + nv, 6 * nb
        cx0, cT0, ceta = slice(0, 3), slice(3, 6), slice(6, 6 + nm)

        # Dq: derivative of q_bar w.r.t. local configuration (= derivative of q_dot_bar w.r.t. zdot)
        # Dqd: derivative of q_dot_bar w.r.t. configuration at fixed zdot; DD = [Dqd, Dq]
        DD = np.zeros((2, E, n, nc))
        Dqd, Dq = DD[0], DD[1]
        DqB, DqdB = view(Dq[:, :nB], (E, nb, 2, 3, nc)), view(Dqd[:, :nB], (E, nb, 2, 3, nc))
        W0x = skew(W0)
        B = -c[..., :, None] * alpha[..., None, :] - 0.5 * skew((c[..., None, :] @ Q)[..., 0, :]) - H @ skew(s["QTW0"])
        DqB[:, :, 0, :, cx0] = -R0T[:, None]  # d_P: -R0^T dx0 + skew(rho) dTheta0 + R0^T dx_P
        DqB[:, :, 0, :, cT0] = skew(rho)
        Dq[:, ix["d_xP"][0], ix["d_xP"][1]] = np.broadcast_to(R0T[:, None], (E, nb, 3, 3)).reshape(E, -1)
        DqB[:, :, 1, :, cT0] = -H @ QT  # alpha_P: H (dTheta_P - Q^T dTheta0)
        Dq[:, ix["a_TP"][0], ix["a_TP"][1]] = H.reshape(E, -1)
        Dq[:, nB:, ceta] = np.eye(nm)
        DqdB[:, :, 0] = -W0x[:, None] @ DqB[:, :, 0]
        DqdB[:, :, 0, :, cT0] += skew(ru)
        Dqd[:, ix["a_TP"][0], ix["a_TP"][1]] = B.reshape(E, -1)
        DqdB[:, :, 1, :, cT0] = -B @ QT

        V = nc  # offset of velocity columns
        vr = slice(V + 6, V + 6 + n)  # r_bar columns
        # constant entries (kinematic rows, m v0dot, J0 Omega0dot, -M r, M rdot): templates built once
        FF = self._jac_FF0.copy()  # [F_y w.r.t. (configuration, velocity), F_ydot w.r.t. (zdot, vdot)]
        dg = self._jac_dg0.copy()  # g = K q + M rdot [+ G(W0) r]: derivatives kept apart, projected below
        Fy, Fz = FF[0], FF[1]
        kr = slice(6, 6 + n)
        FF[:, :, kr, :nc] = M @ DD  # k_q = M (q_dot - r)
        dg[0, :, :, :nc] = K @ Dq
        if self.D is not None:  # D q_bar_dot: D Dqdot on the configuration, D Dq on the rates
            dg[:, :, :, :nc] += self.D[None] @ DD
        if self.coriolis:
            Gw, Gq, Gr = s["Gw"], s["Gq"], s["Gr"]
            Fz[:, kr, cT0] += Gq
            Fy[:, kr, :nc] += Gw @ Dq
            dg[1, :, :, cT0] += Gr
            dg[0, :, :, vr] += Gw
        # dynamic rows
        ox0, oT0, oeta = nv, nv + 3, nv + 6
        onode = nv + 6 + nm
        # W0 x h_ang: d/dW0 = -skew(h_ang); d/dOmega0 = skew(W0) J0
        Fz[:, oT0 : oT0 + 3, cT0] -= skew(s["h_ang"])
        Fy[:, oT0 : oT0 + 3, V + 3 : V + 6] += W0x @ self.J0
        if self.inertia_coupling:
            Gq, Gr = s["Gq"], s["Gr"]
            rbd, qd = s["rbd"], s["qd"]
            Grd = np.einsum("ekij,ej->eik", self.G, rbd)
            GqdT = np.einsum("ekij,ej->eik", self.G, qd)
            GqT = np.swapaxes(Gq, 1, 2)  # (E, 3, n): row k = (G_k q)^T
            # s = (G_k q)^T r: ds/dr = Gq^T, ds/dq = -(G_k r)^T
            ds_dq = -np.swapaxes(Gr, 1, 2)
            Fy[:, oT0 : oT0 + 3, vr] += W0x @ GqT
            Fy[:, oT0 : oT0 + 3, :nc] += W0x @ ds_dq @ Dq
            # sdot = rdot^T G q + r^T G qdot
            Fz[:, oT0 : oT0 + 3, vr] += GqT
            Fy[:, oT0 : oT0 + 3, :nc] += -np.swapaxes(Grd, 1, 2) @ Dq
            Fy[:, oT0 : oT0 + 3, vr] += np.swapaxes(GqdT, 1, 2)
            dsd_dqd = -np.swapaxes(Gr, 1, 2)
            Fz[:, oT0 : oT0 + 3, :nc] += dsd_dqd @ Dq
            Fy[:, oT0 : oT0 + 3, :nc] += dsd_dqd @ Dqd
        D = {"Dq": Dq, "Dqdot": Dqd}
        for term in self.g_terms:
            _, dg_z, dg_y = term(s, D)
            dg[1] += dg_z
            dg[0] += dg_y
        FF[:, :, oeta : oeta + nm] = dg[:, :, nB:]
        # g_B through (91), every node p at once: rows of node p (x, Theta) and dg_d, dg_alpha of node p
        FFN = view(FF[:, :, onode:], (2, E, nb, 2, 3, ncv))
        dgB = view(dg[:, :, :nB], (2, E, nb, 2, 3, ncv))
        # e_x0 -= R0 g_d, node x rows += R0 g_d;  d(R0 g_d) = -R0 skew(g_d) dTheta0 + R0 dg_d
        Yd = R0[:, None] @ dgB[:, :, :, 0]
        FFN[:, :, :, 0] += Yd
        FF[:, :, ox0 : ox0 + 3] -= Yd.sum(2)
        Sgd = skew(gd)
        R0Sg = R0[:, None] @ Sgd
        Fy[:, ox0 : ox0 + 3, cT0] += R0Sg.sum(1)
        FyN = FFN[0]
        FyN[:, :, 0, :, cT0] -= R0Sg
        # node Theta rows += H^T g_a;  d(H^T g_a) = C eps + H^T dg_a, C = -g_a alpha^T + Q skew(g_a) / 2,
        # eps = dTheta_P - Q^T dTheta0
        C = -ga[..., :, None] * alpha[..., None, :] + 0.5 * Q @ skew(ga)
        Ya = np.swapaxes(H, -1, -2) @ dgB[:, :, :, 1]
        FFN[:, :, :, 1] += Ya
        Fy[:, ix["T_TP"][0], ix["T_TP"][1]] += C.reshape(E, -1)
        FyN[:, :, 1, :, cT0] -= C @ QT
        # e_T0 -= rho x g_d + Q H^T g_a;  d rho = d d;  d(Q Fa) = -Q skew(Fa) eps + Q d(Fa)
        FF[:, :, oT0 : oT0 + 3] -= (skew(rho) @ dgB[:, :, :, 0] + Q @ Ya).sum(2)
        Fy[:, oT0 : oT0 + 3, :nc] += (Sgd @ DqB[:, :, 0]).sum(1)
        QC = Q @ (C - skew(Fa))
        Fy[:, ix["T0_TP"][0], ix["T0_TP"][1]] -= QC.reshape(E, -1)
        Fy[:, oT0 : oT0 + 3, cT0] += (QC @ QT).sum(1)
        for term in self.row_terms:
            _, dF_z, dF_y = term(s, D)
            Fz += dF_z
            Fy += dF_y
        return Fz, Fy

