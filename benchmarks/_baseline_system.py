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
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dgetrs as getrs

from ffrf_fmu.runtime.data import BodyData
from ffrf_fmu.runtime.ports import PortValues, StepFailure
from _baseline_rotation import cross, expm, is_rotation, skew, tangent, vect, vect_tangent

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
        self._lu = None
        # world-axes triplets among the unknowns: node positions, CM positions, CM velocities
        world = np.zeros(L.ny, dtype=bool)
        world[(6 * np.arange(L.n_nodes)[:, None] + np.arange(3)).ravel()] = True
        world[L.cfg_map[:, 0:3].ravel()] = True
        world[L.vel_map[:, 0:3].ravel()] = True
        pos = np.cumsum(L.free) - 1  # index of each unknown among the free ones
        trip = pos[np.flatnonzero(world & L.free)].reshape(-1, 3)
        self._world_free = trip
        self._motion_x = np.array([p.node for p in data.ports if p.translation == "motion"], dtype=int)
        self._motion_R = np.array([p.node for p in data.ports if p.rotation == "motion"], dtype=int)
        self.t = 0.0
        self.iterations = 0
        self._reset_reference()

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

    def _local(self, xN, RN, x0, R0, eta, v, yd, jacobian: bool):
        """Residual (E, nv + nc) of every superelement and, on request, its derivatives.

        Returns (res, F_ydot, F_y): F_ydot (E, nrow, nc + nv) w.r.t. local (zdot, vdot); F_y w.r.t. local
        configuration variations (dx world, dTheta body, deta) and velocities. Node rows hold this
        superelement's contribution only; loads are added in `_residual`.
        """
        L = self.layout
        E, nb, nm, n, nc, nv = L.n_se, L.nb, L.nm, L.n, L.nc, L.nv
        zN, zS, vd = self._split_cfg_rates(yd)
        nodes = self.se_nodes
        xP, RP = xN[nodes], RN[nodes]  # (E, nb, 3), (E, nb, 3, 3)
        x0d, W0, etad = zS[:, 0:3], zS[:, 3:6], zS[:, 6:]
        xPd, WP = zN[nodes][..., 0:3], zN[nodes][..., 3:6]
        v0, Om0, rb = v[:, 0:3], v[:, 3:6], v[:, 6:]
        v0d, Om0d, rbd = vd[:, 0:3], vd[:, 3:6], vd[:, 6:]
        R0T = np.swapaxes(R0, -1, -2)
        q, rho, Q, alpha = self._elastic(xP, RP, x0, R0T, eta)
        QT = np.swapaxes(Q, -1, -2)
        H = vect_tangent(Q)
        # q_dot = A zdot (eq. 91 applied to rates)
        ru = (xPd - x0d[:, None]) @ R0
        dd = ru + cross(rho, W0[:, None])
        c = WP - (W0[:, None, None, :] @ Q)[:, :, 0]  # W_P - Q^T W0
        ad = (H @ c[..., None])[..., 0]
        qd = np.concatenate([np.concatenate([dd, ad], axis=2).reshape(E, 6 * nb), etad], axis=1)

        K, M = self.K, self.M
        kq = (M @ (qd - rb)[..., None])[..., 0]
        g = (K @ q[..., None] + M @ rbd[..., None])[..., 0]
        J0Om = (self.J0 @ Om0[..., None])[..., 0]
        h_ang = J0Om
        if self.gyro:
            Gw = np.einsum("ek,ekij->eij", W0, self.G)
            Gq = np.einsum("ekij,ej->eik", self.G, q)  # (E, n, 3): column k = G_k q
            Gr = np.einsum("ekij,ej->eik", self.G, rb)
            kq = kq + (Gw @ q[..., None])[..., 0]
            g = g + (Gw @ rb[..., None])[..., 0]
            s = np.einsum("ei,eik->ek", rb, Gq)  # s_k = r^T G_k q
            sdot = np.einsum("ei,eik->ek", rbd, Gq) - np.einsum("ei,eik->ek", qd, Gr)  # rdot^T G q + r^T G qdot
            h_ang = J0Om + s
        gB = g[:, : 6 * nb].reshape(E, nb, 6)
        gd, ga = gB[..., 0:3], gB[..., 3:6]
        Fd = gd @ R0T  # R0 g_d
        Fa = (ga[..., None, :] @ H)[:, :, 0]  # H^T g_alpha
        QFa = (Fa[..., None, :] @ QT)[:, :, 0]
        e_x0 = self.mass[:, None] * (v0d - self.gravity) - Fd.sum(1)
        e_T0 = (self.J0 @ Om0d[..., None])[..., 0] + cross(W0, h_ang) - (cross(rho, gd) + QFa).sum(1)
        if self.gyro:
            e_T0 = e_T0 + sdot
        res = np.concatenate(
            [x0d - v0, W0 - Om0, kq, e_x0, e_T0, g[:, 6 * nb :], np.concatenate([Fd, Fa], axis=2).reshape(E, 6 * nb)],
            axis=1,
        )
        if not jacobian:
            return res, q, qd
        return res, *self._local_jacobian(locals())

    def _local_jacobian(self, s):
        """Analytic derivatives of `_local` (the algebra is spelled out in docs/equations.md)."""
        L = self.layout
        E, nb, nm, n, nc, nv = L.n_se, L.nb, L.nm, L.n, L.nc, L.nv
        R0, R0T, Q, QT, H, rho, alpha = s["R0"], s["R0T"], s["Q"], s["QT"], s["H"], s["rho"], s["alpha"]
        W0, c, ru, gd, ga, Fa = s["W0"], s["c"], s["ru"], s["gd"], s["ga"], s["Fa"]
        K, M = self.K, self.M
        I3 = np.eye(3)
        cx0, cT0, ceta = slice(0, 3), slice(3, 6), slice(6, 6 + nm)

        def cP(p, part):  # local config column of node p, part 0 = x, 1 = Theta
            o = 6 + nm + 6 * p + 3 * part
            return slice(o, o + 3)

        # Dq: derivative of q_bar w.r.t. local configuration (= derivative of q_dot_bar w.r.t. zdot)
        Dq = np.zeros((E, n, nc))
        # Dqd: derivative of q_dot_bar w.r.t. configuration at fixed zdot
        Dqd = np.zeros((E, n, nc))
        HQT = np.einsum("epij,epkj->epik", H, Q)  # H Q^T
        W0x = skew(W0)
        B = (
            -np.einsum("epi,epj->epij", c, alpha)
            - 0.5 * skew(np.einsum("epji,epj->epi", Q, c))
            - np.einsum("epij,epjk->epik", H, skew(np.einsum("epji,ej->epi", Q, W0)))
        )
        for p in range(nb):
            rd, ra = slice(6 * p, 6 * p + 3), slice(6 * p + 3, 6 * p + 6)
            Dq[:, rd, cx0] = -R0T
            Dq[:, rd, cT0] = skew(rho[:, p])
            Dq[:, rd, cP(p, 0)] = R0T
            Dq[:, ra, cT0] = -HQT[:, p]
            Dq[:, ra, cP(p, 1)] = H[:, p]
            Dqd[:, rd, :] = -W0x @ Dq[:, rd, :]
            Dqd[:, rd, cT0] += skew(ru[:, p])
            Dqd[:, ra, cP(p, 1)] = B[:, p]
            Dqd[:, ra, cT0] = -B[:, p] @ QT[:, p]
        Dq[:, 6 * nb :, ceta] = np.eye(nm)

        nrow = nv + nc
        Fz = np.zeros((E, nrow, nc + nv))  # w.r.t. (zdot, vdot)
        Fy = np.zeros((E, nrow, nc + nv))  # w.r.t. (configuration, velocity)
        V = nc  # offset of velocity columns
        vr = slice(V + 6, V + 6 + n)  # r_bar columns
        # kinematic rows
        Fz[:, 0:3, cx0] = I3
        Fy[:, 0:3, V : V + 3] = -I3
        Fz[:, 3:6, cT0] = I3
        Fy[:, 3:6, V + 3 : V + 6] = -I3
        kr = slice(6, 6 + n)
        Fz[:, kr, :nc] = M @ Dq
        Fy[:, kr, :nc] = M @ Dqd
        Fy[:, kr, vr] = -M
        # g = K q + M rdot [+ G(W0) r]: derivatives kept apart, projected below
        dg_y = np.zeros((E, n, nc + nv))
        dg_z = np.zeros((E, n, nc + nv))
        dg_y[:, :, :nc] = K @ Dq
        dg_z[:, :, vr] = M
        if self.gyro:
            Gw, Gq, Gr = s["Gw"], s["Gq"], s["Gr"]
            Fz[:, kr, cT0] += Gq
            Fy[:, kr, :nc] += Gw @ Dq
            dg_z[:, :, cT0] += Gr
            dg_y[:, :, vr] += Gw
        # dynamic rows
        ox0, oT0, oeta = nv, nv + 3, nv + 6
        onode = nv + 6 + nm
        mass = self.mass[:, None, None]
        Fz[:, ox0 : ox0 + 3, V : V + 3] = mass * I3
        Fz[:, oT0 : oT0 + 3, V + 3 : V + 6] = self.J0
        # W0 x h_ang: d/dW0 = -skew(h_ang); d/dOmega0 = skew(W0) J0
        Fz[:, oT0 : oT0 + 3, cT0] += -skew(s["h_ang"])
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
        Fz[:, oeta : oeta + nm] = dg_z[:, 6 * nb :]
        Fy[:, oeta : oeta + nm] = dg_y[:, 6 * nb :]
        for p in range(nb):
            rd, ra = slice(6 * p, 6 * p + 3), slice(6 * p + 3, 6 * p + 6)
            gdp, gap = gd[:, p], ga[:, p]
            # e_x0 -= R0 g_d ;  d(R0 g_d) = -R0 skew(g_d) dTheta0 + R0 dg_d
            Fy[:, ox0 : ox0 + 3, cT0] += R0 @ skew(gdp)
            for F, dg in ((Fy, dg_y), (Fz, dg_z)):
                F[:, ox0 : ox0 + 3] -= R0 @ dg[:, rd]
            # node x rows: + R0 g_d
            nx = slice(onode + 6 * p, onode + 6 * p + 3)
            Fy[:, nx, cT0] += -R0 @ skew(gdp)
            for F, dg in ((Fy, dg_y), (Fz, dg_z)):
                F[:, nx] += R0 @ dg[:, rd]
            # d(H^T g_a) = C eps + H^T dg_a, C = -g_a alpha^T + Q skew(g_a) / 2, eps = dTheta_P - Q^T dTheta0
            C = -np.einsum("ei,ej->eij", gap, alpha[:, p]) + 0.5 * Q[:, p] @ skew(gap)
            HT = np.swapaxes(H[:, p], 1, 2)
            nT = slice(onode + 6 * p + 3, onode + 6 * p + 6)
            Fy[:, nT, cP(p, 1)] += C
            Fy[:, nT, cT0] += -C @ QT[:, p]
            for F, dg in ((Fy, dg_y), (Fz, dg_z)):
                F[:, nT] += HT @ dg[:, ra]
            # e_T0 -= rho x g_d + Q H^T g_a
            Dr = Dq[:, rd]  # d rho = d d
            Fy[:, oT0 : oT0 + 3, :nc] -= -skew(gdp) @ Dr
            for F, dg in ((Fy, dg_y), (Fz, dg_z)):
                F[:, oT0 : oT0 + 3] -= skew(rho[:, p]) @ dg[:, rd]
            # d(Q Fa) = -Q skew(Fa) eps + Q d(Fa)
            QC = -Q[:, p] @ skew(Fa[:, p]) + Q[:, p] @ C
            Fy[:, oT0 : oT0 + 3, cP(p, 1)] -= QC
            Fy[:, oT0 : oT0 + 3, cT0] -= -QC @ QT[:, p]
            for F, dg in ((Fy, dg_y), (Fz, dg_z)):
                F[:, oT0 : oT0 + 3] -= Q[:, p] @ HT @ dg[:, ra]
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
        """Prescribed node frames/rates and applied loads at time t from the port inputs."""
        L = self.layout
        xN, RN = self.xN.copy(), self.RN.copy()
        zN = np.zeros((L.n_nodes, 6))
        f = np.zeros((L.n_nodes, 3))
        tq = np.zeros((L.n_nodes, 3))
        for p in self.data.ports:
            pv = values.get(p.name)
            if pv is None:
                raise StepFailure(t, f"no input values for port {p.name!r}")
            k = p.node
            if p.translation == "motion":
                xN[k], zN[k, 0:3] = _input(pv, "r", p.name, t), _input(pv, "v", p.name, t)
            elif pv.f is not None:
                f[k] = _input(pv, "f", p.name, t)
            if p.rotation == "motion":
                R = _input(pv, "R", p.name, t)
                if not is_rotation(R):
                    raise StepFailure(t, f"port {p.name!r}: input R is not a rotation matrix (|R^T R - I| > 1e-6 or det < 0)")
                RN[k], zN[k, 3:6] = R, _input(pv, "w", p.name, t) @ R  # body-axes rate R^T w
            elif pv.t is not None:
                tq[k] = _input(pv, "t", p.name, t)
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

    def _residual(self, yd, cfg, loads, jacobian=False, beta=None, delta_h=None):
        L = self.layout
        xN, RN, x0, R0, eta, v = cfg
        out = self._local(xN, RN, x0, R0, eta, v, yd, jacobian)
        res_loc = out[0]
        F = np.bincount(self._rows.ravel(), res_loc.ravel(), minlength=L.ny)
        F[: 6 * L.n_nodes] += self._loads(RN, *loads).ravel()
        if not jacobian:
            return F, out[1], out[2]
        Fz, Fy = out[1], out[2]
        # chain rule: d(config) = beta T(h Delta) d(zdot) on rotations, d(v) = beta d(vdot)
        nc = L.nc
        Tl = tangent(self._split_cfg_rates(delta_h)[1][:, 3:6])  # SE rotations
        TN = tangent(self._split_cfg_rates(delta_h)[0][:, 3:6])  # node rotations
        Fy = Fy.copy()
        Fy[:, :, 3:6] = Fy[:, :, 3:6] @ Tl
        TNl = TN[self.se_nodes]
        for p in range(L.nb):
            c = slice(6 + L.nm + 6 * p + 3, 6 + L.nm + 6 * p + 6)
            Fy[:, :, c] = Fy[:, :, c] @ TNl[:, p]
        Jl = Fz + beta * Fy
        J = np.bincount(self._flat_idx, Jl.ravel(), minlength=L.ny * L.ny).reshape(L.ny, L.ny)
        # load term -R^T t on free node rotations: d = -skew(R^T t) dTheta
        RtT = np.einsum("nji,nj->ni", RN, loads[1])
        for k in range(L.n_nodes):
            r = slice(6 * k + 3, 6 * k + 6)
            J[r, r] += -beta * skew(RtT[k]) @ TN[k]
        return F, J

    def step(self, h: float, inputs: Callable[[float], dict[str, PortValues]]) -> int:
        """Advance by one step h; returns the Newton iterations; raises StepFailure."""
        am, af, gamma = self.coefficients
        return self._step(h, inputs, am, af, gamma, commit_config=True)

    def _stage(self, yd, h, am, af, gamma, prescribed):
        """Configuration at t_{n+1} implied by the rates ydot_{n+1} = yd, with a_{n+1} and h*Delta."""
        a1 = (af * yd + (1.0 - af) * self.yd - (1.0 - am) * self.a) / am
        delta_h = h * ((1.0 - gamma) * self.a + gamma * a1)
        return self._configuration(prescribed[0], prescribed[1], delta_h), a1, delta_h

    def newton_system(self, yd, h, values, coefficients=None, jacobian=True):
        """(F, J) restricted to the unknowns for rates yd at t + h (J = F_ydot + beta [F_y T, F_v])."""
        am, af, gamma = coefficients or self.coefficients
        xN_p, RN_p, zN_p, f_in, t_in = self._read_inputs(self.t + h, values)
        cfg, _, delta_h = self._stage(yd, h, am, af, gamma, (xN_p, RN_p))
        fi = self._free_idx
        if not jacobian:
            return self._residual(yd, cfg, (f_in, t_in))[0][fi]
        F, J = self._residual(yd, cfg, (f_in, t_in), jacobian=True, beta=h * gamma * af / am, delta_h=delta_h)
        return F[fi], J[np.ix_(fi, fi)]

    def _step(self, h, inputs, am, af, gamma, commit_config):
        L = self.layout
        t1 = self.t + h
        if not (h > 0.0 and np.isfinite(h)):
            raise StepFailure(self.t, f"step size must be positive and finite, got {h}")
        prescribed = xN_p, RN_p, zN_p, f_in, t_in = self._read_inputs(t1, inputs(t1))
        loads = (f_in, t_in)
        free_nodes = L.free[: 6 * L.n_nodes]
        # predictor: rates extrapolated linearly from the last two steps
        yd = 2.0 * self.yd - self.yd_prev if commit_config else self.yd.copy()
        yd[: 6 * L.n_nodes][~free_nodes] = zN_p.ravel()[~free_nodes]
        beta = h * gamma * af / am
        fi = self._free_idx
        dx_prev = np.inf
        for it in range(0, self.max_iter + 1):
            cfg, a1, delta_h = self._stage(yd, h, am, af, gamma, prescribed)
            refresh = self._lu is None or self._lu[2] != beta
            if refresh:
                F, J = self._residual(yd, cfg, loads, jacobian=True, beta=beta, delta_h=delta_h)
            else:
                F = self._residual(yd, cfg, loads)[0]
            if not np.all(np.isfinite(F)):
                self._lu = None
                raise StepFailure(t1, "the residual is not finite (NaN or overflow)")
            tol = self.tol * (1.0 + beta * np.max(np.abs(yd[fi])))
            if dx_prev <= tol:
                break  # converged: F is the residual at the accepted rates, reused below
            if it == self.max_iter:
                self._lu = None
                raise StepFailure(t1, f"Newton did not converge in {self.max_iter} iterations (last increment {dx_prev:.3g})")
            if refresh:
                self._factor(J[np.ix_(fi, fi)], beta, t1, cfg[3][0])
            dx = self._solve(F[fi], cfg[3][0])
            yd[fi] += dx
            err = beta * np.max(np.abs(dx))
            if err > 0.25 * dx_prev and err > 10.0 * tol:
                self._lu = None  # slow contraction (above round-off): refresh the iteration matrix
            dx_prev = err
        if not commit_config:
            return yd
        self.xN, self.RN, self.x0, self.R0, self.eta, self.v = cfg
        self.yd_prev = self.yd
        self.yd, self.a, self.t, self.iterations = yd, a1, t1, it
        self._update_port_loads(F, f_in, t_in)
        p_new = self._external_power()
        self.work += 0.5 * h * (self.power + p_new)
        self.power = p_new
        return it

    def _factor(self, J, beta, t, R_ref):
        """LU of the iteration matrix, with the rotation of the first CM frame it was built at."""
        try:
            lu, piv = sla.lu_factor(J, check_finite=True)
        except (ValueError, np.linalg.LinAlgError) as exc:
            self._lu = None
            raise StepFailure(t, f"iteration matrix cannot be factored: {exc}")
        self._lu = (lu, piv, beta, R_ref.copy())

    def _solve(self, F, R_now):
        """Newton increment -J^-1 F with the stored factorization, carried along the rigid rotation.

        The equations are frame-indifferent: rotating every world-axes vector (node and CM positions,
        CM velocities, forces) by a rigid rotation P maps J to P J P^T. So the matrix factored at the
        orientation R_ref serves at R_now through P = R_now R_ref^T, and modified Newton keeps its
        contraction while the body spins."""
        lu, piv, _, R_ref = self._lu
        P = R_now @ R_ref.T
        w = self._world_free  # (k, 3) positions of world-axes triplets among the unknowns
        F = F.copy()
        F[w] = F[w] @ P  # P^T F on each triplet
        dx, info = getrs(lu, piv, F)  # LAPACK directly: scipy's lu_solve wrapper costs more than the solve
        dx = -dx
        dx[w] = dx[w] @ P.T  # P dx
        return dx

    def _update_port_loads(self, F, f_in, t_in):
        """Loads on the nodes: the inputs on force-driven parts, reactions (residual without loads) on motion parts."""
        L = self.layout
        Fn = F[: 6 * L.n_nodes].reshape(L.n_nodes, 6)
        free_nodes = L.free[: 6 * L.n_nodes].reshape(L.n_nodes, 6)
        react_f = Fn[:, 0:3] + f_in  # residual = sum contributions - f  -> contributions
        react_t = np.einsum("nij,nj->ni", self.RN, Fn[:, 3:6] + np.einsum("nji,nj->ni", self.RN, t_in))
        self.fN = np.where(free_nodes[:, 0:3], f_in, react_f)
        self.tN = np.where(free_nodes[:, 3:6], t_in, react_t)

    def _external_power(self) -> float:
        zN = self._split_cfg_rates(self.yd)[0]
        w = np.einsum("nij,nj->ni", self.RN, zN[:, 3:6])
        p_nodes = np.sum(self.fN * zN[:, 0:3]) + np.sum(self.tN * w)
        return float(p_nodes + np.sum(self.mass[:, None] * self.gravity * self.v[:, 0:3]))

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
        F = self._residual(self.yd, (self.xN, self.RN, self.x0, self.R0, self.eta, self.v), (f_in, t_in))[0]
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
                res, _, Fy = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, zero_v, zero_yd, True)
                F = np.bincount(self._rows.ravel(), res.ravel(), minlength=L.ny)
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
    def outputs(self) -> dict[str, PortValues]:
        zN = self._split_cfg_rates(self.yd)[0]
        out = {}
        for p in self.data.ports:
            k = p.node
            out[p.name] = PortValues(
                r=self.xN[k].copy(),
                R=self.RN[k].copy(),
                v=zN[k, 0:3].copy(),
                w=self.RN[k] @ zN[k, 3:6],
                f=self.fN[k].copy(),
                t=self.tN[k].copy(),
            )
        return out

    def elastic_coordinates(self) -> np.ndarray:
        """q_bar of every superelement (E, n) at the current state, eq. (89)."""
        nodes = self.se_nodes
        return self._elastic(self.xN[nodes], self.RN[nodes], self.x0, np.swapaxes(self.R0, -1, -2), self.eta)[0]

    def energies(self) -> dict[str, float]:
        """The split (20): rigid kinetic, elastic kinetic 1/2 r^T M r, strain 1/2 q^T K q, external work."""
        v0, Om, rb = self.v[:, 0:3], self.v[:, 3:6], self.v[:, 6:]
        q = self.elastic_coordinates()
        return {
            "kinetic_rigid": float(0.5 * np.sum(self.mass * np.sum(v0 * v0, 1)) + 0.5 * np.einsum("ei,eij,ej->", Om, self.J0, Om)),
            "kinetic_elastic": float(0.5 * np.einsum("ei,eij,ej->", rb, self.M, rb)),
            "strain": float(0.5 * np.einsum("ei,eij,ej->", q, self.K, q)),
            "work_external": float(self.work),
        }

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


# ---- frozen copy of simulate.record of the same revision (benchmark baseline only)
def record(system):
    from ffrf_fmu.simulate import ENERGIES, flatten_port

    outs = system.outputs()
    e = system.energies()
    vals = [flatten_port(outs[p.name]) for p in system.data.ports]
    return np.concatenate(vals + [np.array([e[k] for k in ENERGIES] + [system.iterations])])
