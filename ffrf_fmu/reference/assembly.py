"""What the reference's dynamic and static Newton share: the banded iteration matrix in LAPACK gbtrf
storage (`_Banded`), the scene's tables of drives, loads and prescribed dofs (`_Scene`), and the internal
and applied nodal forces (`_internal`, `_applied`)."""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from ..model import Body, Scene, scene_body
from ..runtime.drives import evaluate, window_share
from ..runtime.rotation import skew
from .mesh import Mesh

_KL = _KU = 11  # half bandwidth of the 6-dof-per-node two-node element chain
_LDAB = 2 * _KL + _KU + 1  # LAPACK gbtrf storage rows
_D = _KL + _KU  # row of the diagonal in gbtrf storage


# ============================================================================ banded assembly
class _Banded:
    """Scatter indices of the element and nodal blocks into LAPACK band storage (gbtrf layout).

    Prescribed dofs (mask `free` False) get identity rows/columns, so the band structure and the
    dof numbering never change.
    """

    def __init__(self, mesh: Mesh, free: np.ndarray, with_mass: bool):
        nn, ne = mesh.nn, mesh.ne
        n = 6 * nn
        self.n = n
        self.free = free
        f = free.astype(float)
        dof = 6 * np.arange(ne)[:, None] + np.arange(12)[None, :]
        I, J = dof[:, :, None], dof[:, None, :]
        self.idx_e = ((_D + I - J) * n + J).ravel()
        self.w_e = f[I] * f[J]
        rd = 6 * np.arange(nn)[:, None] + 3 + np.arange(3)[None, :]
        I, J = rd[:, :, None], rd[:, None, :]
        self.idx_r = ((_D + I - J) * n + J).ravel()
        self.w_r = f[I] * f[J]
        self.idx = np.concatenate([self.idx_e, self.idx_r])
        base = np.zeros(_LDAB * n)
        if with_mass:
            t = 6 * np.arange(nn)[:, None] + np.arange(3)[None, :]
            np.add.at(base, ((_D) * n + t).ravel(), (np.repeat(mesh.md, 3) * f[t.ravel()]))
            a = 6 * np.arange(ne)[:, None] + np.arange(3)[None, :]
            b = a + 6
            wab = np.repeat(mesh.mo, 3) * f[a.ravel()] * f[b.ravel()]
            np.add.at(base, ((_D + a - b) * n + b).ravel(), wab)
            np.add.at(base, ((_D + b - a) * n + a).ravel(), wab)
            np.add.at(base, ((_D) * n + rd).ravel(), mesh.J.ravel() * f[rd.ravel()])
        base[_D * n + np.flatnonzero(~free)] += 1.0
        self.base = base
        self.size = _LDAB * n

    def factor(self, Ke: np.ndarray, Kr: np.ndarray | None):
        vals = (Ke * self.w_e).ravel()
        if Kr is None:
            ab = self.base + np.bincount(self.idx_e, vals, minlength=self.size)
        else:
            ab = self.base + np.bincount(self.idx, np.concatenate([vals, (Kr * self.w_r).ravel()]), minlength=self.size)
        lu, piv, info = lapack.dgbtrf(ab.reshape(_LDAB, self.n), _KL, _KU)
        if info != 0:
            raise np.linalg.LinAlgError(f"reference: singular iteration matrix (gbtrf info={info})")
        return lu, piv

    def solve(self, fac, rhs: np.ndarray) -> np.ndarray:
        lu, piv = fac
        x, info = lapack.dgbtrs(lu, _KL, _KU, rhs * self.free, piv)
        return x * self.free


# ============================================================================ scene: drives, loads
class _Scene:
    """Causality, prescribed motion and loads of one scene on a mesh."""

    def __init__(self, mesh: Mesh, body: Body, scene: Scene | None):
        if scene is not None:
            body = scene_body(body, scene)
        caus = {p.name: (p.translation, p.rotation) for p in body.ports}
        drives = {}
        loads = []
        gravity = np.zeros(3)
        if scene is not None:
            for d in scene.drives:
                if d.port not in caus:
                    raise ValueError(f"reference: scene {scene.name!r} drives unknown port {d.port!r}")
                tr, ro = caus[d.port]
                if d.translation is not None and tr != "motion":
                    raise ValueError(f"reference: drive on port {d.port!r} prescribes translation, causality is {tr!r}")
                if d.rotation is not None and ro != "motion":
                    raise ValueError(f"reference: drive on port {d.port!r} prescribes rotation, causality is {ro!r}")
                drives[d.port] = d
            for ld in scene.loads:
                if ld.port not in caus:
                    raise ValueError(f"reference: scene {scene.name!r} loads unknown port {ld.port!r}")
                tr, ro = caus[ld.port]
                if tr == "motion" and any(ld.force):
                    raise ValueError(f"reference: force load on port {ld.port!r} whose translation is motion-driven")
                if ro == "motion" and any(ld.moment):
                    raise ValueError(f"reference: moment load on port {ld.port!r} whose rotation is motion-driven")
                loads.append(
                    (mesh.port_node[ld.port], np.asarray(ld.force, float), np.asarray(ld.moment, float),
                     float(ld.t_start), float(ld.t_end))
                )
            gravity = np.asarray(scene.gravity, dtype=float)
        self.causality = caus
        nn = mesh.nn
        self.presc_t = np.zeros(nn, bool)
        self.presc_r = np.zeros(nn, bool)
        self.trans = []  # (node, X_ref, direction | None, kind, params)
        self.rot = []  # (node, axis | None, kind, params)
        for p in body.ports:
            k = mesh.port_node[p.name]
            tr, ro = caus[p.name]
            d = drives.get(p.name)
            if tr == "motion":
                self.presc_t[k] = True
                td = d.translation if d is not None else None
                if td is None:
                    self.trans.append((k, mesh.X[k].copy(), None, None, None))
                else:
                    e = np.asarray(td.direction, float)
                    self.trans.append((k, mesh.X[k].copy(), e / np.linalg.norm(e), td.displacement.kind,
                                       dict(td.displacement.params)))
            if ro == "motion":
                self.presc_r[k] = True
                rd = d.rotation if d is not None else None
                if rd is None:
                    self.rot.append((k, None, None, None))
                else:
                    a = np.asarray(rd.axis, float)
                    a = a / np.linalg.norm(a)
                    A = skew(a)
                    self.rot.append((k, (a, A, A @ A), rd.angle.kind, dict(rd.angle.params)))
        free = np.ones((nn, 6), bool)
        free[self.presc_t, :3] = False
        free[self.presc_r, 3:] = False
        self.free = free.ravel()
        self.loads = loads
        self.has_moments = any(np.any(m) for _, _, m, _, _ in loads)
        fg = np.zeros((nn, 3))
        if np.any(gravity):
            w = mesh.md + np.concatenate([mesh.mo, [0.0]]) + np.concatenate([[0.0], mesh.mo])
            fg = w[:, None] * gravity[None, :]  # consistent: int N m g ds = m L_e/2 g per element end
        self.f_gravity = fg
        self.Lam0 = mesh.Lam0

    def loads_at(self, t: float, nn: int, h: float = 0.0):
        """Nodal loads applied at the end t of a step of h: each window's mean over the step (t - h, t]
        (drives.window_share; the body's runs do the same), so that the impulse is the load times the
        window's length for any step; h = 0: the value at t."""
        F = np.zeros((nn, 3))
        T = np.zeros((nn, 3))
        for k, f, m, t0, t1 in self.loads:
            share = window_share(t0, t1, t - h, t)
            if share:
                F[k] += share * f
                T[k] += share * m
        return F, T

    def impose(self, t: float, x, R, v, vd) -> None:
        """Overwrite prescribed parts of (x, R, v, vd) in place with the drives at time t."""
        for k, X, e, kind, prm in self.trans:
            if kind is None:
                x[k] = X
                v[k, :3] = 0.0
                vd[k, :3] = 0.0
            else:
                u, du, ddu = evaluate(kind, prm, t)
                x[k] = X + u * e
                v[k, :3] = du * e
                vd[k, :3] = ddu * e
        for k, a, kind, prm in self.rot:
            if kind is None:
                R[k] = self.Lam0
                v[k, 3:] = 0.0
                vd[k, 3:] = 0.0
            else:
                phi, dphi, ddphi = evaluate(kind, prm, t)
                a, A, A2 = a
                R[k] = (np.eye(3) + math.sin(phi) * A + (1.0 - math.cos(phi)) * A2) @ self.Lam0
                aloc = R[k].T @ a
                v[k, 3:] = dphi * aloc  # material angular velocity of a rotation about a fixed axis
                vd[k, 3:] = ddphi * aloc  # exact: d/dt (R^T a) phidot = R^T a phiddot (W parallel R^T a)


# ============================================================================ residual
def _internal(mesh: Mesh, x, R):
    st = mesh.elements.state(x[:-1], x[1:], R[:-1], R[1:])
    fe = mesh.elements.forces_from(st)
    f = np.zeros((mesh.nn, 6))
    f[:-1] += fe[:, :6]
    f[1:] += fe[:, 6:]
    return f, st


def _applied(sc: _Scene, R, F, T):
    """Generalized applied forces (nn, 6): world forces, material moments R^T t."""
    out = np.zeros((R.shape[0], 6))
    out[:, :3] = sc.f_gravity + F
    if sc.has_moments:
        out[:, 3:] = (np.swapaxes(R, -1, -2) @ T[..., None])[..., 0]
    return out
