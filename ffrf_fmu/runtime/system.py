"""A flexible body: a chain of two-field superelements joined by spatial coordinates, and its
Lie-group generalized-alpha integrator (formulation.md sections 3-5; geradin eqs. 69, 77-80, 89-91).

Unknowns
    per boundary node P:   frame w_P = (x_P, R_P) (world position, rotation)         [spatial coordinates]
    per superelement e:    CM frame (x0, R0), modal amplitudes eta                    [configuration]
                           velocities v0 (world), Omega0 (body), r_bar = [r_B; r_eta] [independent field]
The elastic boundary dofs are not unknowns: eq. (89) gives them from the frames,
    d_P = R0^T (x_P - x0) - X_P,    alpha_P = vect(R0^T R_P),
with `vect` the skew-part axial vector of the paper (exact tangent H(Q), rotation.vect_tangent).

Configuration rates zdot = (xdot, W) with W = R^T Rdot (body axes), and etadot.
Residual of one superelement (local rows: kinematic then dynamic):
    k_x   = x0dot - v0                                        (69b)
    k_T   = W0 - Omega0                                       (69d)
    k_q   = M_bar (qdot_bar - r_bar) [+ G(W0) q_bar]          (79)
    g     = K_bar q_bar + M_bar rdot_bar [+ G(W0) r_bar]      (78), f_e = 0 (see below)
    e_x0  = m v0dot - m g_grav + (dq_B/dx0)^T g_B             (69a) with (91)
    e_T0  = J0 Omega0dot + W0 x (J0 Omega0 [+ s]) [+ sdot] + (dq_B/dTheta0)^T g_B   (77) with (91)
    e_eta = g_eta
    e_P   = (dq_B/dw_P)^T g_B, summed over the superelements sharing P, minus the load on P
with s = S(q_bar) r_bar, s_k = r_bar^T G_k q_bar (55), G(W) = sum_k W_k G_k (53). Terms in [] belong
to the `gyroscopic` term set only; `linear` is Remark 6 (72a-c). Uniform gravity does no work on
the elastic field: Y^T M U = 0 (74) makes f_e and the q-dependent part of C0 vanish, so gravity is
m g on each CM.

Integrator: first-order generalized-alpha (Jansen-Whiting-Hulbert) in the linear multistep form of
Bruls & Arnold (2008), equations enforced at t_{n+1}:
    am a_{n+1} + (1 - am) a_n = af ydot_{n+1} + (1 - af) ydot_n
    y_{n+1} = y_n (+) h [(1 - gamma) a_n + gamma a_{n+1}]      (R <- R exp(h Delta) on SO(3))
    F(ydot_{n+1}, y_{n+1}, t_{n+1}) = 0
am = (3 - rho)/(2 (1 + rho)), af = 1/(1 + rho), gamma = 1/2 + am - af. Newton on ydot_{n+1}
with the analytic iteration matrix F_ydot + beta [F_y T, F_v], beta = h gamma af / am, T the SO(3)
tangent operator; the factorization is kept across iterations and steps while Newton contracts.

Evaluation: the body is small (E superelements of n ~ 20 dofs), so a step costs numpy calls, not
flops, and the code is organized to make few of them (`_build_evaluation`, `_evaluate`). Within a
step, a_{n+1} and the configuration are affine in ydot_{n+1}: p = beta ydot + P0 for positions,
eta and v, R = R_n exp(beta W + ...) for rotations (`_prepare_step` computes P0 and R_n once). The
residual of all superelements is evaluated at once: the per-node quantities of (89) and (91) as
stacked 3 x 3 products, then every term linear in the local vector
u = [q, qdot, r, rdot, x0dot, W0, v0, Omega0, v0dot, Omega0dot, 1] (k_x, k_T, k_q, m v0dot,
J0 Omega0dot, e_eta, g_B) by ONE matmul with a constant operator made of K_bar, M_bar, J0, m, the
bilinear rest (R0 g_d, H^T g_alpha, Q H^T g_alpha, rho x g_d, W0 x h) as stacked products, and the
assembly with the loads as one bincount.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Callable

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dgetrs as getrs

from .data import BodyData
from .ports import PortValues, StepFailure
from .rotation import _CROSS, cross, expm, is_rotation, skew, tangent, vect, vect_tangent

TERM_SETS = ("linear", "gyroscopic")


def alpha_coefficients(rho_inf: float) -> tuple[float, float, float]:
    """(am, af, gamma) of the first-order generalized-alpha method (JWH 2000) from rho_inf."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf))
    af = 1.0 / (1.0 + rho_inf)
    return am, af, 0.5 + am - af


@dataclass(frozen=True, eq=False)
class Layout:
    """Where each unknown lives in the global vector ydot = [node zdot (6N) | SE zdot (6+nm)E | SE v (nv)E]."""

    n_nodes: int
    n_se: int
    nb: int
    nm: int
    n: int  # reduced dofs per SE: 6 nb + nm
    nc: int  # local configuration-shaped size: 6 + nm + 6 nb
    nv: int  # local velocity size: 6 + n
    ny: int
    cfg_map: np.ndarray  # (E, nc) local [x0, Theta0, eta, node p (x, Theta)...] -> global
    vel_map: np.ndarray  # (E, nv)
    free: np.ndarray  # (ny,) bool: unknown (not prescribed by a motion input)
    rot_cols: np.ndarray  # (n_rot, 3) global columns of every rotation rate (nodes then SEs)

    @classmethod
    def of(cls, data: BodyData) -> "Layout":
        ses = data.superelements
        E, N = len(ses), len(data.node_positions)
        nb = len(ses[0].nodes)
        nm = ses[0].n - 6 * nb
        if any(se.n != ses[0].n or len(se.nodes) != nb for se in ses):
            raise ValueError("all superelements of a body must have the same boundary and mode counts")
        n, nc, nv = 6 * nb + nm, 6 + nm + 6 * nb, 6 + 6 * nb + nm
        se_cfg0 = 6 * N + np.arange(E) * (6 + nm)
        vel0 = 6 * N + E * (6 + nm) + np.arange(E) * nv
        nodes = np.array([se.nodes for se in ses], dtype=int)
        cfg_map = np.concatenate(
            [se_cfg0[:, None] + np.arange(6 + nm), (6 * nodes[:, :, None] + np.arange(6)).reshape(E, 6 * nb)], axis=1
        )
        vel_map = vel0[:, None] + np.arange(nv)
        ny = 6 * N + E * (6 + nm) + E * nv
        free = np.ones(ny, dtype=bool)
        for p in data.ports:
            if p.translation == "motion":
                free[6 * p.node : 6 * p.node + 3] = False
            if p.rotation == "motion":
                free[6 * p.node + 3 : 6 * p.node + 6] = False
        rot_cols = np.concatenate([6 * np.arange(N)[:, None] + 3 + np.arange(3), se_cfg0[:, None] + 3 + np.arange(3)])
        return cls(N, E, nb, nm, n, nc, nv, ny, cfg_map, vel_map, free, rot_cols)


def _input(values: PortValues, field: str, port: str, t: float) -> np.ndarray:
    """One input array of a port, checked: present, the right shape, finite."""
    val = getattr(values, field)
    if val is None:
        raise StepFailure(t, f"port {port!r}: input {field} is missing")
    val = np.asarray(val, dtype=float)
    shape = (3, 3) if field == "R" else (3,)
    if val.shape != shape or not np.isfinite(val).all():
        raise StepFailure(t, f"port {port!r}: input {field} is not a finite array of shape {shape}: {val!r}")
    return val


def _view(a: np.ndarray, shape) -> np.ndarray:
    """a reshaped WITHOUT a copy (writes through the result must reach a); raises if impossible."""
    v = a.reshape(shape)
    if not np.may_share_memory(v, a):
        raise ValueError(f"internal: reshaping {a.shape} to {shape} would copy")
    return v


class _Segments:
    """Named consecutive blocks of a flat vector, e.g. _Segments(q=18, rho=(2, 3)): `seg["rho"]` is
    the slice, `seg.view(a, "rho")` the block of a (..., size) array as a (..., 2, 3) view."""

    def __init__(self, **shapes):
        self.slices, self.shapes, i = {}, {}, 0
        for name, shape in shapes.items():
            shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
            size = int(np.prod(shape))
            self.slices[name], self.shapes[name] = slice(i, i + size), shape
            i += size
        self.size = i

    def __getitem__(self, name: str) -> slice:
        return self.slices[name]

    def view(self, a: np.ndarray, name: str) -> np.ndarray:
        return _view(a[..., self.slices[name]], a.shape[:-1] + self.shapes[name])


def _value(values: PortValues, field: str, port: str, t: float) -> np.ndarray:
    """An input array as given when it already is a float array of the right shape (its finiteness is
    checked later, for all inputs at once), else through the full check of `_input`."""
    val = getattr(values, field)
    if type(val) is np.ndarray and val.dtype == np.float64 and val.shape == ((3, 3) if field == "R" else (3,)):
        return val
    return _input(values, field, port, t)


def _zero_or_nan(x: np.ndarray, zeros: np.ndarray) -> float:
    """0.0 if every entry of x is finite, NaN otherwise (0 * x is 0 for finite x, NaN for inf or NaN;
    one dot product, cheaper than isfinite().all() on the hot path)."""
    return float(x @ zeros)


class BodySystem:
    """One flexible body and its integrator state. Instances share nothing (FMU-safe)."""

    def __init__(
        self,
        data: BodyData,
        *,
        terms: str = "linear",
        rho_inf: float = 0.8,
        gravity=(0.0, 0.0, 0.0),
        tol: float = 1e-9,
        max_iter: int = 25,
    ):
        if terms not in TERM_SETS:
            raise ValueError(f"unknown term set {terms!r}; choose one of {TERM_SETS}")
        self.data, self.terms, self.rho_inf = data, terms, float(rho_inf)
        self.coefficients = alpha_coefficients(self.rho_inf)
        self.gravity = np.asarray(gravity, dtype=float)
        self.tol, self.max_iter = tol, max_iter
        self.layout = L = Layout.of(data)
        ses = data.superelements
        self.K = np.stack([se.K for se in ses])
        self.M = np.stack([se.M for se in ses])
        self.G = np.stack([se.G for se in ses])  # (E, 3, n, n)
        self.mass = np.array([se.mass for se in ses])
        self.J0 = np.stack([se.J0 for se in ses])
        self.X_B = np.stack([se.X_B for se in ses])
        self.se_nodes = np.stack([se.nodes for se in ses]).astype(int)
        self.gyro = terms == "gyroscopic"
        # global (row, col) index pairs of every local Jacobian entry, for one scatter-add
        rows = np.concatenate([L.vel_map, L.cfg_map], axis=1)
        cols = np.concatenate([L.cfg_map, L.vel_map], axis=1)
        self._rows, self._cols = rows, cols
        self._flat_idx = (rows[:, :, None] * L.ny + cols[:, None, :]).ravel()
        self._free_idx = np.flatnonzero(L.free)
        self._fixed_idx = np.flatnonzero(~L.free)  # rates prescribed by motion inputs (node rows only)
        self._lu = None
        # world-axes triplets among the unknowns: node positions, CM positions, CM velocities
        world = np.zeros(L.ny, dtype=bool)
        world[(6 * np.arange(L.n_nodes)[:, None] + np.arange(3)).ravel()] = True
        world[L.cfg_map[:, 0:3].ravel()] = True
        world[L.vel_map[:, 0:3].ravel()] = True
        pos = np.cumsum(L.free) - 1  # index of each unknown among the free ones
        trip = pos[np.flatnonzero(world & L.free)].reshape(-1, 3)
        self._world_free = trip
        # Newton unknowns ordered world triplets first, so that the frame rotation of `_solve` acts on
        # one contiguous block; the stored factorization uses this order
        rest = np.setdiff1d(np.arange(self._free_idx.size), trip.ravel())
        self._newton_order = np.concatenate([trip.ravel(), rest])
        self._newton_idx = self._free_idx[self._newton_order]
        # every local Jacobian entry -> flat position in the Newton-ordered matrix (nf * nf: not an unknown)
        nf = self._newton_idx.size
        newton_pos = np.full(L.ny + 1, nf)
        newton_pos[self._newton_idx] = np.arange(nf)
        r, c = newton_pos[rows][:, :, None], newton_pos[cols][:, None, :]
        self._newton_flat = np.where((r < nf) & (c < nf), r * nf + c, nf * nf).ravel()
        self._newton_pos = newton_pos[: L.ny]
        self._torque_rows = [(k, newton_pos[6 * k + 3 : 6 * k + 6]) for k in range(L.n_nodes) if L.free[6 * k + 3]]
        self._motion_x = np.array([p.node for p in data.ports if p.translation == "motion"], dtype=int)
        self._motion_R = np.array([p.node for p in data.ports if p.rotation == "motion"], dtype=int)
        self._build_evaluation()
        self.t = 0.0
        self.iterations = 0
        self._reset_reference()

    # ------------------------------------------------------- evaluation setup
    def _build_evaluation(self):
        """Index maps, constant operators, buffers and their views for the residual evaluation (`_evaluate`).

        Everything the residual reads is gathered from ONE flat source vector
            src = [p (ny) | ydot (ny) | 1 | HB (E, nb, [H | alpha | -Q^T]) | NB (E, nb, [d | d_dot | alpha_dot])]
        with p the configuration in the ydot layout (node and CM positions, eta, velocities v; the
        rotation slots hold the increments h Delta) and HB, NB the per-node quantities of eq. (89)/(91)
        written by `_evaluate`. Everything the residual writes goes into ONE flat vector W whose
        entries each carry a global row (a dummy row ny for intermediates): F = bincount(rows, W).
        The buffers persist, so every view of them is made once, here (namespace self._b).
        """
        L = self.layout
        E, N, nb, nm, n, ny = L.n_se, L.n_nodes, L.nb, L.nm, L.n, L.ny
        nodes = self.se_nodes
        node_x = 6 * np.arange(N)[:, None] + np.arange(3)
        node_T = node_x + 3
        cfg, vel = L.cfg_map, L.vel_map  # (E, nc): [x0, Theta0, eta, node p (x, Theta)], (E, nv): [v0, Omega0, r]
        se_x, se_T, se_eta = cfg[:, 0:3], cfg[:, 3:6], cfg[:, 6 : 6 + nm]
        self._rot_slots = np.concatenate([node_T, se_T])  # (N + E, 3) == L.rot_cols: nodes then SEs
        # linear configuration slots, in the order of concat(xN, x0, eta, v)
        self._lin_slots = np.concatenate([node_x.ravel(), se_x.ravel(), se_eta.ravel(), vel.ravel()])
        lin = _Segments(xN=(N, 3), x0=(E, 3), eta=(E, nm), v=vel.shape)
        self._lin_views = [(lin[k], lin.shapes[k]) for k in ("xN", "x0", "eta", "v")]
        # stage: p = c * ydot + P0 with c = beta except on configuration slots set by motion inputs
        self._motion_x_slots = node_x[self._motion_x].ravel()
        self._motion_T_slots = node_T[self._motion_R].ravel()
        self._stage_mask = np.ones(ny)
        self._stage_mask[self._motion_x_slots] = 0.0
        self._stage_mask[self._motion_T_slots] = 0.0
        b = self._b = SimpleNamespace()

        # ---- source vector
        hb = _Segments(H=(3, 3), alpha=3, mQT=(3, 3))
        nbk = _Segments(d=3, dd=3, ad=3)
        s = _Segments(p=ny, yd=ny, one=1, HB=(E, nb, hb.size), NB=(E, nb, nbk.size))
        b.src = np.zeros(s.size)
        b.src[s["one"]] = 1.0
        b.p, b.yd = b.src[s["p"]], b.src[s["yd"]]
        HB, NB = s.view(b.src, "HB"), s.view(b.src, "NB")
        b.HB2 = _view(HB, (E * nb, hb.size))
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
        b.T2, b.T4 = b.T.reshape(E, 5 * nb, 3), b.T[:, :, 0:4]
        b.QT, b.rho, b.ru = b.T[:, :, 0:3], b.T[:, :, 3], b.T[:, :, 4]
        b.QT2 = _view(b.QT, (E * nb, 9))
        # QT.ravel() @ _HA = [H(Q), vect(Q), -Q^T] (all linear in Q: rotation.vect_tangent, rotation.vect)
        basis_Q = np.swapaxes(np.eye(9).reshape(9, 3, 3), -1, -2)  # Q of each unit QT.ravel()
        self._HA = np.concatenate([vect_tangent(basis_Q).reshape(9, 9), vect(basis_Q), -np.eye(9)], axis=1)
        # [Q^T; rho^T] [skew(W0) | W0]: Q^T W0 in the last column, (rho x W0)^T in the rho row
        b.Wop = np.zeros((E, 1, 3, 4))
        b.Wop12 = _view(b.Wop, (E, 12))
        self._SKW = np.stack([np.concatenate([skew(e), e[:, None]], axis=1).ravel() for e in np.eye(3)])
        b.TW = np.zeros((E, nb, 4, 4))
        b.QTW0, b.rhoxW0 = b.TW[:, :, 0:3, 3], b.TW[:, :, 3, 0:3]
        b.c = np.zeros((E, nb, 3))  # W_P - Q^T W0
        b.c_col = b.c[..., None]

        # ---- u: the local vector of each SE that the linear operator acts on
        u = self._u = _Segments(
            q=n, qd=n, rb=n, rbd=n, x0d=3, W0=3, v0=3, Om0=3, v0d=3, Om0d=3, one=1,
            **({"Gq": n, "Gr": n, "s": 3, "sdot": 3} if self.gyro else {}),
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

        # ---- O = u @ Lop: the residual rows linear in u, then g_B and the operands of the cross products
        o = self._o = _Segments(
            kx=3, kT=3, kq=n, ex0=3, eT0=3, eeta=nm,
            gd=(nb, 3), mgd=(nb, 3), h_ang=3, rho=(nb, 3), W0=3, ga=(nb, 3),
        )
        Lop = np.zeros((E, u.size, o.size))
        I3 = np.eye(3)
        d_rows = (6 * np.arange(nb)[:, None] + np.arange(3)).ravel()  # rows of q_bar: d of every node
        a_rows = d_rows + 3
        col = np.arange(3 * nb)
        gsel = np.zeros((n, o.size))  # g (n) -> its blocks in O: e_eta, g_d, -g_d, g_alpha
        gsel[6 * nb :, o["eeta"]] = np.eye(nm)
        gsel[d_rows, o["gd"].start + col] = 1.0
        gsel[d_rows, o["mgd"].start + col] = -1.0
        gsel[a_rows, o["ga"].start + col] = 1.0
        for e in range(E):
            Le = Lop[e]
            Le[u["x0d"], o["kx"]], Le[u["v0"], o["kx"]] = I3, -I3  # (69b)
            Le[u["W0"], o["kT"]], Le[u["Om0"], o["kT"]] = I3, -I3  # (69d)
            Le[u["qd"], o["kq"]], Le[u["rb"], o["kq"]] = self.M[e].T, -self.M[e].T  # (79)
            Le[u["q"]] += self.K[e].T @ gsel  # g = K q + M rdot (78)
            Le[u["rbd"]] += self.M[e].T @ gsel
            Le[u["v0d"], o["ex0"]] = self.mass[e] * I3  # (69a): m v0dot (- m g: the `weight` block of W)
            Le[u["Om0d"], o["eT0"]] = self.J0[e].T  # (77): J0 Omega0dot
            Le[u["Om0"], o["h_ang"]] = self.J0[e].T  # h = J0 Omega0 [+ s]
            Le[u["q"].start + d_rows, o["rho"].start + col] = 1.0  # rho_P = X_P + d_P
            Le[u["one"], o["rho"]] = self.X_B[e].ravel()
            Le[u["W0"], o["W0"]] = I3
            if self.gyro:
                Le[u["Gq"], o["kq"]] = np.eye(n)  # + G(W0) q
                Le[u["Gr"]] += gsel  # g + G(W0) r
                Le[u["s"], o["h_ang"]] = I3
                Le[u["sdot"], o["eT0"]] = I3
        # SEs with bitwise-equal data share one operator: one 2D matmul instead of a per-SE stack
        self._Lop = Lop[0].copy() if all(np.array_equal(Lop[0], Le) for Le in Lop) else Lop

        # ---- W: everything the residual adds into global rows
        w = _Segments(O=(E, o.size), Fd=(E, 2 * nb, 3), Fa=(E, nb, 1, 3), QFa=(E, nb, 1, 3),
                      cross=(E, nb + 1, 3, 1), weight=(E, 3), load=(N, 2, 3))
        b.W = np.zeros(w.size)
        b.WO = w.view(b.W, "O")
        b.WO3 = b.WO[:, None, :]
        b.gd, b.ga, b.h_ang = o.view(b.WO, "gd"), o.view(b.WO, "ga"), o.view(b.WO, "h_ang")
        b.gd_mgd = _view(b.WO[:, o["gd"].start : o["mgd"].stop], (E, 2 * nb, 3))  # [g_d; -g_d]
        b.ga_row = b.ga[:, :, None, :]
        # cross products -(a x b) of a = [-g_d, h], b = [rho, W0] (rows of O): (a outer b).ravel() @ -_CROSS
        a = _view(b.WO[:, o["mgd"].start : o["h_ang"].stop], (E, nb + 1, 3, 1))
        c = _view(b.WO[:, o["rho"].start : o["W0"].stop], (E, nb + 1, 1, 3))
        b.cross_a, b.cross_b = a, c
        b.outer = np.zeros((E, nb + 1, 3, 3))
        b.outer2 = b.outer.reshape(E * (nb + 1), 9)
        self._mCROSS = -_CROSS
        b.Fd, b.Fa, b.QFa = w.view(b.W, "Fd"), w.view(b.W, "Fa"), w.view(b.W, "QFa")
        b.cross = _view(w.view(b.W, "cross"), (E * (nb + 1), 3))
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
        self._zeros_ny = np.zeros(ny)
        self._minus_mass = -self.mass[:, None]
        self._motion_parts = (~L.free[: 6 * N]).reshape(N, 2, 3).astype(float)  # 1 on motion-driven node dofs
        self._port_nodes = np.array([p.node for p in self.data.ports], dtype=int)
        # energies: [v0, Omega0, r, q] of each SE with blockdiag(m I, J0, M, K), then 1/2 the sums per part
        nv = L.nv
        self._energy_op = np.zeros((E, nv + n, nv + n))
        for e in range(E):
            self._energy_op[e, 0:3, 0:3] = self.mass[e] * np.eye(3)
            self._energy_op[e, 3:6, 3:6] = self.J0[e]
            self._energy_op[e, 6:nv, 6:nv] = self.M[e]
            self._energy_op[e, nv:, nv:] = self.K[e]
        self._energy_split = np.zeros((nv + n, 3))
        self._energy_split[0:6, 0], self._energy_split[6:nv, 1], self._energy_split[nv:, 2] = 0.5, 0.5, 0.5
        self._stage_beta = None
        # input buffer of `_read_inputs`: [xN (N, 3) | RN (N, 3, 3) | zN (N, 6) | f (N, 3) | t (N, 3)]
        inp = _Segments(xN=(N, 3), RN=(N, 3, 3), zN=(N, 6), f=(N, 3), t=(N, 3))
        self._input_views = [(inp[k], inp.shapes[k]) for k in ("xN", "RN", "zN", "f", "t")]
        self._zeros_inputs = np.zeros(inp.size - inp["zN"].start)
        self._zeros_input_buf = np.zeros(inp.size)
        self._torque = None  # -t on the nodes (N, 1, 3) when a torque input is non-zero
        self._build_jacobian_templates()

    def _build_jacobian_templates(self):
        """Constant entries of the local Jacobian stacks and the (row, column) index pairs of the
        per-node blocks that sit on node-specific columns (`_local_jacobian`)."""
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

    # ------------------------------------------------------------------ state
    def _reset_reference(self):
        L, d = self.layout, self.data
        self.xN = np.array(d.node_positions, dtype=float)
        self.RN = np.repeat(np.eye(3)[None], L.n_nodes, axis=0)
        self.x0 = np.stack([se.x_cm for se in d.superelements]).astype(float)
        self.R0 = np.repeat(np.eye(3)[None], L.n_se, axis=0)
        self.eta = np.zeros((L.n_se, L.nm))
        self.v = np.zeros((L.n_se, L.nv))
        self.yd = np.zeros(L.ny)
        self.yd_prev = np.zeros(L.ny)
        self.a = np.zeros(L.ny)
        self.fN = np.zeros((L.n_nodes, 3))  # force on each boundary node (load or reaction), world
        self.tN = np.zeros((L.n_nodes, 3))
        self.work = 0.0
        self.power = 0.0

    _STATE_FIELDS = ("xN", "RN", "x0", "R0", "eta", "v", "yd", "yd_prev", "a", "fN", "tN")

    def get_state(self) -> np.ndarray:
        """Flat copy of everything the next step depends on, the Newton iteration matrix included
        (modified Newton reuses it, so a restored state must continue with the same one to give
        bit-identical steps)."""
        parts = [np.ravel(getattr(self, k)) for k in self._STATE_FIELDS]
        scalars = np.array([self.t, self.work, self.power, self.iterations, self._lu is not None])
        if self._lu is not None:
            lu, piv, beta, R_ref = self._lu
            parts += [lu.ravel(), piv.astype(float), [beta], R_ref.ravel()]
        return np.concatenate([scalars] + parts)

    def set_state(self, state: np.ndarray) -> None:
        state = np.asarray(state, dtype=float)
        n = self._free_idx.size
        sizes = [getattr(self, k).size for k in self._STATE_FIELDS]
        expected = 5 + sum(sizes) + (n * n + n + 10 if state.size > 4 and state[4] else 0)
        if state.size != expected:
            raise ValueError(f"state has {state.size} entries, this body needs {expected}")
        self.t, self.work, self.power = state[0], state[1], state[2]
        self.iterations, has_lu = int(state[3]), bool(state[4])
        i = 5
        for k, size in zip(self._STATE_FIELDS, sizes):
            setattr(self, k, state[i : i + size].reshape(getattr(self, k).shape).copy())
            i += size
        self._lu = None
        if has_lu:
            lu = np.asfortranarray(state[i : i + n * n].reshape(n, n))
            piv = state[i + n * n : i + n * n + n].astype(np.int32)
            beta, R_ref = state[i + n * n + n], state[i + n * n + n + 1 :].reshape(3, 3).copy()
            self._lu = (lu, piv, beta, R_ref)

    # ------------------------------------------------------------- equations
    def _split_cfg_rates(self, yd):
        """Global ydot -> node (N, 6) rates, SE (E, 6 + nm) rates, SE (E, nv) velocity rates."""
        L = self.layout
        nN, nS = 6 * L.n_nodes, L.n_se * (6 + L.nm)
        return yd[:nN].reshape(L.n_nodes, 6), yd[nN : nN + nS].reshape(L.n_se, 6 + L.nm), yd[nN + nS :].reshape(L.n_se, L.nv)

    def _elastic(self, xP, RP, x0, R0T, eta):
        """q_bar of eq. (89): d_P = R0^T (x_P - x0) - X_P, alpha_P = vect(R0^T R_P), then eta.
        Matmul forms used throughout: (x @ R) = R^T x and (x @ R^T) = R x for stacks of row vectors."""
        rho = (xP - x0[:, None]) @ np.swapaxes(R0T, -1, -2)  # X_P + d_P
        Q = R0T[:, None] @ RP  # R0^T R_P
        alpha = vect(Q)
        E = len(x0)
        q = np.concatenate([np.concatenate([rho - self.X_B, alpha], axis=2).reshape(E, -1), eta], axis=1)
        return q, rho, Q, alpha

    def _evaluate(self, R, jacobian: bool = False):
        """Residual of the assembled equations (loads included) at the configuration in the source
        vector (p, ydot; see `_build_evaluation`) and the rotation stack R (nodes then SEs).

        Returns F (ny,) and, on request, the dict of intermediates `_local_jacobian` needs.
        Row forms throughout: for stacks of row vectors, x @ R = R^T x and x @ R^T = R x.
        """
        b, N = self._b, self.layout.n_nodes
        src = b.src
        R0 = R[N:]
        b.S_RT[...] = np.swapaxes(R[self.se_nodes], -1, -2)  # R_P^T
        X = src[self._X_idx]
        np.subtract(X[0], X[1], out=b.S_X)  # x_P - x0, xdot_P - x0dot
        np.matmul(b.S2, R0, out=b.T2)  # R0^T S: Q^T = R_P^T R0, rho, R0^T (xdot_P - x0dot)
        np.dot(b.QT2, self._HA, out=b.HB2)  # H(Q), alpha = vect(Q), -Q^T
        np.subtract(b.rho, self.X_B, out=b.d)  # d_P (89)
        # q_dot of eq. (91) at the rates: d_dot = R0^T (xdot_P - x0dot) + rho x W0, alpha_dot = H (W_P - Q^T W0)
        Wg = src[self._W_idx]
        W0, WP = Wg[:, 0], Wg[:, 1:]
        np.dot(W0, self._SKW, out=b.Wop12)
        np.matmul(b.T4, b.Wop, out=b.TW)
        np.add(b.ru, b.rhoxW0, out=b.dd)
        np.subtract(WP, b.QTW0, out=b.c)
        np.matmul(b.H, b.c_col, out=b.ad_col)
        # every term linear in u = [q, qdot, r, rdot, x0dot, W0, v0, Omega0, v0dot, Omega0dot, 1]: kinematic
        # rows (69b, 69d, 79), m v0dot, J0 Omega0dot, e_eta and g_B = K q + M rdot (78), h = J0 Omega0, rho
        u = src[self._u_idx]
        if self.gyro:
            gy = self._gyroscopic(u, W0, jacobian)
        if self._Lop.ndim == 2:
            np.dot(u, self._Lop, out=b.WO)
        else:
            np.matmul(u[:, None, :], self._Lop, out=b.WO3)
        # g_B to the CM and the nodes (91): R0 g_d on node and (minus) CM rows, H^T g_alpha on node rows,
        # -Q H^T g_alpha, -rho x g_d and W0 x h on the CM rotation rows (77)
        np.matmul(b.gd_mgd, np.swapaxes(R0, -1, -2), out=b.Fd)
        np.matmul(b.ga_row, b.H, out=b.Fa)
        np.matmul(b.Fa, b.mQT, out=b.QFa)
        np.multiply(b.cross_a, b.cross_b, out=b.outer)
        np.dot(b.outer2, self._mCROSS, out=b.cross)
        if self._torque is not None:  # -R^T t on the nodes
            np.matmul(self._torque, R[:N], out=b.load_t)
        F = np.bincount(self._W_rows, b.W, minlength=self.layout.ny + 1)[:-1]
        if not jacobian:
            return F, None
        s = {
            "R0": R0, "R0T": np.swapaxes(R0, -1, -2), "Q": np.swapaxes(b.QT, -1, -2), "QT": b.QT, "H": b.H,
            "rho": b.rho, "alpha": b.alpha, "W0": W0, "c": b.c, "ru": b.ru, "gd": b.gd, "ga": b.ga,
            "Fa": b.Fa[:, :, 0], "h_ang": b.h_ang, "QTW0": b.QTW0,
            "q": self._u.view(u, "q"), "qd": self._u.view(u, "qd"), "rb": self._u.view(u, "rb"), "rbd": self._u.view(u, "rbd"),
        }
        if self.gyro:
            s.update(gy)
        return F, s

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

    def _load_source(self, xN, RN, x0, R0, eta, v, yd):
        """Write an explicit configuration and rates into the source vector; returns the rotation stack."""
        self._b.p[self._lin_slots] = np.concatenate([np.ravel(xN), np.ravel(x0), np.ravel(eta), np.ravel(v)])
        self._b.yd[:] = yd
        return np.concatenate([RN, R0])

    def _local(self, xN, RN, x0, R0, eta, v, yd, jacobian: bool):
        """Assembled residual WITHOUT loads at an explicit configuration and, on request, its derivatives.

        Returns (F, q, qd) or, with jacobian, (F, F_ydot, F_y): F_ydot (E, nrow, nc + nv) w.r.t. local
        (zdot, vdot); F_y w.r.t. local configuration variations (dx world, dTheta body, deta) and
        velocities, rows and columns in the local layout of `_rows`, `_cols`.
        """
        R = self._load_source(xN, RN, x0, R0, eta, v, yd)
        self._b.load[...] = 0.0
        self._torque = None
        np.multiply(self._minus_mass, self.gravity, out=self._b.weight)
        F, s = self._evaluate(R, jacobian=True)
        if not jacobian:
            return F, s["q"].copy(), s["qd"].copy()
        return F, *self._local_jacobian(s)

    def _local_jacobian(self, s):
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
        DqB, DqdB = _view(Dq[:, :nB], (E, nb, 2, 3, nc)), _view(Dqd[:, :nB], (E, nb, 2, 3, nc))
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
        if self.gyro:
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
        if self.gyro:
            rb, rbd, q, qd = s["rb"], s["rbd"], s["q"], s["qd"]
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
        FF[:, :, oeta : oeta + nm] = dg[:, :, nB:]
        # g_B through (91), every node p at once: rows of node p (x, Theta) and dg_d, dg_alpha of node p
        FFN = _view(FF[:, :, onode:], (2, E, nb, 2, 3, ncv))
        dgB = _view(dg[:, :, :nB], (2, E, nb, 2, 3, ncv))
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
        return Fz, Fy

    def _loads(self, RN, inputs_f, inputs_t):
        """Node residual rows get -f and -R^T t from force-driven port parts."""
        L = self.layout
        out = np.zeros((L.n_nodes, 6))
        out[:, 0:3] = -inputs_f
        out[:, 3:6] = -np.einsum("nji,nj->ni", RN, inputs_t)
        return out

    # -------------------------------------------------------------- stepping
    def _read_inputs(self, t: float, values: dict[str, PortValues]):
        """Prescribed node frames/rates and applied loads at time t from the port inputs, checked:
        present, the right shape, finite, R a rotation. Returns (xN, RN, zN, f, t), views of one fresh
        buffer; nodes without motion inputs keep the current frame, without loads zero loads."""
        L = self.layout
        N = L.n_nodes
        buf = np.concatenate([self.xN.ravel(), self.RN.ravel(), self._zeros_inputs])
        xN, RN, zN, f, tq = (buf[sl].reshape(shape) for sl, shape in self._input_views)
        for p in self.data.ports:
            pv = values.get(p.name)
            if pv is None:
                raise StepFailure(t, f"no input values for port {p.name!r}")
            k = p.node
            if p.translation == "motion":
                xN[k], zN[k, 0:3] = _value(pv, "r", p.name, t), _value(pv, "v", p.name, t)
            elif pv.f is not None:
                f[k] = _value(pv, "f", p.name, t)
            if p.rotation == "motion":
                R = RN[k] = _value(pv, "R", p.name, t)
                zN[k, 3:6] = _value(pv, "w", p.name, t) @ R  # body-axes rate R^T w
            elif pv.t is not None:
                tq[k] = _value(pv, "t", p.name, t)
        # finiteness of everything at once; on failure the checks field by field name the culprit
        if _zero_or_nan(buf, self._zeros_input_buf) != 0.0:
            for p in self.data.ports:
                pv = values[p.name]
                for fld, used in (("r", p.translation == "motion"), ("v", p.translation == "motion"),
                                  ("f", p.translation == "force" and pv.f is not None),
                                  ("R", p.rotation == "motion"), ("w", p.rotation == "motion"),
                                  ("t", p.rotation == "force" and pv.t is not None)):
                    if used:
                        _input(pv, fld, p.name, t)
        for k in self._motion_R:
            if not is_rotation(RN[k]):
                name = next(p.name for p in self.data.ports if p.node == k and p.rotation == "motion")
                raise StepFailure(t, f"port {name!r}: input R is not a rotation matrix (|R^T R - I| > 1e-6 or det < 0)")
        return xN, RN, zN, f, tq

    def _configuration(self, xN_pres, RN_pres, delta_h):
        """Configuration at t_{n+1} from the increment h*Delta (global ydot layout); prescribed nodes from inputs."""
        L = self.layout
        dN, dS, dv = self._split_cfg_rates(delta_h)
        rot = expm(np.concatenate([dN[:, 3:6], dS[:, 3:6]]))
        xN = self.xN + dN[:, 0:3]
        RN = self.RN @ rot[: L.n_nodes]
        xN[self._motion_x] = xN_pres[self._motion_x]
        RN[self._motion_R] = RN_pres[self._motion_R]
        return xN, RN, self.x0 + dS[:, 0:3], self.R0 @ rot[L.n_nodes :], self.eta + dS[:, 6:], self.v + dv

    def _prepare_step(self, t1, h, values, am, af, gamma):
        """Everything of the step t -> t1 = t + h that does not depend on the rates ydot_{n+1}.

        With a_{n+1} = (af/am) ydot + A0 the increment is h Delta = beta ydot + D0, beta = h gamma af/am,
        so the linear part of the configuration is p = beta ydot + P0 (P0 = y_n + D0) and the rotations
        are R = R_n exp(h Delta); configuration slots set by motion inputs get c = 0 and the input.
        Returns the prescribed node rates and the loads (zN, f, t)."""
        xN_p, RN_p, zN_p, f_in, t_in = self._read_inputs(t1, values)
        b = self._b
        beta = h * gamma * af / am
        # a_{n+1} = (af/am) ydot + A0, A0 = ((1 - af) ydot_n - (1 - am) a_n)/am; h Delta = beta ydot + D0,
        # D0 = h ((1 - gamma) a_n + gamma A0): both linear in (ydot_n, a_n), one 2 x 2 matmul
        c1, c2 = (1.0 - af) / am, -(1.0 - am) / am
        C = np.array([[c1, c2], [h * gamma * c1, h * (1.0 - gamma) + h * gamma * c2]])
        A0, P0 = C @ np.stack([self.yd, self.a])
        P0[self._lin_slots] += np.concatenate([self.xN.ravel(), self.x0.ravel(), self.eta.ravel(), self.v.ravel()])
        P0[self._motion_x_slots] = xN_p[self._motion_x].ravel()
        P0[self._motion_T_slots] = 0.0
        Rn = np.concatenate([RN_p, self.R0])  # RN_p: the inputs on motion nodes, the current frames elsewhere
        if self._stage_beta != beta:
            self._stage_beta, self._stage_c = beta, beta * self._stage_mask
        self._stage = (self._stage_c, P0, Rn, af / am, A0)
        np.negative(f_in, out=b.load[:, 0])  # -f on the node translation rows
        b.load[:, 1] = 0.0  # -R^T t on the rotation rows: per evaluation, when there is a torque
        self._torque = -t_in[:, None, :] if t_in.any() else None
        np.multiply(self._minus_mass, self.gravity, out=b.weight)
        return zN_p, f_in, t_in

    def _residual_at(self, yd, jacobian: bool = False, beta: float | None = None):
        """F (ny,) at the rates ydot_{n+1} = yd of the prepared step [and J = F_ydot + beta [F_y T, F_v]].
        Leaves the configuration in the source vector and `self._R` (for `_commit`)."""
        c, P0, Rn, _, _ = self._stage
        b = self._b
        if yd is not b.yd:
            b.yd[:] = yd
        p = np.multiply(yd, c, out=b.p)
        p += P0
        theta = p[self._rot_slots]  # h Delta on every rotation (nodes then SEs)
        self._R = R = Rn @ expm(theta)
        F, s = self._evaluate(R, jacobian)
        if not jacobian:
            return F
        Fz, Fy = self._local_jacobian(s)
        return F, self._iteration_matrix(Fz, Fy, beta, theta, R)

    def _iteration_matrix(self, Fz, Fy, beta, theta, R):
        """J = F_ydot + beta [F_y T, F_v] on the unknowns, assembled in the Newton order:
        d(config) = beta T(h Delta) d(zdot) on rotations, d(v) = beta d(vdot)."""
        L = self.layout
        N, nf = L.n_nodes, len(self._newton_idx)
        T = tangent(theta)
        TN, Tl = T[:N], T[N:]
        Fy = Fy * beta
        Fy[:, :, 3:6] = Fy[:, :, 3:6] @ Tl
        TNl = TN[self.se_nodes]
        for p in range(L.nb):
            c = slice(6 + L.nm + 6 * p + 3, 6 + L.nm + 6 * p + 6)
            Fy[:, :, c] = Fy[:, :, c] @ TNl[:, p]
        Fy += Fz
        J = np.bincount(self._newton_flat, Fy.ravel(), minlength=nf * nf + 1)[:-1].reshape(nf, nf)
        # load term -R^T t on free node rotations: d = -skew(R^T t) dTheta
        if self._torque is not None:
            RtT = -(self._torque @ R[:N])[:, 0]
            for k, pos in self._torque_rows:
                J[np.ix_(pos, pos)] += -beta * skew(RtT[k]) @ TN[k]
        return J

    def step(self, h: float, inputs: Callable[[float], dict[str, PortValues]]) -> int:
        """Advance by one step h; returns the Newton iterations; raises StepFailure."""
        am, af, gamma = self.coefficients
        return self._step(h, inputs, am, af, gamma, commit_config=True)

    def newton_system(self, yd, h, values, coefficients=None, jacobian=True):
        """(F, J) restricted to the unknowns for rates yd at t + h (J = F_ydot + beta [F_y T, F_v])."""
        am, af, gamma = coefficients or self.coefficients
        self._prepare_step(self.t + h, h, values, am, af, gamma)
        fi = self._free_idx
        if not jacobian:
            return self._residual_at(yd)[fi]
        F, J = self._residual_at(yd, jacobian=True, beta=h * gamma * af / am)
        pos = self._newton_pos[fi]
        return F[fi], J[np.ix_(pos, pos)]

    def _step(self, h, inputs, am, af, gamma, commit_config):
        t1 = self.t + h
        if not (h > 0.0 and np.isfinite(h)):
            raise StepFailure(self.t, f"step size must be positive and finite, got {h}")
        zN_p, f_in, t_in = self._prepare_step(t1, h, inputs(t1), am, af, gamma)
        # predictor: rates extrapolated linearly from the last two steps. Newton iterates on the rates
        # slot of the source vector, which the evaluation reads
        yd = self._b.yd
        if commit_config:
            np.subtract(2.0 * self.yd, self.yd_prev, out=yd)
        else:
            yd[:] = self.yd
        fixed = self._fixed_idx
        yd[fixed] = zN_p.ravel()[fixed]
        beta = h * gamma * af / am
        fi, order = self._free_idx, self._newton_idx
        dx_prev = np.inf
        for it in range(0, self.max_iter + 1):
            # a matrix built for a step within 1e-6 of this one serves as well (modified Newton); an FMU's
            # communication grid repeats its step only up to round-off
            refresh = self._lu is None or abs(self._lu[2] - beta) > 1e-6 * beta
            if refresh:
                F, J = self._residual_at(yd, jacobian=True, beta=beta)
            else:
                F = self._residual_at(yd)
            if _zero_or_nan(F, self._zeros_ny) != 0.0:
                self._lu = None
                raise StepFailure(t1, "the residual is not finite (NaN or overflow)")
            if it > 0:  # (the tolerance, scaled by the rates, is needed from the first increment on)
                tol = self.tol * (1.0 + beta * np.abs(yd[fi]).max())
                if dx_prev <= tol:
                    break  # converged: F is the residual at the accepted rates, reused below
            if it == self.max_iter:
                self._lu = None
                raise StepFailure(t1, f"Newton did not converge in {self.max_iter} iterations (last increment {dx_prev:.3g})")
            R_now = self._R[self.layout.n_nodes]  # first CM frame
            if refresh:
                self._factor(J, beta, t1, R_now)
            dx = self._solve(F, R_now)
            yd[order] -= dx
            err = beta * np.abs(dx).max()
            if it > 0 and err > 0.25 * dx_prev and err > 10.0 * tol:
                self._lu = None  # slow contraction (above round-off): refresh the iteration matrix
            dx_prev = err
        if not commit_config:
            return yd.copy()
        self._commit(yd.copy())
        self.t, self.iterations = t1, it
        self._update_port_loads(F, f_in, t_in)
        p_new = self._external_power()
        self.work += 0.5 * h * (self.power + p_new)
        self.power = p_new
        return it

    def _commit(self, yd):
        """The configuration of the last residual evaluation and the rates yd become the state."""
        L, R = self.layout, self._R
        _, _, _, af_am, A0 = self._stage
        lin = self._b.p[self._lin_slots]
        self.xN, self.x0, self.eta, self.v = (lin[sl].reshape(shape) for sl, shape in self._lin_views)
        self.RN, self.R0 = R[: L.n_nodes], R[L.n_nodes :]
        self.yd_prev = self.yd
        self.a = af_am * yd + A0
        self.yd = yd

    def _factor(self, J, beta, t, R_ref):
        """LU of the iteration matrix (unknowns in the Newton order), with the rotation of the first CM
        frame it was built at."""
        try:
            lu, piv = sla.lu_factor(J, overwrite_a=True, check_finite=True)  # J is not used afterwards
        except (ValueError, np.linalg.LinAlgError) as exc:
            self._lu = None
            raise StepFailure(t, f"iteration matrix cannot be factored: {exc}")
        self._lu = (lu, piv, beta, R_ref.copy())

    def _solve(self, F, R_now):
        """J^-1 F on the unknowns in the Newton order (the increment is minus this), with the stored
        factorization carried along the rigid rotation.

        The equations are frame-indifferent: rotating every world-axes vector (node and CM positions,
        CM velocities, forces) by a rigid rotation P maps J to P J P^T. So the matrix factored at the
        orientation R_ref serves at R_now through P = R_now R_ref^T, and modified Newton keeps its
        contraction while the body spins."""
        lu, piv, _, R_ref = self._lu
        P = R_now @ R_ref.T
        k3 = 3 * len(self._world_free)
        F = F[self._newton_idx]  # world triplets first
        Fw = F[:k3].reshape(-1, 3)
        Fw[...] = Fw @ P  # P^T F on each triplet
        dx, info = getrs(lu, piv, F, overwrite_b=1)  # LAPACK directly: scipy's lu_solve wrapper costs more than the solve
        dw = dx[:k3].reshape(-1, 3)
        dw[...] = dw @ P.T  # P J_ref^-1 P^T F
        return dx

    def _update_port_loads(self, F, f_in, t_in):
        """Loads on the nodes: the inputs on force-driven parts, reactions (residual without loads) on
        motion parts (where no load is read, so the residual there is the contributions alone)."""
        N = self.layout.n_nodes
        Fn = F[: 6 * N].reshape(N, 2, 3)  # node rows: x, Theta (body axes)
        self.fN = f_in + self._motion_parts[:, 0] * Fn[:, 0]
        self.tN = t_in + self._motion_parts[:, 1] * (Fn[:, 1:2] @ np.swapaxes(self.RN, -1, -2))[:, 0]  # R F_Theta

    def _external_power(self) -> float:
        """Power of the port loads and gravity: f . v + t . (R W) on the nodes, m g . v0 on the CMs."""
        N = self.layout.n_nodes
        zN = self.yd[: 6 * N].reshape(N, 2, 3)
        Rt_t = (self.tN[:, None, :] @ self.RN)[:, 0]  # R^T t . W = t . R W
        p_nodes = np.vdot(self.fN, zN[:, 0]) + np.vdot(Rt_t, zN[:, 1])
        return float(p_nodes + (self.mass @ self.v[:, 0:3]) @ self.gravity)

    # ----------------------------------------------------------- initial state
    def initialize(
        self,
        t0: float,
        inputs: dict[str, PortValues] | Callable[[float], dict[str, PortValues]],
        velocity=(0.0, 0.0, 0.0),
        angular_velocity=(0.0, 0.0, 0.0),
        port_displacements: dict[str, np.ndarray] | None = None,
        origin=(0.0, 0.0, 0.0),
    ) -> None:
        """Reference configuration moved rigidly onto the motion inputs, rigid velocity field
        v + w x (x - origin) (or the motion inputs' velocities), optional port offsets (an initial
        elastic deformation), then consistent rates ydot_0 from a backward-Euler micro-step."""
        fn = inputs if callable(inputs) else (lambda t, _v=inputs: _v)
        self._reset_reference()
        self.t = float(t0)
        values = fn(t0)
        xN_p, RN_p, zN_p, f_in, t_in = self._read_inputs(t0, values)
        # rigid placement on the first motion-driven rotation (then translation) input
        R_rig, c_ref, c_new = np.eye(3), np.zeros(3), np.zeros(3)
        v_lin, w = np.asarray(velocity, float), np.asarray(angular_velocity, float)
        o = np.asarray(origin, float)
        for p in self.data.ports:
            if p.rotation == "motion":
                R_rig = RN_p[p.node]
                w = RN_p[p.node] @ zN_p[p.node, 3:6]
                break
        for p in self.data.ports:
            if p.translation == "motion":
                c_ref = self.data.node_positions[p.node]
                c_new = xN_p[p.node]
                v_lin, o = zN_p[p.node, 0:3], c_new
                break
        place = lambda X: c_new + (np.asarray(X) - c_ref) @ R_rig.T
        self.xN = place(self.xN)
        self.x0 = place(self.x0)
        self.RN = np.repeat(R_rig[None], len(self.xN), 0)
        self.R0 = np.repeat(R_rig[None], len(self.x0), 0)
        for name, u in (port_displacements or {}).items():
            self.xN[self.data.port(name).node] += np.asarray(u, float)
        if port_displacements:
            self._relax(set(port_displacements))
        vel = lambda x: v_lin + cross(w, x - o)
        zN, zS, v = self._split_cfg_rates(self.yd)  # views into self.yd
        zN[:, 0:3] = vel(self.xN)
        zN[:, 3:6] = w @ self.RN  # R^T w, body-axes rates of the rigid field
        zS[:, 0:3] = vel(self.x0)
        zS[:, 3:6] = w @ self.R0
        self.v[:, 0:3] = zS[:, 0:3]
        self.v[:, 3:6] = zS[:, 3:6]
        # r_bar = q_dot_bar of the rigid field (zero unless ports were displaced)
        _, q, qd = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, self.v, self.yd, False)
        self.v[:, 6:] = qd
        self.fN, self.tN = f_in.copy(), t_in.copy()
        # consistent ydot_0: a backward-Euler micro-step (am = af = gamma = 1) from the initial state
        delta = 1e-6
        saved = self.get_state()
        yd0 = self._step(delta, fn, 1.0, 1.0, 1.0, commit_config=False)
        self.set_state(saved)
        self.yd = yd0
        self.yd_prev = yd0.copy()
        self.a = yd0.copy()
        F = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, self.v, self.yd, False)[0]
        F[: 6 * self.layout.n_nodes] += self._loads(self.RN, f_in, t_in).ravel()
        self._update_port_loads(F, f_in, t_in)
        self.power = self._external_power()
        self.work = 0.0
        self._lu = None

    def _relax(self, displaced: set[str], tol: float = 1e-12, max_iter: int = 30) -> None:
        """Static equilibrium (no inertia, no loads) with every port's translation held and the rotation
        of every port that was not displaced: the smooth deformed shape through displaced ports (for a
        free beam with its far end displaced, the cantilever shape), instead of a kink of the
        attachment modes at the displaced node."""
        L = self.layout
        relax = np.zeros(L.ny, dtype=bool)
        relax[: 6 * L.n_nodes + L.n_se * (6 + L.nm)] = True
        for p in self.data.ports:
            relax[6 * p.node : 6 * p.node + 3] = False
            if p.name not in displaced or p.rotation == "motion":
                relax[6 * p.node + 3 : 6 * p.node + 6] = False
        idx = np.flatnonzero(relax)
        zero_v, zero_yd = np.zeros_like(self.v), np.zeros(L.ny)
        gravity, self.gravity = self.gravity, np.zeros(3)
        try:
            for _ in range(max_iter):
                F, _, Fy = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, zero_v, zero_yd, True)
                J = np.bincount(self._flat_idx, Fy.ravel(), minlength=L.ny * L.ny).reshape(L.ny, L.ny)
                delta = np.zeros(L.ny)
                delta[idx] = np.linalg.solve(J[np.ix_(idx, idx)], -F[idx])
                self.xN, self.RN, self.x0, self.R0, self.eta, _ = self._configuration(self.xN, self.RN, delta)
                if np.max(np.abs(delta)) < tol:
                    return
        finally:
            self.gravity = gravity
        raise ValueError("initial port displacements: no static equilibrium of the deformed body found")

    def linearization(self) -> tuple[np.ndarray, np.ndarray]:
        """(F_ydot, F_y) of the assembled equations at the current state, restricted to the unknowns:
        small motions obey F_ydot d(ydot) + F_y d(y) = 0, so their frequencies solve
        det(i w F_ydot + F_y) = 0 (a check of the dynamic equations against the modal analysis)."""
        L = self.layout
        _, Fz, Fy = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, self.v, self.yd, True)
        fi = self._free_idx
        scatter = lambda A: np.bincount(self._flat_idx, A.ravel(), minlength=L.ny * L.ny).reshape(L.ny, L.ny)[np.ix_(fi, fi)]
        return scatter(Fz), scatter(Fy)

    # ----------------------------------------------------------------- outputs
    OUTPUT_FIELDS = ("r", "R", "v", "w", "f", "t")  # the columns of `port_array`, 3 or 9 each

    def port_array(self) -> np.ndarray:
        """(n_ports, 24) port outputs, one row per port in data.ports order: r, R (row-major), v, w, f, t."""
        k = self._port_nodes
        zN = self.yd[: 6 * self.layout.n_nodes].reshape(-1, 6)[k]
        R = self.RN[k]
        w = (zN[:, None, 3:6] @ np.swapaxes(R, -1, -2))[:, 0]  # R W
        return np.concatenate([self.xN[k], R.reshape(-1, 9), zN[:, 0:3], w, self.fN[k], self.tN[k]], axis=1)

    def outputs(self) -> dict[str, PortValues]:
        rows = self.port_array()
        return {
            p.name: PortValues(r=row[0:3], R=row[3:12].reshape(3, 3), v=row[12:15], w=row[15:18], f=row[18:21], t=row[21:24])
            for p, row in zip(self.data.ports, rows)
        }

    def elastic_coordinates(self) -> np.ndarray:
        """q_bar of every superelement (E, n) at the current state, eq. (89)."""
        nodes = self.se_nodes
        return self._elastic(self.xN[nodes], self.RN[nodes], self.x0, np.swapaxes(self.R0, -1, -2), self.eta)[0]

    def energies(self) -> dict[str, float]:
        """The split (20): rigid kinetic, elastic kinetic 1/2 r^T M r, strain 1/2 q^T K q, external work.

        The quadratic forms of every SE are one stacked matmul: [v, q] with blockdiag(m I, J0, M, K)."""
        vq = np.concatenate([self.v, self.elastic_coordinates()], axis=1)  # [v0, Omega0, r, q]
        halves = (vq * (vq[:, None, :] @ self._energy_op)[:, 0]) @ self._energy_split  # (E, 3)
        kr, ke, st = halves.sum(0)
        return {"kinetic_rigid": float(kr), "kinetic_elastic": float(ke), "strain": float(st), "work_external": float(self.work)}

    def momenta(self) -> tuple[np.ndarray, np.ndarray]:
        """Linear and angular momentum (about the world origin) of the rigid + elastic fields, world axes.

        The elastic velocity field carries no momentum about each CM (69h), so these are sums over CMs."""
        p = self.mass[:, None] * self.v[:, 0:3]
        hc = np.einsum("eij,ejk,ek->ei", self.R0, self.J0, self.v[:, 3:6])
        if self.gyro:
            q = self.elastic_coordinates()
            s = np.einsum("ei,ekij,ej->ek", self.v[:, 6:], self.G, q)
            hc = hc + np.einsum("eij,ej->ei", self.R0, s)
        return p.sum(0), (np.cross(self.x0, p) + hc).sum(0)
