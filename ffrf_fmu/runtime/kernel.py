"""The Newton loop of one generalized-alpha step as ONE compiled numba function (backend `numba`).

Self-contained on purpose (imports numpy and numba only): `runtime/compiled.py` copies this file
into a user cache directory named by its content hash and imports it from there, so numba's
on-disk cache (cache=True) serves every later process and FMU instantiation with the same code.

It computes what the numpy backend computes (runtime/fused.py, runtime/integrator.py), in the same
order of decisions, written as plain loops after runtime/equations.py (the oracle; equation numbers
there): per superelement the boundary coordinates (89), their rates (91), the residual rows (69),
(77)-(79) [+ the gyroscopic terms (53), (55)] and, when the iteration matrix is refreshed, the local
Jacobian blocks; the iteration matrix F_ydot + beta [F_y T, F_v] on the unknowns in the Newton
order; its LU (LAPACK getrf, the routine scipy's lu_factor calls, so the factors are identical);
modified Newton with the factorization carried along the rotation of the first CM frame.

Term sets covered: `linear`, `gyroscopic` (gyro = CORIOLIS | COUPLING), `full` (its switches: either part
of gyro, W1 possibly zero, W2 possibly absent), each with or without the geometric stiffening of runtime/stiffening.py (stiff = 1:
the deformation-dependent inertia W1 [W2] and, when vk_a has rows, the membrane strain); the
spring-dampers of compliant ports (runtime/coupling.py).
Anything else is refused by compiled.py.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np
from numba.np.linalg import _LAPACK, ensure_lapack

ensure_lapack()
_getrf = _LAPACK().numba_xxgetrf(numba.float64)  # numba's binding of LAPACK dgetrf (scipy's cython_lapack)
_KIND = ord("d")
_EPS = 1e-5  # runtime/rotation.py: below this angle the series of the tangent are exact to round-off

# the gyroscopic terms' two parts (flag gyro, bits): the elastic Coriolis G(W0) (53) in (78)-(79), the
# inertia coupling s = S(q) r (55) in (77) (BodySystem.coriolis, .coupling)
CORIOLIS, COUPLING = 1, 2

# status codes of `newton_step`
OK, NOT_FINITE, NOT_CONVERGED, NOT_FACTORED, ROTATION_ALIAS = 0, 1, 2, 3, 4

jit = numba.njit(cache=True, nogil=True)
# A function compiled on its own has its library optimized and emitted by LLVM with its whole callee
# tree linked in, and again in its caller's, down the chain (docs/benchmarks.md, compile section). The thin
# layers called from one site (`step` in `advance`, `_evaluate` and `_work` in `newton_step`) are inlined
# into their caller at numba's IR level instead: one optimization of the tree fewer. Not the whole tree:
# numba's own passes over the one huge function that makes took 354 s, LLVM 39 s. Numerics unchanged (no
# fast-math: LLVM keeps IEEE results whatever it inlines). A call of an inlined function takes at most
# 30 arguments (Python passes more as *args, which numba cannot inline).
inlined = numba.njit(cache=True, nogil=True, inline="always")

_Work = namedtuple("_Work", "q qd g rho Q H alpha x0 W0 x0dot v vdot u c v3 v3b GW h torque Gq Gqd Gr Grd dsdq fa "
                            "Dq Dqd dgz dgy S S2 B W0x C QC T1 Bq Nk Z Jq Jqd hs Kt eq V Vd Kc HQ")


@inlined
def _work(n, nb, nc, nv, r, n2):
    """Work arrays of `_superelement` and `_jacobian`, allocated once per step."""
    ncv = nc + nv
    z3 = np.zeros
    return _Work(z3(n), z3(n), z3(n), z3((nb, 3)), z3((nb, 3, 3)), z3((nb, 3, 3)), z3((nb, 3)), z3(3), z3(3), z3(3),
                 z3(nv), z3(nv), z3((nb, 3)), z3((nb, 3)), z3(3), z3(3), z3((n, n)), z3(3), z3(3), z3((3, n)),
                 z3((3, n)), z3((3, n)), z3((3, n)), z3((3, n)), z3((nb, 3)), z3((n, nc)), z3((n, nc)), z3((n, ncv)),
                 z3((n, ncv)), z3((3, 3)), z3((3, 3)), z3((3, 3)), z3((3, 3)), z3((3, 3)), z3((3, 3)), z3((3, nc)),
                 z3((r, n)), z3(r), z3((3, n)), z3((3, 3)), z3((3, 3)), z3(3), z3((n, n)), z3((3, n)), z3((n2, 3, 3)), z3((n2, 3, 3)),
                 z3((n2, n2)), z3((3, n)))


@jit
def _expm(th, out):
    """exp(skew(th)) through the unit quaternion (cos(t/2), sin(t/2)/t th), as rotation.expm."""
    t2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2]
    half = np.sqrt(0.25 * t2)
    w = np.cos(half)
    s = np.sin(half) / half if half > 0.0 else 0.0
    x, y, z = 0.5 * s * th[0], 0.5 * s * th[1], 0.5 * s * th[2]
    d = w * w - x * x - y * y - z * z
    out[0, 0], out[1, 1], out[2, 2] = d + 2 * x * x, d + 2 * y * y, d + 2 * z * z
    out[0, 1], out[1, 0] = 2 * (x * y - w * z), 2 * (x * y + w * z)
    out[0, 2], out[2, 0] = 2 * (x * z + w * y), 2 * (x * z - w * y)
    out[1, 2], out[2, 1] = 2 * (y * z - w * x), 2 * (y * z + w * x)


@jit
def _tangent(th, out):
    """T(th) = I - b skew(th) + c skew(th)^2 (rotation.tangent)."""
    t2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2]
    t = np.sqrt(t2)
    if t < _EPS:
        b, c = 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0
    else:
        b, c = (1.0 - np.cos(t)) / t2, (t - np.sin(t)) / (t2 * t)
    S = np.zeros((3, 3))
    _skew(th, S)
    for i in range(3):
        for j in range(3):
            ss = 0.0
            for k in range(3):
                ss += S[i, k] * S[k, j]
            out[i, j] = (1.0 if i == j else 0.0) - b * S[i, j] + c * ss


@jit
def _copy(dst, d0, src, s0, n):
    """dst.flat[d0:d0 + n] = src.flat[s0:s0 + n], dst C-contiguous (a kernel buffer). A loop on purpose:
    numba's array-to-array assignment (a[:k] = b, a[i] = b) compiles its shape-mismatch message with
    numba's string functions, which the kernel otherwise never needs (docs/benchmarks.md, compile times)."""
    d, s = dst.reshape(dst.size), src.ravel()  # a view, and a view of a C-contiguous source (else a copy)
    for i in range(n):
        d[d0 + i] = s[s0 + i]


@jit
def _put_rotation(motion, k, s, Rd, wd, RN_p, zN_p, R_in, w_in):
    """A port's rotation Rd and world angular velocity wd at the step's end: a motion-driven rotation
    into the node's prescribed frame RN_p[k] and body-axes rate zN_p[k, 3:] = Rd^T wd, else into the
    compliant spring's input slot s (R_in, w_in). Shared by the scene's schedule and the held inputs."""
    if motion:
        _copy(RN_p, 9 * k, Rd, 0, 9)
        for i in range(3):
            zN_p[k, 3 + i] = wd[0] * Rd[0, i] + wd[1] * Rd[1, i] + wd[2] * Rd[2, i]
    else:
        _copy(R_in, 9 * s, Rd, 0, 9)
        _copy(w_in, 3 * s, wd, 0, 3)


@jit
def _skew(a, out):
    out[0, 0], out[0, 1], out[0, 2] = 0.0, -a[2], a[1]
    out[1, 0], out[1, 1], out[1, 2] = a[2], 0.0, -a[0]
    out[2, 0], out[2, 1], out[2, 2] = -a[1], a[0], 0.0


@jit
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@jit
def _superelement(e, N, gyro, K, M, G, stiff, W1, W2, vk_a, vk_B, mass, J0, X_B, nodes, cfg, vel, gravity, p, yd, R, jac, F, Fz, Fy, w):
    """Local residual rows F (nv + nc) of superelement e and, if jac, F_ydot (Fz) and F_y (Fy)
    (runtime/equations.py residual_and_jacobian, the same rows and columns). w: work arrays."""
    n, nb, nc, nv = K.shape[1], X_B.shape[1], cfg.shape[1], vel.shape[1]
    nm = n - 6 * nb
    ncv = nc + nv
    q, qd, g = w.q, w.qd, w.g
    rho, Q, H, alpha = w.rho, w.Q, w.H, w.alpha
    R0 = R[N + e]
    x0, W0, x0dot = w.x0, w.W0, w.x0dot
    for i in range(3):
        x0[i] = p[cfg[e, i]]
        x0dot[i] = yd[cfg[e, i]]
        W0[i] = yd[cfg[e, 3 + i]]
    v = w.v
    vdot = w.vdot
    for i in range(nv):
        v[i] = p[vel[e, i]]
        vdot[i] = yd[vel[e, i]]
    # ---- boundary coordinates (89) and their rates (91), node by node
    for k in range(nb):
        P = nodes[e, k]
        base = 6 + nm + 6 * k
        for i in range(3):
            s1 = 0.0
            s2 = 0.0
            for j in range(3):
                s1 += R0[j, i] * (p[cfg[e, base + j]] - x0[j])
                s2 += R0[j, i] * (yd[cfg[e, base + j]] - x0dot[j])
            rho[k, i] = s1
            w.u[k, i] = s2
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += R0[m, i] * R[P, m, j]
                Q[k, i, j] = s
        alpha[k, 0] = 0.5 * (Q[k, 2, 1] - Q[k, 1, 2])
        alpha[k, 1] = 0.5 * (Q[k, 0, 2] - Q[k, 2, 0])
        alpha[k, 2] = 0.5 * (Q[k, 1, 0] - Q[k, 0, 1])
        tr = Q[k, 0, 0] + Q[k, 1, 1] + Q[k, 2, 2]
        for i in range(3):
            for j in range(3):
                H[k, i, j] = 0.5 * ((tr if i == j else 0.0) - Q[k, j, i])
        c = w.c[k]
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += Q[k, j, i] * W0[j]
            c[i] = yd[cfg[e, base + 3 + i]] - s
        rxW = w.v3
        _cross(rho[k], W0, rxW)
        for i in range(3):
            q[6 * k + i] = rho[k, i] - X_B[e, k, i]
            q[6 * k + 3 + i] = alpha[k, i]
            qd[6 * k + i] = w.u[k, i] + rxW[i]
            s = 0.0
            for j in range(3):
                s += H[k, i, j] * c[j]
            qd[6 * k + 3 + i] = s
    for i in range(nm):
        q[6 * nb + i] = p[cfg[e, 6 + i]]
        qd[6 * nb + i] = yd[cfg[e, 6 + i]]
    r = v[6:]
    rdot = vdot[6:]
    Ke, Me, Je = K[e], M[e], J0[e]
    # ---- residual rows
    for i in range(3):
        F[i] = x0dot[i] - v[i]  # (69b)
        F[3 + i] = W0[i] - v[3 + i]  # (69d)
    GW = w.GW
    if gyro & CORIOLIS:
        for i in range(n):
            for j in range(n):
                GW[i, j] = W0[0] * G[e, 0, i, j] + W0[1] * G[e, 1, i, j] + W0[2] * G[e, 2, i, j]
    for i in range(n):  # (79) and (78)
        s1 = 0.0
        s2 = 0.0
        for j in range(n):
            s1 += Me[i, j] * (qd[j] - r[j])
            s2 += Ke[i, j] * q[j] + Me[i, j] * rdot[j]
            if gyro & CORIOLIS:
                s1 += GW[i, j] * q[j]
                s2 += GW[i, j] * r[j]
        F[6 + i] = s1
        g[i] = s2
    h, torque = w.h, w.torque
    for i in range(3):
        s1 = 0.0
        s2 = 0.0
        for j in range(3):
            s1 += Je[i, j] * v[3 + j]
            s2 += Je[i, j] * vdot[3 + j]
        h[i] = s1
        torque[i] = s2
    if gyro:  # G_k q, G_k qdot; s_k = r^T G_k q (55), sdot_k = rdot^T G_k q + r^T G_k qdot
        for kk in range(3):
            for i in range(n):
                s1 = 0.0
                s2 = 0.0
                for j in range(n):
                    s1 += G[e, kk, i, j] * q[j]
                    s2 += G[e, kk, i, j] * qd[j]
                w.Gq[kk, i] = s1
                w.Gqd[kk, i] = s2
            s = 0.0
            sd = 0.0
            for i in range(n):
                s += r[i] * w.Gq[kk, i]
                sd += rdot[i] * w.Gq[kk, i] + r[i] * w.Gqd[kk, i]
            if gyro & COUPLING:
                h[kk] += s
                torque[kk] += sd
    ex0, eT0, eeta = nv, nv + 3, nv + 6
    if stiff:  # geometric stiffening (runtime/stiffening.py elastic_force): g += f_vk(q) - f0(Omega0)
        _stiff_force(e, W1, W2, vk_a, vk_B, q, v[3:6], g, w)
    _cross(W0, h, w.v3)
    for i in range(3):
        F[eT0 + i] = torque[i] + w.v3[i]  # (77)
        F[ex0 + i] = mass[e] * vdot[i] - mass[e] * gravity[i]  # (69a)
    for i in range(nm):
        F[eeta + i] = g[6 * nb + i]
    for k in range(nb):  # g_B through (91)
        exP, eTP = nv + 6 + nm + 6 * k, nv + 9 + nm + 6 * k
        for i in range(3):
            s1 = 0.0
            s2 = 0.0
            for j in range(3):
                s1 += R0[i, j] * g[6 * k + j]
                s2 += H[k, j, i] * g[6 * k + 3 + j]
            F[exP + i] = s1
            F[ex0 + i] -= s1
            F[eTP + i] = s2
            w.fa[k, i] = s2
        _cross(rho[k], g[6 * k : 6 * k + 3], w.v3)
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += Q[k, i, j] * w.fa[k, j]
            F[eT0 + i] -= w.v3[i] + s
    if stiff:  # stiffening.rotation_rows: W0 x (Jq Omega0) + Jq Omega0dot + Jqd Omega0, Jq = W1 q [+ q W2 q]
        Om, Omd = v[3:6], vdot[3:6]
        Jq, Jqd, HQ = w.Jq, w.Jqd, w.HQ
        for a in range(3):
            for b in range(3):
                s1 = 0.0
                s2 = 0.0
                for j in range(n):
                    s1 += q[j] * W1[e, j, a, b]
                    s2 += qd[j] * W1[e, j, a, b]
                Jq[a, b] = s1
                Jqd[a, b] = s2
            for j in range(n):
                HQ[a, j] = w.Z[a, j]  # dh/dq = Z [+ V_j Omega0]
        if W2.shape[1] > 0:  # V_j = sum_l q_l (W2_jl + W2_lj), Vd_j the same with qdot (deformed_inertia)
            V, Vd = w.V, w.Vd
            for j in range(n):
                for a in range(3):
                    for b in range(3):
                        s1 = 0.0
                        s2 = 0.0
                        for l in range(n):
                            wjl = W2[e, j, l, a, b] + W2[e, l, j, a, b]
                            s1 += q[l] * wjl
                            s2 += qd[l] * wjl
                        V[j, a, b] = s1
                        Vd[j, a, b] = s2
            for a in range(3):
                for b in range(3):
                    s1 = 0.0
                    s2 = 0.0
                    for j in range(n):
                        s1 += q[j] * V[j, a, b]
                        s2 += qd[j] * V[j, a, b]
                    Jq[a, b] += 0.5 * s1  # q W2 q = 1/2 sum_j q_j V_j
                    Jqd[a, b] += s2
                for j in range(n):
                    s = 0.0
                    for b in range(3):
                        s += V[j, a, b] * Om[b]
                    HQ[a, j] += s
        for a in range(3):
            s = 0.0
            for b in range(3):
                s += Jq[a, b] * Om[b]
            w.hs[a] = s
        _cross(W0, w.hs, w.v3)
        for a in range(3):
            s = w.v3[a]
            for b in range(3):
                s += Jq[a, b] * Omd[b] + Jqd[a, b] * Om[b]
            F[eT0 + a] += s
    if jac:
        _jacobian(e, gyro, Ke, Me, G, stiff, W1, W2, vk_a, vk_B, mass, Je, nb, nm, n, nc, nv, ncv, q, qd, r, rdot, g, h, W0, R0, w, Fz, Fy)


@jit
def _stiff_force(e, W1, W2, vk_a, vk_B, q, Om, g, w):
    """g += f_vk(q) - f0(Omega0) [- Kc(Omega0) q] (stiffening.von_karman, deformed_inertia); keeps Bq,
    N = a q + sigma, Z(Omega0) (Z[:, j] = W1_j Omega0) [and Kc] in w for the Jacobian and the rotation rows.
    W2 (E, n, n, 3, 3), or (E, 0, 0, 3, 3) without the quadratic inertia term."""
    r, n = vk_a.shape[1], q.shape[0]
    Bq, Nk, Z = w.Bq, w.Nk, w.Z
    for k in range(r):
        ek = 0.0
        sk = 0.0
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += vk_B[e, k, i, j] * q[j]
            Bq[k, i] = s
            ek += vk_a[e, k, i] * q[i]
        for i in range(n):
            sk += 0.5 * Bq[k, i] * q[i]
        Nk[k] = ek + sk
        for i in range(n):  # a^T sigma + Bq^T N
            g[i] += vk_a[e, k, i] * sk + Bq[k, i] * Nk[k]
    for j in range(n):
        s = 0.0
        for a in range(3):
            za = 0.0
            for b in range(3):
                za += W1[e, j, a, b] * Om[b]
            Z[a, j] = za
            s += za * Om[a]
        g[j] -= 0.5 * s
    if W2.shape[1] > 0:  # the elastic centrifugal force -Kc(Omega0) q, Kc_jl = Omega0^T W2_jl Omega0
        Kc = w.Kc
        for j in range(n):
            s = 0.0
            for l in range(n):
                kc = 0.0
                for a in range(3):
                    for b in range(3):
                        kc += Om[a] * W2[e, j, l, a, b] * Om[b]
                Kc[j, l] = kc
                s += kc * q[l]
            g[j] -= s


@jit
def _stiff_tangent(e, vk_a, vk_B, n, w):
    """Kt = a^T Bq + Bq^T a + Bq^T Bq + sum_k N_k B_k (stiffening.von_karman) into w.Kt."""
    r = vk_a.shape[1]
    Bq, Nk, Kt = w.Bq, w.Nk, w.Kt
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(r):
                s += vk_a[e, k, i] * Bq[k, j] + Bq[k, i] * (vk_a[e, k, j] + Bq[k, j]) + Nk[k] * vk_B[e, k, i, j]
            Kt[i, j] = s


@jit
def _jacobian(e, gyro, Ke, Me, G, stiff, W1, W2, vk_a, vk_B, mass, Je, nb, nm, n, nc, nv, ncv, q, qd, r, rdot, g, h, W0, R0, w, Fz, Fy):
    """The local Jacobian blocks of `_superelement` (runtime/equations.py, same algebra)."""
    rho, Q, H, alpha = w.rho, w.Q, w.H, w.alpha
    Dq, Dqd, dgz, dgy = w.Dq, w.Dqd, w.dgz, w.dgy
    S, S2, B = w.S, w.S2, w.B
    Fz[:, :] = 0.0
    Fy[:, :] = 0.0
    Dq[:, :] = 0.0
    Dqd[:, :] = 0.0
    dgz[:, :] = 0.0
    dgy[:, :] = 0.0
    W0x = w.W0x
    _skew(W0, W0x)
    for k in range(nb):
        XP, TP = 6 + nm + 6 * k, 9 + nm + 6 * k
        d, a = 6 * k, 6 * k + 3
        _skew(rho[k], S)
        for i in range(3):
            for j in range(3):
                Dq[d + i, j] = -R0[j, i]  # d d_P = -R0^T dx0 + skew(rho) dTheta0 + R0^T dx_P
                Dq[d + i, 3 + j] = S[i, j]
                Dq[d + i, XP + j] = R0[j, i]
                Dq[a + i, TP + j] = H[k, i, j]  # d alpha_P = H (dTheta_P - Q^T dTheta0)
                s = 0.0
                for m in range(3):
                    s += H[k, i, m] * Q[k, j, m]
                Dq[a + i, 3 + j] = -s
        # d(d_Pdot) = skew(u) dTheta0 - skew(W0) d(d_P)
        _skew(w.u[k], S)
        for i in range(3):
            for j in range(nc):
                s = 0.0
                for m in range(3):
                    s -= W0x[i, m] * Dq[d + m, j]
                Dqd[d + i, j] = s
            for j in range(3):
                Dqd[d + i, 3 + j] += S[i, j]
        # d(H c) = B eps, B = -c alpha^T - skew(Q^T c)/2 - H skew(Q^T W0)
        c = w.c[k]
        QTc, QTW = w.v3, w.v3b
        for i in range(3):
            s1 = 0.0
            s2 = 0.0
            for j in range(3):
                s1 += Q[k, j, i] * c[j]
                s2 += Q[k, j, i] * W0[j]
            QTc[i] = s1
            QTW[i] = s2
        _skew(QTc, S)
        _skew(QTW, S2)
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += H[k, i, m] * S2[m, j]
                B[i, j] = -c[i] * alpha[k, j] - 0.5 * S[i, j] - s
        for i in range(3):
            for j in range(3):
                Dqd[a + i, TP + j] = B[i, j]
                s = 0.0
                for m in range(3):
                    s += B[i, m] * Q[k, j, m]
                Dqd[a + i, 3 + j] = -s
    for i in range(nm):
        Dq[6 * nb + i, 6 + i] = 1.0
    cv0, cO0, cr = nc, nc + 3, nc + 6
    kq, ex0, eT0, eeta = 6, nv, nv + 3, nv + 6
    for i in range(3):
        Fz[i, i] = 1.0  # x0dot - v0
        Fy[i, cv0 + i] = -1.0
        Fz[3 + i, 3 + i] = 1.0  # W0 - Omega0
        Fy[3 + i, cO0 + i] = -1.0
        Fz[ex0 + i, cv0 + i] = mass[e]
    for i in range(n):  # k_q = M (qdot - r) [+ G(W0) q]; g = K q + M rdot [+ G(W0) r]
        for j in range(nc):
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            for m in range(n):
                s1 += Me[i, m] * Dq[m, j]
                s2 += Me[i, m] * Dqd[m, j]
                s3 += Ke[i, m] * Dq[m, j]
            Fz[kq + i, j] = s1
            Fy[kq + i, j] = s2
            dgy[i, j] = s3
        for j in range(n):
            Fy[kq + i, cr + j] = -Me[i, j]
            dgz[i, cr + j] = Me[i, j]
    # angular momentum rows: J0 Omega0dot + W0 x h
    for i in range(3):
        for j in range(3):
            Fz[eT0 + i, cO0 + j] = Je[i, j]
            s = 0.0
            for m in range(3):
                s += W0x[i, m] * Je[m, j]
            Fy[eT0 + i, cO0 + j] = s
    _skew(h, S)  # h includes s for the gyroscopic set
    for i in range(3):
        for j in range(3):
            Fz[eT0 + i, 3 + j] -= S[i, j]
    if gyro:
        GW, Gq, Gqd, Gr, Grd = w.GW, w.Gq, w.Gqd, w.Gr, w.Grd
        for kk in range(3):
            for i in range(n):
                s1 = 0.0
                s2 = 0.0
                s3 = 0.0
                s4 = 0.0
                for j in range(n):
                    s1 += G[e, kk, i, j] * r[j]
                    s2 += r[j] * G[e, kk, j, i]  # (r^T G_k)_i
                    s3 += rdot[j] * G[e, kk, j, i]  # (rdot^T G_k)_i
                Gr[kk, i] = s1
                w.dsdq[kk, i] = s2
                Grd[kk, i] = s3
        for i in range(n if gyro & CORIOLIS else 0):
            for kk in range(3):
                Fz[kq + i, 3 + kk] += Gq[kk, i]  # d(G(W0) q)/dW0
                dgz[i, 3 + kk] += Gr[kk, i]
            for j in range(nc):
                s = 0.0
                for m in range(n):
                    s += GW[i, m] * Dq[m, j]
                Fy[kq + i, j] += s
            for j in range(n):
                dgy[i, cr + j] += GW[i, j]
    if gyro & COUPLING:  # s and sdot: rows of ds/dq, ds/dr, dsdot/d...
        GW, Gq, Gqd, Gr, Grd = w.GW, w.Gq, w.Gqd, w.Gr, w.Grd
        T1 = w.T1  # (3, nc): ds_dq Dq ; T2 = rdot^T G_k Dq ; T3 = ds_dq Dqd
        for kk in range(3):
            for j in range(nc):
                s1 = 0.0
                s2 = 0.0
                s3 = 0.0
                for m in range(n):
                    s1 += w.dsdq[kk, m] * Dq[m, j]
                    s2 += Grd[kk, m] * Dq[m, j]
                    s3 += w.dsdq[kk, m] * Dqd[m, j]
                T1[kk, j] = s1
                Fy[eT0 + kk, j] += s2 + s3
                Fz[eT0 + kk, j] += s1
            for j in range(n):
                Fz[eT0 + kk, cr + j] += Gq[kk, j]
                Fy[eT0 + kk, cr + j] += Gqd[kk, j]
        for i in range(3):
            for j in range(nc):
                s = 0.0
                for m in range(3):
                    s += W0x[i, m] * T1[m, j]
                Fy[eT0 + i, j] += s
            for j in range(n):
                s = 0.0
                for m in range(3):
                    s += W0x[i, m] * Gq[m, j]
                Fy[eT0 + i, cr + j] += s
    if stiff:  # d(f_vk - f0 [- Kc q]): (Kt [- Kc]) Dq on the configuration, -HQ^T on the Omega0 columns
        Kt = w.Kt
        _stiff_tangent(e, vk_a, vk_B, n, w)
        if W2.shape[1] > 0:
            for i in range(n):
                for j in range(n):
                    Kt[i, j] -= w.Kc[i, j]
        for i in range(n):
            for j in range(nc):
                s = 0.0
                for m in range(n):
                    s += Kt[i, m] * Dq[m, j]
                dgy[i, j] += s
            for b in range(3):
                dgy[i, cO0 + b] -= w.HQ[b, i]
    for i in range(nm):
        for j in range(ncv):
            Fz[eeta + i, j] = dgz[6 * nb + i, j]
            Fy[eeta + i, j] = dgy[6 * nb + i, j]
    # g_B through (91): equations.project_boundary_force
    C, QC = w.C, w.QC
    for k in range(nb):
        exP, eTP = nv + 6 + nm + 6 * k, nv + 9 + nm + 6 * k
        TP = 9 + nm + 6 * k
        d, a = 6 * k, 6 * k + 3
        gd, ga = g[d : d + 3], g[a : a + 3]
        ya = w.v3
        for D, dg in ((Fz, dgz), (Fy, dgy)):
            for j in range(ncv):
                for i in range(3):
                    s1 = 0.0
                    s2 = 0.0
                    for m in range(3):
                        s1 += R0[i, m] * dg[d + m, j]
                        s2 += H[k, m, i] * dg[a + m, j]
                    D[exP + i, j] += s1  # R0 dg_d
                    D[ex0 + i, j] -= s1
                    D[eTP + i, j] += s2  # H^T dg_a
                    ya[i] = s2
                for i in range(3):  # -(rho x dg_d + Q H^T dg_a)
                    s = rho[k, (i + 1) % 3] * dg[d + (i + 2) % 3, j] - rho[k, (i + 2) % 3] * dg[d + (i + 1) % 3, j]
                    for m in range(3):
                        s += Q[k, i, m] * ya[m]
                    D[eT0 + i, j] -= s
        _skew(gd, S)
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += R0[i, m] * S[m, j]
                Fy[exP + i, 3 + j] -= s  # d(R0 g_d) = -R0 skew(g_d) dTheta0 + ...
                Fy[ex0 + i, 3 + j] += s
        # C = -g_a alpha^T + Q skew(g_a)/2 on the node rotation rows
        _skew(ga, S2)
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += Q[k, i, m] * S2[m, j]
                C[i, j] = -ga[i] * alpha[k, j] + 0.5 * s
        for i in range(3):
            for j in range(3):
                Fy[eTP + i, TP + j] += C[i, j]
                s = 0.0
                for m in range(3):
                    s += C[i, m] * Q[k, j, m]
                Fy[eTP + i, 3 + j] -= s
        # CM rotation rows: + skew(g_d) Dq_d, and -Q (C - skew(f_a)) eps
        for i in range(3):
            for j in range(nc):
                s = 0.0
                for m in range(3):
                    s += S[i, m] * Dq[d + m, j]
                Fy[eT0 + i, j] += s
        _skew(w.fa[k], S2)
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += Q[k, i, m] * (C[m, j] - S2[m, j])
                QC[i, j] = s
        for i in range(3):
            for j in range(3):
                Fy[eT0 + i, TP + j] -= QC[i, j]
                s = 0.0
                for m in range(3):
                    s += QC[i, m] * Q[k, j, m]
                Fy[eT0 + i, 3 + j] += s
    if stiff:  # stiffening.rotation_rows derivatives
        Z, Jq, Jqd, eq = w.HQ, w.Jq, w.Jqd, w.eq  # Z: dh/dq = de/dqdot
        Om, Omd = w.v[3:6], w.vdot[3:6]
        for a in range(3):
            for j in range(n):
                s = 0.0
                for b in range(3):
                    s += W1[e, j, a, b] * Omd[b]
                    if W2.shape[1] > 0:
                        s += w.V[j, a, b] * Omd[b] + w.Vd[j, a, b] * Om[b]
                eq[a, j] = s  # de/dq: W1_j Omd [+ V_j Omd + Vd_j Om]
        _skew(w.hs, S)
        for i in range(3):
            for j in range(3):
                Fz[eT0 + i, 3 + j] -= S[i, j]  # d(W0 x h)/dW0
                Fz[eT0 + i, cO0 + j] += Jq[i, j]  # d/dOmega0dot
                s = Jqd[i, j]
                for m in range(3):
                    s += W0x[i, m] * Jq[m, j]
                Fy[eT0 + i, cO0 + j] += s  # W0 x (W1 q) + W1 qdot on Omega0
            for j in range(nc):
                s1 = 0.0
                s2 = 0.0
                for m in range(n):
                    zw = eq[i, m]
                    for b in range(3):
                        zw += W0x[i, b] * Z[b, m]
                    s1 += Z[i, m] * Dq[m, j]
                    s2 += zw * Dq[m, j] + Z[i, m] * Dqd[m, j]
                Fz[eT0 + i, j] += s1
                Fy[eT0 + i, j] += s2


@inlined
def _evaluate(N, const, f_load, t_load, p, yd, R, theta, jac, beta, F, JT, w, Fl, Fz, Fy, T):
    """Assembled residual F (ny) with the loads and, if jac, the iteration matrix
    J = F_ydot + beta [F_y T, F_v] on the unknowns in the Newton order, stored transposed (JT[col, row],
    i.e. J in Fortran order, as LAPACK wants it). runtime/integrator.py `_iteration_matrix`. const: `step`'s."""
    (gyro, K, M, G, stiff, W1, W2, vk_a, vk_B, mass, J0, X_B, nodes, cfg, vel, gravity), newton_pos = const[:16], const[18]
    E, nc, nv = K.shape[0], cfg.shape[1], vel.shape[1]
    nb, nf = X_B.shape[1], JT.shape[0]
    nm = K.shape[1] - 6 * nb
    F[:] = 0.0
    if jac:
        JT[:, :] = 0.0
        for r in range(theta.shape[0]):
            _tangent(theta[r], T[r])
    tmp = w.v3b
    for e in range(E):
        _superelement(e, N, gyro, K, M, G, stiff, W1, W2, vk_a, vk_B, mass, J0, X_B, nodes, cfg, vel, gravity, p, yd, R, jac, Fl, Fz, Fy, w)
        for i in range(nv):
            F[vel[e, i]] += Fl[i]
        for i in range(nc):
            F[cfg[e, i]] += Fl[nv + i]
        if not jac:
            continue
        # d(configuration) = beta T(h Delta) d(zdot) on rotations: the Theta0 and Theta_P columns times T
        for i in range(nv + nc):
            for blk in range(nb + 1):
                col = 3 if blk == 0 else 9 + nm + 6 * (blk - 1)
                Tr = T[N + e] if blk == 0 else T[nodes[e, blk - 1]]
                for j in range(3):
                    s = 0.0
                    for m in range(3):
                        s += Fy[i, col + m] * Tr[m, j]
                    tmp[j] = s
                for j in range(3):
                    Fy[i, col + j] = tmp[j]
        for i in range(nv + nc):
            gr = newton_pos[vel[e, i]] if i < nv else newton_pos[cfg[e, i - nv]]
            if gr >= nf:
                continue
            for j in range(nc + nv):
                gc = newton_pos[cfg[e, j]] if j < nc else newton_pos[vel[e, j - nc]]
                if gc < nf:
                    JT[gc, gr] += beta * Fy[i, j] + Fz[i, j]
    # loads: -f on node translation rows, -R^T t on node rotation rows; d(-R^T t) = -skew(R^T t) dTheta
    S = w.S
    for k in range(N):
        for i in range(3):
            F[6 * k + i] -= f_load[k, i]
            s = 0.0
            for j in range(3):
                s += R[k, j, i] * t_load[k, j]
            tmp[i] = s
            F[6 * k + 3 + i] -= s
        if jac and newton_pos[6 * k + 3] < nf:
            _skew(tmp, S)
            for i in range(3):
                for j in range(3):
                    s = 0.0
                    for m in range(3):
                        s += S[i, m] * T[k, m, j]
                    JT[newton_pos[6 * k + 3 + j], newton_pos[6 * k + 3 + i]] -= beta * s


@jit
def _logm(M, out):
    """Rotation vector of M (rotation.logm: the angle atan2(sin t, cos t) of the skew part and the
    trace, accurate at every angle; near pi the axis from the symmetric part)."""
    v0, v1, v2 = 0.5 * (M[2, 1] - M[1, 2]), 0.5 * (M[0, 2] - M[2, 0]), 0.5 * (M[1, 0] - M[0, 1])
    cos = 0.5 * (M[0, 0] + M[1, 1] + M[2, 2]) - 0.5
    sin = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    t = np.arctan2(sin, cos)
    t2 = t * t
    factor = 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0 if t < 1e-2 else t / sin
    out[0], out[1], out[2] = factor * v0, factor * v1, factor * v2
    if t > np.pi - 1e-4:
        k = 0
        for i in range(3):
            if M[i, i] - cos > M[k, k] - cos:
                k = i
        col = np.empty(3)
        for i in range(3):
            col[i] = 0.5 * (M[i, k] + M[k, i]) - (cos if i == k else 0.0)
        nrm = np.sqrt(col[0] ** 2 + col[1] ** 2 + col[2] ** 2)
        sign = -1.0 if col[0] * v0 + col[1] * v1 + col[2] * v2 < 0.0 else 1.0
        for i in range(3):
            out[i] = t * sign * col[i] / nrm


@jit
def _inv3(A, out):
    """Inverse of a 3 x 3 matrix by cofactors."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    d = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    out[0, 0], out[1, 0], out[2, 0] = c00 / d, c01 / d, c02 / d
    out[0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) / d
    out[1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) / d
    out[2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) / d
    out[0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) / d
    out[1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) / d
    out[2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) / d


@jit
def _springs(springs, p, yd, R, T, jac, beta, newton_pos, F, JT):
    """The spring-dampers of compliant ports (runtime/coupling.py add_springs, the same terms): -f on
    the node translation rows, -m on the node rotation rows, their derivatives into JT (transposed
    iteration matrix) when jac, and the loads (force, moment; world) into the springs' `loads`.
    springs = (node, translation, rotation, KC (4, 3): K_t, C_t, K_r, C_r, r_in, v_in, R_in, w_in, loads)."""
    node, trans, rot, KC, r_in, v_in, R_in, w_in, loads = springs
    M, A, Ainv, S = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    phi, wb, m = np.empty(3), np.empty(3), np.empty(3)
    for s in range(node.shape[0]):
        k = node[s]
        i0 = 6 * k
        if trans[s]:
            for a in range(3):  # f = K_t (r_in - x) + C_t (v_in - xdot)
                f = KC[s, 0, a] * (r_in[s, a] - p[i0 + a]) + KC[s, 1, a] * (v_in[s, a] - yd[i0 + a])
                F[i0 + a] -= f
                loads[k, 0, a] = f
                if jac:
                    pos = newton_pos[i0 + a]
                    JT[pos, pos] += beta * KC[s, 0, a] + KC[s, 1, a]
        if rot[s]:
            Rk = R[k]
            for a in range(3):  # M = R^T R_in, wb = R^T w_in
                wb[a] = Rk[0, a] * w_in[s, 0] + Rk[1, a] * w_in[s, 1] + Rk[2, a] * w_in[s, 2]
                for b in range(3):
                    M[a, b] = Rk[0, a] * R_in[s, 0, b] + Rk[1, a] * R_in[s, 1, b] + Rk[2, a] * R_in[s, 2, b]
            _logm(M, phi)
            for a in range(3):  # m = K_r phi + C_r (R^T w_in - W)
                m[a] = KC[s, 2, a] * phi[a] + KC[s, 3, a] * (wb[a] - yd[i0 + 3 + a])
                F[i0 + 3 + a] -= m[a]
            for a in range(3):
                loads[k, 1, a] = Rk[a, 0] * m[0] + Rk[a, 1] * m[1] + Rk[a, 2] * m[2]
            if jac:  # dm/dTheta = -K_r T(-phi)^-1 + C_r skew(R^T w_in); J += -beta dm T + diag(C_r)
                for a in range(3):
                    phi[a] = -phi[a]
                _tangent(phi, A)
                _inv3(A, Ainv)
                _skew(wb, S)
                for a in range(3):
                    for b in range(3):
                        A[a, b] = -KC[s, 2, a] * Ainv[a, b] + KC[s, 3, a] * S[a, b]  # dm/dTheta
                for a in range(3):
                    pa = newton_pos[i0 + 3 + a]
                    for b in range(3):
                        v = -beta * (A[a, 0] * T[k, 0, b] + A[a, 1] * T[k, 1, b] + A[a, 2] * T[k, 2, b])
                        if a == b:
                            v += KC[s, 3, a]
                        JT[newton_pos[i0 + 3 + b], pa] += v


@jit
def _stage_at(rot_slots, c, P0, Rn, yd, p, theta, R, Rexp):
    """The configuration at the rates yd (integrator `_stage_at`): p = c yd + P0, theta = p at the
    rotation slots (h Delta), R = Rn exp(theta)."""
    for i in range(yd.shape[0]):
        p[i] = yd[i] * c[i] + P0[i]
    for r in range(Rn.shape[0]):
        for i in range(3):
            theta[r, i] = p[rot_slots[r, i]]
        _expm(theta[r], Rexp)
        for i in range(3):
            for j in range(3):
                R[r, i, j] = Rn[r, i, 0] * Rexp[0, j] + Rn[r, i, 1] * Rexp[1, j] + Rn[r, i, 2] * Rexp[2, j]


@jit
def newton_step(const, stale, trusted, c, P0, Rn, f_load, t_load, springs, beta, tol, max_iter, yd, p, R, F, luT, piv, lu_meta, info):
    """Newton on the rates ydot_{n+1} of one step (runtime/integrator.py `_step`, the same decisions);
    const: `step`'s.

    In: the stage p = c ydot + P0, R = Rn exp(theta) (theta = p at rot_slots); the loads; yd holds the
    predictor. Out: yd the accepted rates, p, R their configuration, F the residual of the last
    evaluation (the accepted iterate is not evaluated again). luT, piv,
    lu_meta = [valid, beta, R_ref (9), serves] hold the LU of the iteration matrix across steps (transposed:
    luT.T is scipy's lu_factor LU; piv 0-based); returns (luT, piv), new arrays after a refresh (the
    arguments are only read). info = [status, iterations]; lu_meta[0] = 0 and
    a status != OK on failure, with the last increment in lu_meta[1] for NOT_CONVERGED.
    Convergence and refresh as integrator `_newton`: increments scaled per field (field_of), accepted
    on the contraction estimate theta/(1 - theta) |dx|; serves as there (keep = KEEP_CONTRACTION, keep_miss =
    KEEP_MISS; stale:
    luT, piv, lu_meta hold the matrix REFRESH_AFTER dropped, which the first refresh compares; trusted:
    REFRESH_AFTER kept it on its serves verdict)."""
    K, X_B, cfg, vel, W2, vk_a = const[1], const[11], const[13], const[14], const[6], const[7]
    rot_slots, newton_idx, newton_pos, k3, field_of, theta_refresh, keep, keep_miss = const[16:24]
    NR, E = Rn.shape[0], K.shape[0]
    N = NR - E
    n, nb, nc, nv = K.shape[1], X_B.shape[1], cfg.shape[1], vel.shape[1]
    ny, nf = yd.shape[0], newton_idx.shape[0]
    w = _work(n, nb, nc, nv, vk_a.shape[1], W2.shape[1])
    Fl, Fz, Fy = np.zeros(nv + nc), np.zeros((nv + nc, nc + nv)), np.zeros((nv + nc, nc + nv))
    theta, T, Rexp = np.zeros((NR, 3)), np.zeros((NR, 3, 3)), np.zeros((3, 3))
    JT = np.zeros((0, 0))  # the iteration matrix, allocated on the first refresh of the step
    b, P = np.zeros(nf), np.zeros((3, 3))
    b_stale, ref_stale, luT_stale, piv_stale = np.zeros(nf), np.zeros(9), luT, piv
    kept, serves, use_stale, far = True, False, False, False  # kept: no matrix built in this step (yet)
    n_fields = 0
    for i in range(nf):
        n_fields = max(n_fields, field_of[i] + 1)
    S = np.zeros(n_fields)
    nrm_prev = np.inf
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        refresh = lu_meta[0] == 0.0 or abs(lu_meta[1] - beta) > 1e-6 * beta
        if refresh and JT.shape[0] != nf:
            JT = np.zeros((nf, nf))
        _stage_at(rot_slots, c, P0, Rn, yd, p, theta, R, Rexp)
        _evaluate(N, const, f_load, t_load, p, yd, R, theta, refresh, beta, F, JT, w, Fl, Fz, Fy, T)
        _springs(springs, p, yd, R, T, refresh, beta, newton_pos, F, JT)
        s = 0.0
        for i in range(ny):
            s += F[i] * 0.0
        if s != 0.0 or s != s:  # NaN: some entry of F is not finite
            lu_meta[0] = 0.0
            info[0], info[1] = NOT_FINITE, it
            return luT, piv
        if refresh:
            kept = False
            use_stale = stale and it == 1 and abs(lu_meta[1] - beta) <= 1e-6 * beta
            if use_stale:  # the dropped matrix, compared with the new one after the solve
                luT_stale, piv_stale = luT, piv
                for i in range(9):
                    ref_stale[i] = lu_meta[2 + i]
            # factored in place of the new matrix, with new pivots: a factorization is never overwritten
            # (a rollback snapshot shares it, BodySystem.snapshot); the next refresh builds a new matrix
            ok = True
            for i in range(nf):
                for j in range(nf):
                    v = JT[i, j]
                    if not (v - v == 0.0):
                        ok = False
            luT, piv = JT, np.empty(nf, dtype=np.int32)
            JT = np.zeros((0, 0))
            status = _getrf(_KIND, nf, nf, luT.ctypes, nf, piv.ctypes) if ok else -1
            if status != 0:
                lu_meta[0] = 0.0
                info[0], info[1] = NOT_FACTORED, it
                return luT, piv
            for i in range(nf):
                piv[i] -= 1
            lu_meta[0], lu_meta[1] = 1.0, beta
            for i in range(3):
                for j in range(3):
                    lu_meta[2 + 3 * i + j] = R[N, i, j]
        _corotated_solve(luT, piv, lu_meta[2:11], R[N], F, newton_idx, k3, P, b)
        if use_stale:
            _corotated_solve(luT_stale, piv_stale, ref_stale, R[N], F, newton_idx, k3, P, b_stale)
        for i in range(nf):
            yd[newton_idx[i]] -= b[i]
        S[:] = 0.0  # the largest rate of each field, at the new iterate
        for i in range(nf):
            S[field_of[i]] = max(S[field_of[i]], abs(yd[newton_idx[i]]))
        nrm = 0.0
        for i in range(nf):
            nrm = max(nrm, abs(b[i]) / (tol / beta + tol * S[field_of[i]]))
        rate = nrm / nrm_prev  # the contraction theta of integrator `_newton`
        if it == 1:
            far = nrm * tol > keep_miss
        if use_stale and far:  # the dropped matrix's first increment against the new one's (integrator `_newton`)
            dev = 0.0
            for i in range(nf):
                dev = max(dev, abs(b_stale[i] - b[i]) / (tol / beta + tol * S[field_of[i]]))
            serves = dev <= keep * nrm
        use_stale = False
        if nrm <= 1.0 if it == 1 else nrm <= 0.1 or (rate < 1.0 and rate / (1.0 - rate) * nrm <= 1.0):
            converged = True  # the accepted iterate's configuration, not evaluated again
            _stage_at(rot_slots, c, P0, Rn, yd, p, theta, R, Rexp)
            if kept:
                serves = it == 2 and far and rate <= keep
            break
        # slow contraction, or too slow to reach the tolerance in 3 more iterations: refresh
        if it > 1 and (rate > theta_refresh or rate**4 / (1.0 - rate) * nrm > 1.0 or (trusted and kept)):
            lu_meta[0], serves = 0.0, False
        nrm_prev = nrm
    if not converged:
        lu_meta[0], lu_meta[1] = 0.0, nrm_prev
        info[0], info[1] = NOT_CONVERGED, it
        return luT, piv
    for r in range(NR):  # integrator `_check_rotation_increments`
        if theta[r, 0] ** 2 + theta[r, 1] ** 2 + theta[r, 2] ** 2 > np.pi**2:
            lu_meta[0] = 0.0
            info[0], info[1] = ROTATION_ALIAS, it
            return luT, piv
    info[0], info[1] = OK, it
    lu_meta[11] = 1.0 if serves else 0.0
    return luT, piv


@jit
def _corotated_solve(luT, piv, ref, R_now, F, newton_idx, k3, P, b):
    """b = J^-1 F on the unknowns in the Newton order from the factorization (luT, piv) built at the first
    CM frame's rotation ref (9, row-major), carried along the rigid rotation P = R_now ref^T (integrator
    `_solve`); P is work space."""
    for i in range(3):
        for j in range(3):
            P[i, j] = R_now[i, 0] * ref[3 * j] + R_now[i, 1] * ref[3 * j + 1] + R_now[i, 2] * ref[3 * j + 2]
    for i in range(b.shape[0]):
        b[i] = F[newton_idx[i]]
    for t3 in range(0, k3, 3):  # P^T F on each world triplet
        x, y, z = b[t3], b[t3 + 1], b[t3 + 2]
        for i in range(3):
            b[t3 + i] = P[0, i] * x + P[1, i] * y + P[2, i] * z
    _lu_solve(luT, piv, b)
    for t3 in range(0, k3, 3):  # P J_ref^-1 P^T F
        x, y, z = b[t3], b[t3 + 1], b[t3 + 2]
        for i in range(3):
            b[t3 + i] = P[i, 0] * x + P[i, 1] * y + P[i, 2] * z


@jit
def _conjugate(A, B, out):
    """out = A B A^T (3 x 3)."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                for m in range(3):
                    s += A[i, k] * B[k, m] * A[j, m]
            out[i, j] = s


@jit
def _rotate_world(world_idx, Q, y):
    """Every world triplet of the ydot-layout vector y rotated by Q, in place (integrator `_rotate_world`)."""
    for t in range(world_idx.shape[0]):
        x0, x1, x2 = y[world_idx[t, 0]], y[world_idx[t, 1]], y[world_idx[t, 2]]
        for i in range(3):
            y[world_idx[t, i]] = Q[i, 0] * x0 + Q[i, 1] * x1 + Q[i, 2] * x2


@jit
def _lu_solve(luT, piv, b):
    """Solve J x = b in place from LAPACK's LU of J (luT = the factors, transposed; piv 0-based)."""
    n = b.shape[0]
    for i in range(n):
        k = piv[i]
        if k != i:
            b[i], b[k] = b[k], b[i]
    for j in range(n):  # unit lower triangle, column by column: L[i, j] = luT[j, i]
        bj = b[j]
        row = luT[j]
        for i in range(j + 1, n):
            b[i] -= row[i] * bj
    for j in range(n - 1, -1, -1):  # upper triangle
        b[j] /= luT[j, j]
        bj = b[j]
        row = luT[j]
        for i in range(j):
            b[i] -= row[i] * bj


@inlined
def step(const, state, inputs, springs, h, am, af, gamma, tol, max_iter, last_it, work, luT, piv, lu_meta, info):
    """One whole step t -> t + h of the numpy path (integrator `_step` with `_prepare_step`, `_commit`,
    body `_update_port_loads`, `_external_power`): the state arrays (xN ... tN in BodySystem._STATE_FIELDS'
    order, then energy = [work, power]) are updated in place, and only if Newton succeeded (info[0] == OK).
    inputs = (xN_p, RN_p, zN_p, f_in, t_in): those read by `BodySystem._read_inputs` (current frames where
    no motion input); last_it the iterations of the last step (the refresh rule `REFRESH_AFTER` =
    (refresh_min, refresh_max); keep its KEEP_CONTRACTION); work = (ydw, p, R, F) of newton_step. Returns
    the factorization (luT, piv) to keep, new arrays if it was refreshed (newton_step)."""
    (gyro, K, M, G, stiff, W1, W2, vk_a, vk_B, mass, J0, X_B, nodes, cfg, vel, gravity, rot_slots, newton_idx, newton_pos, k3,
     field_of, theta_refresh, keep, keep_miss, refresh_min, refresh_max, world_idx, lin_slots, fixed_idx, motion_x, motion_x_slots,
     motion_T_slots, stage_mask, motion_parts) = const
    xN, RN, x0, R0, eta, v, yd, yd_prev, yd_prev2, a, fN, tN, energy = state
    xN_p, RN_p, zN_p, f_in, t_in = inputs
    ydw, p, R, F = work
    N, E, ny = xN.shape[0], x0.shape[0], yd.shape[0]
    beta = h * gamma * af / am
    # stage (integrator `_prepare_step`): a_{n+1} = (af/am) ydot + A0, p = beta ydot + P0
    c1, c2 = (1.0 - af) / am, -(1.0 - am) / am
    d1, d2 = h * gamma * c1, h * (1.0 - gamma) + h * gamma * c2
    A0, P0, c = np.empty(ny), np.empty(ny), np.empty(ny)
    for i in range(ny):
        A0[i] = c1 * yd[i] + c2 * a[i]
        P0[i] = d1 * yd[i] + d2 * a[i]
        c[i] = beta * stage_mask[i]
        ydw[i] = (yd[i] - yd_prev[i]) * 3.0 + yd_prev2[i]  # predictor: quadratic extrapolation of the rates
    # ... its world triplets rotated with the first CM frame over the step (integrator `_predicted_rotation`)
    Q, Rexp, th = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for i in range(3):
        th[i] = beta * ydw[rot_slots[N, i]] + P0[rot_slots[N, i]]
    _expm(th, Rexp)
    _conjugate(R0[0], Rexp, Q)
    _rotate_world(world_idx, Q, ydw)
    k = 0
    for arr in (xN.ravel(), x0.ravel(), eta.ravel(), v.ravel()):
        for i in range(arr.shape[0]):
            P0[lin_slots[k]] += arr[i]
            k += 1
    for j in range(motion_x.shape[0]):
        for i in range(3):
            P0[motion_x_slots[3 * j + i]] = xN_p[motion_x[j], i]
    for i in range(motion_T_slots.shape[0]):
        P0[motion_T_slots[i]] = 0.0
    zflat = zN_p.ravel()
    for i in fixed_idx:
        ydw[i] = zflat[i]
    Rn = np.empty((N + E, 3, 3))
    _copy(Rn, 0, RN_p, 0, 9 * N)
    _copy(Rn, 9 * N, R0, 0, 9 * E)
    # the predictor missed at the last step and the matrix is not known to serve: a fresh one (integrator `_step`)
    after = refresh_min <= last_it <= refresh_max and lu_meta[0] != 0.0
    stale, trusted = after and lu_meta[11] == 0.0, after and lu_meta[11] != 0.0
    if stale:
        lu_meta[0] = 0.0
    for attempt in range(2):  # ONE call site (a retry's call with literal False compiled newton_step's tree a second time)
        luT, piv = newton_step(const, stale, trusted, c, P0, Rn, f_in, t_in, springs, beta, tol, max_iter, ydw, p, R, F, luT, piv,
                               lu_meta, info)
        if attempt == 1:
            info[1] += max_iter  # the failed attempt's iterations count
        if info[0] == OK or info[0] == ROTATION_ALIAS or attempt == 1:
            break
        # one retry from the last step's rates with a fresh matrix (integrator `_step`)
        for i in range(ny):
            ydw[i] = yd[i]
        for i in fixed_idx:
            ydw[i] = zflat[i]
        lu_meta[0] = 0.0
        stale, trusted = False, False
    if info[0] != OK:
        return luT, piv
    # commit (integrator `_commit`)
    k = 0
    for arr in (xN.ravel(), x0.ravel(), eta.ravel(), v.ravel()):  # ravel of a C-contiguous array is a view
        for i in range(arr.shape[0]):
            arr[i] = p[lin_slots[k]]
            k += 1
    for i in range(3):  # the rotation of the first CM frame over the step, R_{n+1} R_n^T
        for j in range(3):
            Q[i, j] = R[N, i, 0] * R0[0, j, 0] + R[N, i, 1] * R0[0, j, 1] + R[N, i, 2] * R0[0, j, 2]
    _copy(RN, 0, R, 0, 9 * N)
    _copy(R0, 0, R, 9 * N, 9 * E)
    af_am = af / am
    for i in range(ny):
        yd_prev2[i] = yd_prev[i]
        yd_prev[i] = yd[i]
        yd[i] = ydw[i]
        a[i] = af_am * ydw[i] + A0[i]
    _rotate_world(world_idx, Q, yd_prev2)  # the history carried along with the body (integrator `_commit`)
    _rotate_world(world_idx, Q, yd_prev)
    # port loads (body `_update_port_loads`) and the power of loads and gravity (`_external_power`)
    spring_loads = springs[8]  # force, moment of compliant ports' springs (zero on other nodes)
    power = 0.0
    for n in range(N):
        for i in range(3):
            fN[n, i] = f_in[n, i] + motion_parts[n, 0, i] * F[6 * n + i] + spring_loads[n, 0, i]
            s = 0.0
            for j in range(3):
                s += RN[n, i, j] * F[6 * n + 3 + j]
            tN[n, i] = t_in[n, i] + motion_parts[n, 1, i] * s + spring_loads[n, 1, i]
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += RN[n, j, i] * tN[n, j]
            power += fN[n, i] * yd[6 * n + i] + s * yd[6 * n + 3 + i]
    for e in range(E):
        for i in range(3):
            power += mass[e] * v[e, i] * gravity[i]
    energy[0] += 0.5 * h * (energy[1] + power)
    energy[1] = power
    return luT, piv


# ------------------------------------------------------------------ many steps in one call
# A standalone run whose inputs are known functions of time (a scene's drives and loads) takes its
# steps in one call of `advance`: the inputs evaluated and each step's output row recorded inside the
# compiled code, so no Python runs between steps. The numpy twins: simulate.scene_inputs,
# BodySystem._read_inputs, simulate.record (port_array, energies).


@jit
def _time_function(kind, prm, t, out):
    """(s, ds/dt) of a time function into out (runtime/drives.py evaluate; kind codes drives.CODES)."""
    if kind == 0:  # constant
        out[0], out[1] = prm[0], 0.0
    elif kind == 1:  # haug_spinup (omega, T)
        w, T = prm[0], prm[1]
        if t < T:
            tau = t / T
            two_pi = 2.0 * np.pi
            out[0] = w * T * (tau**2 / 2.0 + (np.cos(two_pi * tau) - 1.0) / two_pi**2)
            out[1] = w * (tau - np.sin(two_pi * tau) / two_pi)
        else:
            out[0], out[1] = w * T * (t / T - 0.5), w
    elif kind == 2:  # ramp (rate, t_start)
        dt = t - prm[1]
        if dt > 0.0:
            out[0], out[1] = prm[0] * dt, prm[0]
        else:
            out[0], out[1] = 0.0, 0.0
    elif kind == 3:  # window (value, t_start, t_end)
        out[0], out[1] = (prm[0] if prm[1] <= t < prm[2] else 0.0), 0.0
    else:  # sine (amplitude, frequency_hz, phase)
        w = 2.0 * np.pi * prm[1]
        out[0], out[1] = prm[0] * np.sin(w * t + prm[2]), prm[0] * w * np.cos(w * t + prm[2])


@jit
def _no_inputs(xN, RN, xN_p, RN_p, zN_p, f_in, t_in):
    """The inputs of a step where no port prescribes anything: the current frames (`BodySystem._read_inputs`
    where there is no motion input), zero rates, zero loads. The input functions overwrite what the ports set."""
    _copy(xN_p, 0, xN, 0, xN.size)
    _copy(RN_p, 0, RN, 0, RN.size)
    zN_p[:] = 0.0
    f_in[:] = 0.0
    t_in[:] = 0.0


@jit
def _scheduled_inputs(t, ports, schedule, xN, RN, xN_p, RN_p, zN_p, f_in, t_in, springs):
    """The inputs of `step` at time t from a scene's schedule (simulate.scene_schedule, after the ports'
    (node, mode, spring) = runtime/held.py port_codes): what simulate.scene_inputs gives and
    BodySystem._read_inputs reads. Parts: 0 force, 1 motion, 2 compliant."""
    node, mode, spring = ports
    r0, kind, prm, axis, load_port, load_window, load_fm = schedule
    r_in, v_in, R_in, w_in = springs[4], springs[5], springs[6], springs[7]
    _no_inputs(xN, RN, xN_p, RN_p, zN_p, f_in, t_in)
    sv, th, Rd, wd = np.zeros(2), np.zeros(3), np.zeros((3, 3)), np.zeros(3)
    for j in range(node.shape[0]):
        k, s = node[j], spring[j]
        if mode[j, 0] != 0:  # motion or the far end of a spring: r = r0 + u e, v = du e
            sv[0], sv[1] = 0.0, 0.0
            if kind[j, 0] >= 0:
                _time_function(kind[j, 0], prm[j, 0], t, sv)
            for i in range(3):
                r, vv = r0[j, i] + sv[0] * axis[j, 0, i], sv[1] * axis[j, 0, i]
                if mode[j, 0] == 1:
                    xN_p[k, i], zN_p[k, i] = r, vv
                else:
                    r_in[s, i], v_in[s, i] = r, vv
        if mode[j, 1] != 0:  # R = exp(phi a), w = dphi a (world)
            sv[0], sv[1] = 0.0, 0.0
            if kind[j, 1] >= 0:
                _time_function(kind[j, 1], prm[j, 1], t, sv)
            for i in range(3):
                th[i], wd[i] = sv[0] * axis[j, 1, i], sv[1] * axis[j, 1, i]
            _expm(th, Rd)
            _put_rotation(mode[j, 1] == 1, k, s, Rd, wd, RN_p, zN_p, R_in, w_in)
    for ld in range(load_port.shape[0]):
        if load_window[ld, 0] <= t < load_window[ld, 1]:
            j = load_port[ld]
            k = node[j]
            for i in range(3):
                if mode[j, 0] == 0:
                    f_in[k, i] += load_fm[ld, 0, i]
                if mode[j, 1] == 0:
                    t_in[k, i] += load_fm[ld, 1, i]


@jit
def _record(row, node, energy_data, xN, RN, x0, R0, eta, v, yd, fN, tN, work, iterations):
    """One row of simulate.record: per port (boundary nodes node) r, R (row-major), v, w = R W, f, t
    (BodySystem.port_array); the energies kinetic_rigid, kinetic_elastic, strain, work_external
    (BodySystem.energies); iterations. energy_data: the arrays of `step`'s const it reads (`_energy_data`;
    passed alone, not const: each array of a call's arguments costs its unboxing when called from Python)."""
    K, M, mass, J0, X_B, se_nodes, stiff, W1, W2, vk_a, vk_B = energy_data
    col = 0
    for j in range(node.shape[0]):
        k = node[j]
        for i in range(3):
            row[col + i] = xN[k, i]
            row[col + 12 + i] = yd[6 * k + i]
            row[col + 15 + i] = RN[k, i, 0] * yd[6 * k + 3] + RN[k, i, 1] * yd[6 * k + 4] + RN[k, i, 2] * yd[6 * k + 5]
            row[col + 18 + i] = fN[k, i]
            row[col + 21 + i] = tN[k, i]
            for m in range(3):
                row[col + 3 + 3 * i + m] = RN[k, i, m]
        col += 24
    E, n, nb = K.shape[0], K.shape[1], X_B.shape[1]
    nm = n - 6 * nb
    q, Jq = np.zeros(n), np.zeros((3, 3))
    kr, ke, st = 0.0, 0.0, 0.0
    for e in range(E):
        for p in range(nb):  # q_bar (89): d_P = R0^T (x_P - x0) - X_P, alpha_P = vect(R0^T R_P)
            P = se_nodes[e, p]
            Q = np.zeros((3, 3))
            for i in range(3):
                s = 0.0
                for m in range(3):
                    s += R0[e, m, i] * (xN[P, m] - x0[e, m])
                    for l in range(3):
                        Q[i, l] += R0[e, m, i] * RN[P, m, l]
                q[6 * p + i] = s - X_B[e, p, i]
            q[6 * p + 3] = 0.5 * (Q[2, 1] - Q[1, 2])
            q[6 * p + 4] = 0.5 * (Q[0, 2] - Q[2, 0])
            q[6 * p + 5] = 0.5 * (Q[1, 0] - Q[0, 1])
        for i in range(nm):
            q[6 * nb + i] = eta[e, i]
        for i in range(3):
            kr += 0.5 * mass[e] * v[e, i] * v[e, i]
            for m in range(3):
                kr += 0.5 * v[e, 3 + i] * J0[e, i, m] * v[e, 3 + m]
        for i in range(n):
            for m in range(n):
                ke += 0.5 * v[e, 6 + i] * M[e, i, m] * v[e, 6 + m]
                st += 0.5 * q[i] * K[e, i, m] * q[m]
        for kk in range(vk_a.shape[1]):  # V2 = e.sigma + sigma.sigma / 2 (stiffening.von_karman)
            ek, sk = 0.0, 0.0
            for i in range(n):
                ek += vk_a[e, kk, i] * q[i]
                for m in range(n):
                    sk += 0.5 * q[i] * vk_B[e, kk, i, m] * q[m]
            st += (ek + 0.5 * sk) * sk
        if stiff:  # 1/2 Omega0^T (W1 q [+ q W2 q]) Omega0 (stiffening.deformed_inertia)
            for a in range(3):
                for b in range(3):
                    s = 0.0
                    for i in range(n):
                        s += q[i] * W1[e, i, a, b]
                        for m in range(W2.shape[1]):
                            s += q[i] * W2[e, i, m, a, b] * q[m]
                    Jq[a, b] = s
            for a in range(3):
                for b in range(3):
                    kr += 0.5 * v[e, 3 + a] * Jq[a, b] * v[e, 3 + b]
    row[col], row[col + 1], row[col + 2], row[col + 3], row[col + 4] = kr, ke, st, work, iterations


# ------------------------------------------------------------------ an FMU's communication step in one call
# The inputs extrapolated from the values held at the communication point t_c (runtime/held.py, whose
# `inputs` is the numpy twin of `_held_inputs`), evaluated at every internal step inside the compiled
# code (`advance`); the output row recorded once, at the end.


@jit
def _held_inputs(t, t_c, ports, values, xN, RN, xN_p, RN_p, zN_p, f_in, t_in, springs):
    """The inputs of `step` at time t extrapolated from the held values (runtime/held.py `inputs`, read by
    BodySystem._read_inputs): ports = (node, mode, spring) (held.port_codes), mode 0 force, 1 motion,
    2 compliant; values one row per port, columns held.COLUMNS (r 0, v 3, a 6, R 9, w 18, dw 21, f 24, t 27)."""
    node, mode, spring = ports
    r_in, v_in, R_in, w_in = springs[4], springs[5], springs[6], springs[7]
    _no_inputs(xN, RN, xN_p, RN_p, zN_p, f_in, t_in)
    dt = t - t_c
    half = 0.5 * dt * dt
    th, E, Rd, wd = np.empty(3), np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for j in range(node.shape[0]):
        k, s, row = node[j], spring[j], values[j]
        if mode[j, 0] == 0:
            for i in range(3):
                f_in[k, i] = row[24 + i]
        else:
            for i in range(3):
                r, vv = row[i] + row[3 + i] * dt + half * row[6 + i], row[3 + i] + dt * row[6 + i]
                if mode[j, 0] == 1:
                    xN_p[k, i], zN_p[k, i] = r, vv
                else:
                    r_in[s, i], v_in[s, i] = r, vv
        if mode[j, 1] == 0:
            for i in range(3):
                t_in[k, i] = row[27 + i]
        else:
            for i in range(3):
                th[i], wd[i] = row[18 + i] * dt + half * row[21 + i], row[18 + i] + dt * row[21 + i]
            _expm(th, E)
            for i in range(3):
                for m in range(3):
                    Rd[i, m] = E[i, 0] * row[9 + m] + E[i, 1] * row[12 + m] + E[i, 2] * row[15 + m]
            _put_rotation(mode[j, 1] == 1, k, s, Rd, wd, RN_p, zN_p, R_in, w_in)


# ------------------------------------------------------------------ the one entry point
# Every step the kernel takes is taken by `advance`: numba links a jitted function's whole callee tree into
# each function that calls it and optimizes and emits it again there, so an entry point of its own per use
# (one step, a scene's run, an FMU's communication step) would compile `step`'s tree once more each
# (docs/benchmarks.md, compile section). One entry point with the inputs' kind as an argument compiles it
# once; the arguments a kind does not read are empty arrays of the same types (runtime/compiled.py). An
# output row alone is `_record` called directly: a callee of `advance` without callees, compiled once for both.

GIVEN, SCHEDULED, HELD = 0, 1, 2  # `advance`: where a step's inputs come from


@jit
def _energy_data(const):
    """(K, M, mass, J0, X_B, se_nodes, stiff, W1, W2, vk_a, vk_B) of `step`'s const: what `_record` reads."""
    return const[1], const[2], const[9], const[10], const[11], const[12], const[4], const[5], const[6], const[7], const[8]


@jit
def advance(kind, n, const, state, inputs, springs, ports, schedule, values, h, am, af, gamma, tol, max_iter, last_it, work, luT,
            piv, lu_meta, info, t, t_c, rows, times):
    """n steps of h from time t (`step` each), their inputs by kind: GIVEN as the caller set them in inputs
    (BodySystem.step, n = 1), SCHEDULED from the scene's schedule (`_scheduled_inputs`; every step's row
    recorded into rows[k] and its time into times[k], simulate.record's layout), HELD extrapolated from the
    values held at t_c (`_held_inputs`, an FMU's communication step; the last step's row into rows[0]).
    ports = (node, mode, spring) of the ports (held.port_codes). Returns (steps completed, the most Newton iterations of a
    step, the iterations of the last completed step (last_it if none), luT, piv); a failed step leaves the
    state at the last completed one, its status in info (as `step`), rows untouched."""
    xN, RN, x0, R0, eta, v, yd, fN, tN, energy = state[0], state[1], state[2], state[3], state[4], state[5], state[6], \
        state[10], state[11], state[12]
    xN_p, RN_p, zN_p, f_in, t_in = inputs
    energy_data = _energy_data(const)
    worst = 0
    for k in range(n):
        t1 = t + h
        if kind == SCHEDULED:
            _scheduled_inputs(t1, ports, schedule, xN, RN, xN_p, RN_p, zN_p, f_in, t_in, springs)
        elif kind == HELD:
            _held_inputs(t1, t_c, ports, values, xN, RN, xN_p, RN_p, zN_p, f_in, t_in, springs)
        luT, piv = step(const, state, inputs, springs, h, am, af, gamma, tol, max_iter, last_it, work, luT, piv, lu_meta, info)
        if info[0] != OK:
            return k, worst, last_it, luT, piv
        last_it = info[1]
        worst = max(worst, last_it)
        t = t1
        if kind == SCHEDULED:
            times[k] = t
            _record(rows[k], ports[0], energy_data, xN, RN, x0, R0, eta, v, yd, fN, tN, energy[0], last_it)
    if kind == HELD and n > 0:
        _record(rows[0], ports[0], energy_data, xN, RN, x0, R0, eta, v, yd, fN, tN, energy[0], last_it)
    return n, worst, last_it, luT, piv
