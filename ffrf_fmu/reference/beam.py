"""Geometrically exact (Simo-Reissner) two-node beam element: strain energy, forces, tangent.

Element e joins nodes 1 and 2 with positions x1, x2 (world) and section frames R1, R2 (columns:
section axes 1, 2, 3 in world axes; R = Lambda0 in the reference configuration). Interpolation:

- position linear in the arc length: x' = (x2 - x1) / L;
- rotation along the relative-rotation geodesic R(xi) = R1 exp(xi psi^), psi = log(R1^T R2).
  This is the Crisfield-Jelenic (1999) strain-objective, path-independent interpolation for two
  nodes: a rigid rotation of both nodes leaves psi and hence the strains unchanged, and no
  incremental or total rotation vector is ever interpolated.

Strain measures (material, Simo-Reissner): Gamma = R^T x' - e1, K = vee(R^T R') = psi / L.
K is exactly constant along the element. The force strain Gamma is evaluated at the midpoint
with R_m = R1 exp(psi^/2) only: one-point (reduced) integration, which removes shear and
membrane locking of the linear element. The discrete energy is

    U_e = L/2 (Gamma_m^T C_N Gamma_m + K^T C_M K),  C_N = diag(EA, GA2, GA3),  C_M = diag(GJ, EI2, EI3).

Forces are its exact gradient with respect to nodal displacements u and right (material)
rotation perturbations R -> R exp(theta^). The tangent is the exact derivative of those forces
(analytic, including the derivatives of the exponential/log Jacobians); a test checks it
against central finite differences. Everything is vectorized over elements: no Python loop
over elements.
"""
from __future__ import annotations

import numpy as np

from ..runtime.rotation import cross, expm, logm, skew

# The coefficient functions of exp and its right Jacobians with their derivatives in p = phi^2,
# which the exact tangent needs (the SO(3) basics are runtime/rotation.py's). The arrays are
# small (one entry per element), so the cost is the number of numpy calls: one Taylor series
# when every angle is below SERIES rad, closed forms otherwise.
SERIES = 0.1  # rad; series truncation error < 1e-13 below; closed forms lose digits to cancellation

# Taylor coefficients in p = phi^2 (columns: s1, s2, s3, s4, ds1/dp, ds2/dp, ds3/dp, ds4/dp)
#   s1 = sin(phi)/phi, s2 = (1 - cos phi)/phi^2, s3 = (phi - sin phi)/phi^3,
#   s4 = 1/phi^2 - (1 + cos phi)/(2 phi sin phi)
_TAYLOR = np.array(
    [
        [1.0, 1 / 2, 1 / 6, 1 / 12, -1 / 6, -1 / 24, -1 / 120, 1 / 720],
        [-1 / 6, -1 / 24, -1 / 120, 1 / 720, 1 / 60, 1 / 360, 1 / 2520, 1 / 15120],
        [1 / 120, 1 / 720, 1 / 5040, 1 / 30240, -1 / 1680, -1 / 13440, -1 / 120960, 1 / 403200],
        [-1 / 5040, -1 / 40320, -1 / 362880, 1 / 1209600, 1 / 90720, 1 / 907200, 1 / 9979200, 1 / 11975040],
        [1 / 362880, 1 / 3628800, 1 / 39916800, 1 / 47900160, 0.0, 0.0, 0.0, 0.0],
    ]
)
_POW = np.arange(5)


def newton_update(x: np.ndarray, R: np.ndarray, d: np.ndarray, length: float, tol: float):
    """A static Newton correction d (nn, 6: node translations, material rotation increments) applied to the
    node positions x and frames R (R exp(theta^): the right perturbation the forces and tangent are taken
    in), and whether Newton has converged: every node moved by less than tol * length and turned by less
    than tol rad. (x, R, converged)."""
    return (x + d[:, :3], R @ expm(d[:, 3:]),
            bool(np.abs(d[:, :3]).max() < tol * length and np.abs(d[:, 3:]).max() < tol))


def newton(x: np.ndarray, R: np.ndarray, correction, length: float, tol: float, max_iterations: int):
    """Static Newton from (x, R): correction(x, R) gives d (nn, 6), applied by newton_update, until it
    converges. (x, R, converged); not converged when d is None (a singular tangent) or not finite, or
    after max_iterations corrections."""
    for _ in range(max_iterations):
        d = correction(x, R)
        if d is None or not np.all(np.isfinite(d)):
            return x, R, False
        x, R, converged = newton_update(x, R, d, length, tol)
        if converged:
            return x, R, True
    return x, R, False


def coefficients(p: np.ndarray, derivatives: bool = False) -> np.ndarray:
    """Coefficient functions of p = phi^2, stacked on a new last axis.

    Returns (..., 4) [s1, s2, s3, s4], or (..., 8) with their derivatives d/dp appended.
    """
    p = np.asarray(p, dtype=float)
    ncol = 8 if derivatives else 4
    if p.size == 0 or p.max() < SERIES * SERIES:
        return (p[..., None] ** _POW) @ _TAYLOR[:, :ncol]
    small = p < SERIES * SERIES
    q = np.where(small, 1.0, p)
    f = np.sqrt(q)
    sn, cs = np.sin(f), np.cos(f)
    cot_h = (1.0 + cs) / sn  # cot(phi/2)
    cols = [sn / f, (1.0 - cs) / q, (f - sn) / (f * q), 1.0 / q - cot_h / (2.0 * f)]
    if derivatives:
        csc2_h = 1.0 / np.sin(0.5 * f) ** 2
        cols += [
            (f * cs - sn) / (2.0 * f * q),
            (f * sn - 2.0 + 2.0 * cs) / (2.0 * q * q),
            ((1.0 - cs) * f - 3.0 * (f - sn)) / (2.0 * q * q * f),
            (-2.0 / (f * q) + (f * csc2_h + 2.0 * cot_h) / (4.0 * q)) / (2.0 * f),
        ]
    out = np.stack(cols, axis=-1)
    if np.any(small):
        out = np.where(small[..., None], (p[..., None] ** _POW) @ _TAYLOR[:, :ncol], out)
    return out


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of stacks of 3-vectors."""
    return (a * b).sum(-1)


_E1 = np.array([1.0, 0.0, 0.0])
_I3 = np.eye(3)
# F = I + b A + c A^2 (A = skew(psi)) for E = exp(psi^/2), Jh = J_r(-psi/2), Jri = J_r^-1(psi),
# Jrim = J_r^-1(-psi): (b, c) picked from [s1..s4 at p/4, s1..s4 at p] (see state()).
_BC_IDX = np.array([0, 1, 0, 0, 1, 2, 7, 7])
_BC_SCALE = np.array([0.5, 0.5, 0.0, 0.0, 0.25, 0.25, 1.0, 1.0])
_BC_OFFSET = np.array([0.0, 0.0, 0.5, -0.5, 0.0, 0.0, 0.0, 0.0])
# their derivatives d/dp from [ds1..ds4 at p/4, ds1..ds4 at p] (chain rule: d/dp f(p/4) = f'(p/4)/4)
_D_IDX = np.array([0, 1, 0, 0, 1, 2, 7, 7])
_D_SCALE = np.array([1 / 8, 1 / 8, 0.0, 0.0, 1 / 16, 1 / 16, 1.0, 1.0])
_SEL = np.array([0, 1, 2, 2, 3, 3])


def _dFv(b, c, db, dc, psi, v):
    """d(F(psi) v)/dpsi at fixed v for F = I + b(p) skew(psi) + c(p) skew(psi)^2, p = |psi|^2.

    Stacked: b, c, db, dc (k, ne), psi (ne, 3), v (k, ne, 3) -> (k, ne, 3, 3).
    """
    pv = dot(psi, v)
    pxv = cross(psi, v)
    pxpxv = cross(psi, pxv)
    out = c[..., None, None] * (
        pv[..., None, None] * _I3 + psi[..., :, None] * v[..., None, :] - 2.0 * v[..., :, None] * psi[..., None, :]
    )
    out -= b[..., None, None] * skew(v)
    out += (2.0 * (db[..., None] * pxv + dc[..., None] * pxpxv))[..., :, None] * psi[..., None, :]
    return out


def _mv(A, v):
    return (A @ v[..., None])[..., 0]


class BeamElements:
    """Elements of length L with section stiffness diagonals C_N, C_M (vectorized over elements)."""

    def __init__(self, L: float, CN, CM):
        self.L = float(L)
        self.CN = np.asarray(CN, dtype=float)
        self.CM = np.asarray(CM, dtype=float)

    def state(self, x1, x2, R1, R2) -> dict:
        """Intermediate quantities of all elements, shared by forces, energy and tangent."""
        L = self.L
        psi = logm(np.swapaxes(R1, -1, -2) @ R2)
        ne = psi.shape[0]
        p = dot(psi, psi)
        if p.size and p.max() > (np.pi - 1e-6) ** 2:
            raise ValueError("element relative rotation too close to pi: refine the mesh")
        pp = np.concatenate([p, 0.25 * p])
        co = coefficients(pp)
        cat = np.concatenate([co[ne:], co[:ne]], axis=1)  # s1..s4 at p/4, then s1..s4 at p
        bc = cat[:, _BC_IDX] * _BC_SCALE + _BC_OFFSET
        b, c = bc[:, :4].T, bc[:, 4:].T
        A = skew(psi)
        A2 = A @ A
        F = _I3 + b[..., None, None] * A + c[..., None, None] * A2
        E, Jh, Jri, Jrim = F
        Rm = R1 @ E
        g = (np.swapaxes(Rm, -1, -2) @ (x2 - x1)[..., None])[..., 0] / L  # R_m^T x'
        Gam = g - _E1
        n = self.CN * Gam
        m = self.CM * psi / L
        mu = L * cross(n, g)
        return dict(psi=psi, pp=pp, A=A, F=F, E=E, Jh=Jh, Jri=Jri, Jrim=Jrim, b=b, c=c,
                    Rm=Rm, g=g, Gam=Gam, n=n, m=m, mu=mu)

    def energy(self, x1, x2, R1, R2) -> np.ndarray:
        return self.energy_from(self.state(x1, x2, R1, R2))

    def energy_from(self, st) -> np.ndarray:
        return 0.5 * self.L * (dot(st["Gam"], st["n"]) + dot(st["psi"], st["m"]) / self.L)

    def forces(self, x1, x2, R1, R2, tangent: bool = False):
        """Element forces (ne, 12) = dU/d(u1, theta1, u2, theta2); with tangent also (ne, 12, 12)."""
        st = self.state(x1, x2, R1, R2)
        f = self.forces_from(st)
        return (f, self.tangent_from(st)) if tangent else f

    def forces_from(self, st) -> np.ndarray:
        # f_th1 = A1^T mu + P1^T m = E mu - 1/2 Jri Jh mu - Jri m
        # f_th2 = A2^T mu + P2^T m = 1/2 Jrim Jh mu + Jrim m
        E, Jri, Jrim, Rm = st["E"], st["Jri"], st["Jrim"], st["Rm"]
        n, m, mu = st["n"], st["m"], st["mu"]
        Jh_mu = _mv(st["Jh"], mu)
        st["Jh_mu"] = Jh_mu
        vec = np.array([mu, -0.5 * Jh_mu - m, 0.5 * Jh_mu + m])  # (3, ne, 3)
        r = _mv(st["F"][[0, 2, 3]], vec)
        fx2 = _mv(Rm, n)
        return np.concatenate([-fx2, r[0] + r[1], fx2, r[2]], axis=-1)

    def tangent_from(self, st) -> np.ndarray:
        """Exact derivative (ne, 12, 12) of the forces; call forces_from(st) first."""
        L, CN, CM = self.L, self.CN, self.CM
        psi = st["psi"]
        E, Jh, Jri, Jrim, Rm = st["E"], st["Jh"], st["Jri"], st["Jrim"], st["Rm"]
        g, n, m, mu, Jh_mu = st["g"], st["n"], st["m"], st["mu"], st["Jh_mu"]
        ne = psi.shape[0]
        JhT = np.swapaxes(Jh, -1, -2)  # J_r(psi/2)
        # delta psi = P1 th1 + P2 th2 ; theta_m = A1 th1 + A2 th2
        P1 = -np.swapaxes(Jri, -1, -2)  # -J_l^-1(psi)
        P2 = np.swapaxes(Jrim, -1, -2)  # J_r^-1(psi)
        JP = 0.5 * JhT @ np.array([P1, P2])
        A1 = np.swapaxes(E, -1, -2) + JP[0]
        A2 = JP[1]
        Gpsi = np.concatenate([P1, P2], axis=-1)  # (ne, 3, 6)
        Gm = np.concatenate([A1, A2], axis=-1)
        Bu = np.swapaxes(Rm, -1, -2) / L  # d gamma / d(u2 - u1)
        H = skew(np.array([g, n]))
        Hg, Hn = H[0], H[1]
        # translational rows of node 2 (node 1: minus)
        Kx_u = (Rm * CN) @ Bu
        Kx_t = Rm @ (CN[:, None] * Hg - Hn) @ Gm
        # moment rows
        Q = L * (Hn - Hg * CN)  # d mu / d gamma
        QB = Q @ Bu
        QHG = Q @ Hg @ Gm
        # derivative terms of the psi-dependent matrices, all six at once:
        # (E, mu), (Jh, mu), (Jri, Jh mu), (Jri, m), (Jrim, Jh mu), (Jrim, m)
        co = coefficients(st["pp"], derivatives=True)[:, 4:]
        dcat = np.concatenate([co[ne:], co[:ne]], axis=1)[:, _D_IDX] * _D_SCALE
        db, dc = dcat[:, :4].T, dcat[:, 4:].T
        sel = _SEL
        D = _dFv(st["b"][sel], st["c"][sel], db[sel], dc[sel], psi, np.array([mu, mu, Jh_mu, m, Jh_mu, m]))
        JD = st["F"][2:] @ D[1]
        CML = CM / L
        D1 = D[0] - 0.5 * (D[2] + JD[0]) - D[3] - Jri * CML  # + P1^T C_M / L = -Jri C_M / L
        D2 = 0.5 * (D[4] + JD[1]) + D[5] + Jrim * CML
        At = np.swapaxes(np.array([A1, A2]), -1, -2)
        Kt_t = At @ QHG + np.array([D1, D2]) @ Gpsi  # (2, ne, 3, 6)
        Kt_u = At @ QB  # (2, ne, 3, 3)
        K = np.empty((ne, 4, 3, 4, 3))
        K[:, 2, :, 0] = -Kx_u
        K[:, 2, :, 2] = Kx_u
        K[:, 2, :, 1] = Kx_t[..., 0:3]
        K[:, 2, :, 3] = Kx_t[..., 3:6]
        K[:, 0] = -K[:, 2]
        K[:, 1, :, 0] = -Kt_u[0]
        K[:, 1, :, 2] = Kt_u[0]
        K[:, 3, :, 0] = -Kt_u[1]
        K[:, 3, :, 2] = Kt_u[1]
        K[:, 1, :, 1] = Kt_t[0, ..., 0:3]
        K[:, 1, :, 3] = Kt_t[0, ..., 3:6]
        K[:, 3, :, 1] = Kt_t[1, ..., 0:3]
        K[:, 3, :, 3] = Kt_t[1, ..., 3:6]
        return K.reshape(ne, 12, 12)
