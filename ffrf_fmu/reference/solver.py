"""Full-order dynamics and statics of one body: mesh, scene, Lie-group generalized-alpha, Newton.

Unknowns per node i: position x_i (world) and section frame R_i in SO(3) (columns: section axes
1, 2, 3 in world axes), velocities (xdot_i, W_i) with W_i the material angular velocity.
The configuration space is (R^3 x SO(3))^N (not SE(3)): with world positions the translational
mass matrix is constant and the only inertial nonlinearity is the nodal gyroscopic term.

Inertia: consistent translational mass of the linear element (m L/6 [[2, 1], [1, 2]], exact
for the linear velocity field, so centrifugal loads are integrated exactly), rotary inertia
diag(m11, m22, m33) lumped at the nodes (half an element each) in section axes. Equations:

    M_t xddot + f_x(x, R) = f_ext,          J Wdot + W x J W + f_theta(x, R) = R^T t_ext,

with forces from `beam.BeamElements`. Time integration: the Lie-group generalized-alpha method
of Bruls, Cardona & Arnold (2012) for second-order systems (Arnold & Bruls 2007 form):

    q_{n+1} = q_n o exp(h dq_n),  dq_n = v_n + h (1/2 - beta) a_n + h beta a_{n+1},
    v_{n+1} = v_n + h (1 - gamma) a_n + h gamma a_{n+1},
    (1 - alpha_m) a_{n+1} + alpha_m a_n = (1 - alpha_f) vdot_{n+1} + alpha_f vdot_n,
    M vdot_{n+1} + g(q_{n+1}, v_{n+1}, t_{n+1}) = 0           (equilibrium exact at t_{n+1}),

alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 + alpha_f - alpha_m,
beta = (gamma + 1/2)^2 / 4 (Chung-Hulbert optimal, second-order accurate, spectral radius rho at
infinite frequency). Newton on vdot_{n+1} with the consistent iteration matrix
M + gamma' C_t + beta' K_t T(h dq) (T = right Jacobian of exp on the rotation columns), K_t the
exact element tangent; the matrix is banded (bandwidth 11) and factorized with LAPACK gbtrf.
The factorization is reused across iterations and steps ("modified" Newton) in a co-rotated way:
a rigid rotation Q of the configuration turns the iteration matrix into P S P^T with
P = diag(Q on nodal translations, I on material rotations), so a stale factorization is applied
to Q^T-rotated residuals and its corrections are rotated back by Q (Q = rotation of the mid node
since the factorization). A spinning body thus keeps one factorization for many steps; a fresh one
is computed when the contraction is slow, after a diverging correction (discarded) or after
`jacobian_age` steps. Newton stops when a correction moves every node by less than tol * L and
turns it by less than tol rad (default 1e-9: the accumulated effect on B1's maximum deflection is
below 1e-5 relative).

Prescribed motion (port parts with causality "motion") is imposed exactly on the node's
position and/or rotation with velocity and acceleration from the drive's time function; those
dofs are eliminated (identity rows), and the reaction is the residual of their equations.

Over 400 lines: the full-order model's mesh, scene tables and solvers (the dynamic run with its step and
Newton, the static relaxation and equilibrium), which share the mesh's node layout and its banded
solver; the element forces and tangents are in reference/beam.py, the steady start in reference/steady.py.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
from scipy.linalg import lapack


from ..model import Body, Scene, scene_body
from ..runtime.drives import evaluate, window_share
from .beam import BeamElements, newton_update
from ..runtime.rotation import cross, expm, skew, tangent
from ..runtime.outputs import tip_from_hub as eq92_tip_from_hub
from ..runtime.steps import whole_steps

# an energy error (|kinetic + strain - work - initial| / energy level) above this makes the run suspect:
# the solver warns, and the chart and the spin map mark what they compared against it
ENERGY_ERROR_SUSPECT = 0.02

_KL = _KU = 11  # half bandwidth of the 6-dof-per-node two-node element chain
_LDAB = 2 * _KL + _KU + 1  # LAPACK gbtrf storage rows
_D = _KL + _KU  # row of the diagonal in gbtrf storage
_GA_PENALTY = 1.0e2  # shear-rigid sections: GA = 100 * 12 EI_max / L_e^2 (see Mesh)


# ============================================================================ mesh and body data
def section_frame(direction) -> np.ndarray:
    """Lambda0 = [e1 e2 e3]: e1 = beam direction, e2 = normalize(e_z x e1), e3 = e1 x e2.

    For a beam along +-Z (e_z x e1 = 0) e2 = e_y is used (stated convention of this module).
    """
    e1 = np.asarray(direction, dtype=float)
    e1 = e1 / np.linalg.norm(e1)
    e2 = cross(np.array([0.0, 0.0, 1.0]), e1)
    if np.linalg.norm(e2) < 1e-9:
        e2 = np.array([0.0, 1.0, 0.0])
    e2 = e2 / np.linalg.norm(e2)
    e3 = cross(e1, e2)
    return np.column_stack([e1, e2, e3])


class Mesh:
    """Uniform mesh of the body's beam: nodes, elements, mass, port nodes.

    Section stiffness: C_N = diag(EA, GA2, GA3), C_M = diag(GJ, EI2, EI3) in section axes.
    GA2/GA3 None (Euler-Bernoulli section) is modelled as shear-rigid by a penalty
    GA = 100 * 12 EI_max / L_e^2: the shear flexibility of an element is 1 % of its bending
    flexibility, so the shear adds 1/(400 n^2) relative to a cantilever's tip deflection (1e-5 at
    16 elements, 100 times below the element's own 1/(4 n^2) discretization error), while the
    conditioning and the stiffness of the shear modes stay moderate (a larger penalty made the
    Newton iteration struggle on B2's suddenly applied root torque); with one-point integration
    the penalty causes no locking.
    """

    def __init__(self, body: Body, n_elements: int | None = None):
        nse = int(body.superelements)
        if n_elements is None:
            n_elements = max(16, 4 * nse)
        n_elements = int(n_elements)
        if n_elements < 1 or n_elements % nse:
            raise ValueError(
                f"reference: n_elements={n_elements} must be a positive multiple of body.superelements={nse} "
                "so that every port lands on a finite-element node"
            )
        sec = body.section
        self.body = body
        self.ne = n_elements
        self.nn = n_elements + 1
        self.length = float(body.length)
        self.Le = self.length / n_elements
        self.Lam0 = section_frame(body.direction)
        self.origin = np.asarray(body.origin, dtype=float)
        s = np.linspace(0.0, self.length, self.nn)
        self.s = s
        self.X = self.origin + s[:, None] * self.Lam0[:, 0]
        ei_max = max(sec.EI2, sec.EI3)
        ga_pen = _GA_PENALTY * 12.0 * ei_max / self.Le**2
        self.shear_rigid = (sec.GA2 is None, sec.GA3 is None)
        GA2 = ga_pen if sec.GA2 is None else float(sec.GA2)
        GA3 = ga_pen if sec.GA3 is None else float(sec.GA3)
        self.elements = BeamElements(self.Le, [sec.EA, GA2, GA3], [sec.GJ, sec.EI2, sec.EI3])
        m = float(sec.m)
        m11 = sec.m22 + sec.m33 if sec.m11 is None else sec.m11
        w = np.full(self.nn, self.Le)
        w[0] = w[-1] = 0.5 * self.Le
        self.md = m * self.Le / 3.0 * np.where((np.arange(self.nn) == 0) | (np.arange(self.nn) == self.nn - 1), 1, 2)
        self.mo = np.full(self.ne, m * self.Le / 6.0)
        self.J = w[:, None] * np.array([m11, sec.m22, sec.m33], dtype=float)[None, :]
        self.mass = m * self.length
        for pm in body.masses:  # rigid bodies lumped at nodes: mass on the node, inertia in section axes
            k = int(round(pm.at / self.Le))
            if abs(pm.at - k * self.Le) > 1e-9 * self.length:
                raise ValueError(f"reference: point mass at {pm.at:g} m is not on a node of the {n_elements}-element mesh "
                                 f"(element length {self.Le:g} m): choose n_elements so that it is")
            self.md[k] += pm.mass
            self.J[k] += np.asarray(pm.inertia, dtype=float)
            self.mass += pm.mass
        self.M_dense = None
        if self.nn <= 80:  # one dense mat-vec beats five sliced updates at these sizes
            self.M_dense = self._mass_columns()
        per = n_elements // nse
        self.port_node = {p.name: (p.node % (nse + 1)) * per for p in body.ports}

    def mass_times(self, vd: np.ndarray) -> np.ndarray:
        """M @ vd for (..., nn, 6) generalized accelerations (translational consistent, rotary lumped)."""
        if vd.ndim == 2 and self.M_dense is not None:
            return (self.M_dense @ vd.ravel()).reshape(vd.shape)
        out = np.empty_like(vd)
        out[..., :3] = self.md[:, None] * vd[..., :3]
        out[..., :-1, :3] += self.mo[:, None] * vd[..., 1:, :3]
        out[..., 1:, :3] += self.mo[:, None] * vd[..., :-1, :3]
        out[..., 3:] = self.J * vd[..., 3:]
        return out

    def _mass_columns(self) -> np.ndarray:
        """Dense M (6 nn x 6 nn), built column by column from the sliced product."""
        eye = np.eye(6 * self.nn).reshape(6 * self.nn, self.nn, 6)
        saved, self.M_dense = self.M_dense, None
        cols = self.mass_times(eye).reshape(6 * self.nn, 6 * self.nn)
        self.M_dense = saved
        return np.ascontiguousarray(cols.T)

    def kinetic_energy(self, v: np.ndarray) -> np.ndarray:
        """0.5 v^T M v for (..., nn, 6) velocities."""
        return 0.5 * np.sum(v * self.mass_times(v), axis=(-2, -1))


# ============================================================================ banded assembly
def mass_properties(mesh: Mesh, x: np.ndarray, R: np.ndarray, v: np.ndarray):
    """(CM (3,), inertia tensor about the CM (3, 3), linear momentum (3,), angular momentum about the CM
    (3,)) of the beam at nodal positions x (nn, 3), rotations R (nn, 3, 3) (section frames) and velocities
    v (nn, 6) (world translational, section-axes angular), world axes: the consistent translational mass
    (exact for the linear interpolation of positions and velocities along each element), the rotary
    inertia lumped at the nodes in section axes (R J R^T), point masses on their nodes."""
    md, mo, vt = mesh.md, mesh.mo, v[:, :3]
    c = (md @ x + mo @ (x[:-1] + x[1:])) / mesh.mass
    y = x - c
    p = md @ vt + mo @ (vt[:-1] + vt[1:])
    h = md @ cross(y, vt) + mo @ (cross(y[:-1], vt[1:]) + cross(y[1:], vt[:-1]))
    h = h + np.einsum("nij,nj->i", R, mesh.J * v[:, 3:])
    S = np.einsum("n,ni,nj->ij", md, y, y) + np.einsum("n,ni,nj->ij", mo, y[:-1], y[1:])
    S = S + S.T - np.einsum("n,ni,nj->ij", md, y, y)  # md y y^T once, the mo pairs both ways
    J_cm = np.trace(S) * np.eye(3) - S + np.einsum("nik,nk,njk->ij", R, mesh.J, R)
    return c, J_cm, p, h


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


# ============================================================================ results
@dataclass(frozen=True, eq=False)
class ReferenceResult:
    t: np.ndarray  # (nt,)
    ports: dict  # port -> {"r","R","v","w","f","t"}; R is relative to the world-aligned reference (R(0) = I)
    nodes_r: np.ndarray  # (nt, n_nodes, 3)
    energy: dict  # "kinetic", "strain", "work_external" (nt,)
    wall_time_s: float
    newton_iterations_mean: float
    port_reference: dict | None = None  # port -> reference position (3,), world
    info: dict | None = None  # n_elements, step, rho_inf, ...
    mass: dict | None = None  # `mass_properties` per step: "cm" (nt, 3), "J_cm" (nt, 3, 3), "p" (nt, 3), "h_cm" (nt, 3)


class StaticResult(NamedTuple):
    r: np.ndarray  # (n_nodes, 3) node positions
    R: np.ndarray  # (n_nodes, 3, 3) node rotations relative to the reference (R = I unloaded)


def _port_outputs(mesh, sc, times, X, Rp, V, Rres, A, h: float = 0.0):
    """Port histories from stored node histories (vectorized over time).

    X (nt, nn, 3), Rp (nt, np, 3, 3) section frames of the port nodes, V (nt, nn, 6),
    Rres (nt, np, 6) equation residuals at the port nodes (the reaction on motion-driven parts),
    A (nt, np, 6) the port nodes' accelerations (world translational, material angular: the world angular
    acceleration is R W_dot, the derivative of R W with R_dot W = R (W x W) = 0).
    """
    out = {}
    loads = None
    for j, p in enumerate(mesh.body.ports):
        k = mesh.port_node[p.name]
        tr, ro = sc.causality[p.name]
        R = Rp[:, j]
        if (tr == "force" or ro == "force") and loads is None:
            FT = [sc.loads_at(float(t), mesh.nn, h) for t in times] if sc.loads else None
            loads = (np.array([a[0] for a in FT]), np.array([a[1] for a in FT])) if FT else (None, None)
        if tr == "motion":
            f = Rres[:, j, :3].copy()
        else:
            f = loads[0][:, k].copy() if loads[0] is not None else np.zeros((len(times), 3))
        if ro == "motion":
            tq = (R @ Rres[:, j, 3:, None])[..., 0]
        else:
            tq = loads[1][:, k].copy() if loads[1] is not None else np.zeros((len(times), 3))
        out[p.name] = {
            "r": X[:, k].copy(),
            "R": R @ mesh.Lam0.T,
            "v": V[:, k, :3].copy(),
            "w": (R @ V[:, k, 3:, None])[..., 0],
            "f": f,
            "t": tq,
            "a": A[:, j, :3].copy(),
            "dw": (R @ A[:, j, 3:, None])[..., 0],
        }
    return out


# ============================================================================ dynamics
def simulate_reference(
    body: Body,
    scene: Scene,
    n_elements: int | None = None,
    step: float | None = None,
    progress: Callable[[float, float], None] | None = None,
    *,
    rho_inf: float | None = None,
    tol: float = 1e-9,
    max_iterations: int = 25,
    duration: float | None = None,
    newton: str = "modified",
    jacobian_age: int = 100,
    predictor: str | None = None,
) -> ReferenceResult:
    """Run `scene` on the full-order geometrically exact beam model of `body`.

    n_elements: default max(16, 4 * superelements), a multiple of body.superelements.
    step: default scene.step (adjusted down to divide the duration into equal steps).
    progress(t, duration) is called about 100 times during the run.
    tol: Newton stops when the last correction moved every node by less than tol * L (positions)
    and tol rad (rotations).
    newton: "modified" (default) reuses the factorized iteration matrix, co-rotated with the body
    (module docstring), for up to `jacobian_age` steps and refreshes it whenever the iteration
    contracts slowly or diverges (the diverging correction is discarded); "full" refactorizes at
    every iteration. Without the co-rotation a matrix older than a step fails on spinning bodies:
    the rigid rotation turns the axial stiffness, which dwarfs the bending one, into the
    transverse directions. Both converge to the same solution (to tol).
    predictor: guess of vdot_{n+1}: "constant" (vdot_n), "linear" (2 vdot_n - vdot_{n-1}; amplifies
    near-Nyquist components), "corotated" (vdot_n with its translational part turned by the
    last step's rotation of the mid node: exact for a steady spin, the B1/B3 situation) or "velocity"
    (a_{n+1} such that the increment h (1/2 - beta) a_n + h beta a_{n+1} of the acceleration is zero:
    the configuration is guessed as q_n o exp(h v_n); for rho_inf = 1, vdot_{n+1} = -vdot_n). Default
    "linear", but "velocity" for an initially deformed body (scene.initial.port_displacements). Why: its
    release drops the fixed end's reaction moment on a node whose rotary inertia is half an element's
    (B4, 32 el.: 4.7e5 rad/s^2), which rings the mesh's top mode (omega h >> 1) and, with rho_inf = 1,
    keeps ringing. There generalized-alpha gives a_{n+1} ~ -a_n, so the acceleration part of the increment
    nearly cancels: a guess that carries a_n over puts that node h^2/4 |a_n + a_{n+1}| = 0.4-0.9 rad off
    (constant: h^2/2 |a_n|; linear, which guesses ~3 a_n: h^2 |a_n|), and the damped Newton (0.1 rad per correction) spends
    10-20 iterations walking back, running out of its 25 at B4 32 el./2 ms (t = 0.936 s with constant; linear:
    0.81 s with 16 el.). Not the convergence test: the failing step's corrections were still shrinking ~11x
    per iteration, 94x above it. The velocity guess is exact for that ringing and off by O(h^2 a) for the smooth
    motion, which Newton removes in one or two corrections: B4 32 el./2 ms 5.4 iterations per step over
    the 10 s (constant: ~13 until it fails), 64 el./2 ms runs (constant fails at the first step), 32 el./1 ms
    4.0 (constant 5.8), the same solution (metric 5e-11 apart; docs/accuracy.md, B4).
    """
    t_wall = time.perf_counter()
    t_cpu = time.process_time()
    if predictor is None:
        predictor = "velocity" if scene.initial.port_displacements else "linear"
    if predictor not in ("constant", "linear", "corotated", "velocity"):
        raise ValueError(f"reference: unknown predictor {predictor!r} (constant, linear, corotated, velocity)")
    mesh = Mesh(body, n_elements)
    sc = _Scene(mesh, body, scene)
    T_end = float(scene.duration if duration is None else duration)
    h = float(scene.step if step is None else step)
    nsteps, h = whole_steps(T_end, h)
    rho = float(scene.rho_inf if rho_inf is None else rho_inf)
    am = (2 * rho - 1) / (rho + 1)
    af = rho / (rho + 1)
    gam = 0.5 + af - am
    bet = 0.25 * (gam + 0.5) ** 2
    ca = (1 - af) / (1 - am)
    beta_p = h * h * bet * ca  # d(position increment)/d(vdot_{n+1})
    gamma_p = h * gam * ca  # d(v_{n+1})/d(vdot_{n+1})
    nn = mesh.nn
    band = _Banded(mesh, sc.free, with_mass=True)
    free = sc.free.reshape(nn, 6)
    J = mesh.J
    el = mesh.elements
    tol_x = tol * mesh.length

    # ---------------- initial state: reference (or relaxed deformed) configuration, rigid velocity field,
    # drives at t=0
    state = getattr(scene.initial, "state", "rest")
    if state == "static":  # the static equilibrium under gravity and the loads acting at t = 0 (initial_state.py)
        loads0: dict = {}
        for ld in scene.loads:
            share = window_share(ld.t_start, ld.t_end, 0.0, 0.0)
            f0, m0 = loads0.get(ld.port, (np.zeros(3), np.zeros(3)))
            loads0[ld.port] = (f0 + share * np.asarray(ld.force, float), m0 + share * np.asarray(ld.moment, float))
        st = static_reference(scene_body(body, scene), loads0, None, n_elements, gravity=scene.gravity)
        x, R = st.r.copy(), st.R @ mesh.Lam0
    elif state == "steady_spin":  # the relative equilibrium at the drive's rate at t = 0 (steady.py)
        from .steady import spin_of, steady_spin_state

        w_spin, phi0, _ = spin_of(scene)
        x, R, v, vd = steady_spin_state(mesh, sc, w_spin, phi0, *sc.loads_at(0.0, nn), banded=_Banded, internal=_internal)
    elif state != "rest":
        raise ValueError(f"reference: initial state {state!r} is not one of rest, static, steady_spin")
    else:
        x, R = relaxed_shape(mesh, scene_body(body, scene), dict(scene.initial.port_displacements))
    if state != "steady_spin":
        v = np.zeros((nn, 6))
        v0 = np.asarray(scene.initial.velocity, float)
        w0 = np.asarray(scene.initial.angular_velocity, float)
        v[:, :3] = v0 + cross(w0, x - mesh.origin)
        v[:, 3:] = np.einsum("nji,j->ni", R, w0)
        vd = np.zeros((nn, 6))
    sc.impose(0.0, x, R, v, vd)
    F, T = sc.loads_at(0.0, nn)  # the loads acting at t = 0: a consistent start (as the body's runs)
    fint, st = _internal(mesh, x, R)
    fa = _applied(sc, R, F, T)
    r = mesh.mass_times(vd) + fint - fa
    r[:, 3:] += cross(v[:, 3:], J * v[:, 3:])
    fac = band.factor(np.zeros((mesh.ne, 12, 12)), None)
    vd = vd + band.solve(fac, -r.ravel()).reshape(nn, 6)
    r = mesh.mass_times(vd) + fint - fa
    r[:, 3:] += cross(v[:, 3:], J * v[:, 3:])
    a = vd.copy()

    # ---------------- outputs
    nt = nsteps + 1
    times = np.linspace(0.0, T_end, nt)
    pnodes = np.array([mesh.port_node[p.name] for p in body.ports], dtype=int)
    nodes_r = np.empty((nt, nn, 3))
    V_hist = np.empty((nt, nn, 6))
    Rp_hist = np.empty((nt, len(pnodes), 3, 3))
    res_hist = np.empty((nt, len(pnodes), 6))
    acc_hist = np.empty((nt, len(pnodes), 6))
    mass_hist = {"cm": np.empty((nt, 3)), "J_cm": np.empty((nt, 3, 3)), "p": np.empty((nt, 3)), "h_cm": np.empty((nt, 3))}
    e_str = np.empty(nt)
    work = np.empty(nt)
    presc = ~free

    def record(i, x, R, v, vd, r, F, T, fa, st):
        nodes_r[i] = x
        acc_hist[i] = vd[pnodes]
        V_hist[i] = v
        Rp_hist[i] = R[pnodes]
        res_hist[i] = r[pnodes]
        for key, value in zip(("cm", "J_cm", "p", "h_cm"), mass_properties(mesh, x, R, v)):
            mass_hist[key][i] = value
        e_str[i] = el.energy_from(st).sum()
        return ((fa + presc * r) * v).sum()  # external power (applied loads, gravity, reactions)

    power = record(0, x, R, v, vd, r, F, T, fa, st)
    work[0] = 0.0
    iters_total = 0
    every = max(1, nsteps // 100)

    fac = None
    R_fac = None
    kref = nn // 2
    refresh = True
    fac_age = 0
    n_factor = 0
    vd_prev = vd
    R_prev = None
    for n in range(nsteps):
        t1 = times[n + 1]
        x0, R0, v0_, vd0, a0 = x, R, v, vd, a
        F, T = sc.loads_at(t1, nn, h)
        base_inc = v0_ + h * (0.5 - bet) * a0
        base_v = v0_ + h * (1 - gam) * a0
        base_a = (af * vd0 - am * a0) / (1 - am)
        if predictor == "linear":
            vd1 = 2.0 * vd0 - vd_prev
        elif predictor == "velocity":
            # a_{n+1} = -(1/2 - beta)/beta a_n: no acceleration part in the guessed increment
            vd1 = (-(0.5 - bet) / bet * a0 - base_a) / ca
        else:
            vd1 = vd0.copy()
            if predictor == "corotated" and R_prev is not None:
                # nodal accelerations of a spinning body turn with it: rotate them by the last
                # step's rotation of the reference node (exact for a steady rigid spin)
                Qs = R0[kref] @ R_prev[kref].T
                vd1[:, :3] = vd0[:, :3] @ Qs.T
        x1 = x0.copy()
        R1 = R0.copy()
        v1 = np.empty_like(v0_)
        # prescribed values at t1 (positions and rotations fixed during the iterations)
        sc.impose(t1, x1, R1, v1, vd1)
        converged = False
        dx = dth = prev = corr = float("nan")
        for it in range(max_iterations + 1):
            a1 = base_a + ca * vd1
            inc = base_inc + h * bet * a1
            v1[:] = np.where(free, base_v + h * gam * a1, v1)
            hinc = h * inc[:, 3:]
            x1 = np.where(free[:, :3], x0 + h * inc[:, :3], x1)
            if refresh or fac is None:
                Eh, Tm = expm(hinc), tangent(hinc)
            else:
                Eh = expm(hinc)
            R1 = np.where(free[:, 3:4, None], R0 @ Eh, R1)
            if converged and corr < 1e-2:
                # the last correction was far below the tolerance: the residual, reactions and
                # strain energy of the previous iterate are exact to ~1e-2 tol; skip re-evaluation
                break
            fint, st = _internal(mesh, x1, R1)
            fa = _applied(sc, R1, F, T)
            W = v1[:, 3:]
            JW = J * W
            r = mesh.mass_times(vd1) + fint - fa
            r[:, 3:] += cross(W, JW)
            if converged:
                break
            if it == max_iterations or not np.all(np.isfinite(r)):
                raise RuntimeError(
                    f"reference: Newton failed at t={t1:.6g} s (step {n + 1}/{nsteps}, h={h:.3g} s) after {it} "
                    f"iterations; last correction {dx:.3e} m / {dth:.3e} rad, residual {np.abs(r * free).max():.3e}"
                )
            if refresh or fac is None:
                Ke = el.tangent_from(st) * beta_p
                Ke[:, :, 3:6] = Ke[:, :, 3:6] @ Tm[:-1]
                Ke[:, :, 9:12] = Ke[:, :, 9:12] @ Tm[1:]
                Kr = gamma_p * (skew(W) * J[:, None, :] - skew(JW))
                if sc.has_moments:
                    Kr = Kr - beta_p * skew(np.einsum("nji,nj->ni", R1, T)) @ Tm
                fac = band.factor(Ke, Kr)
                R_fac = R1[kref].copy()
                n_factor += 1
                fac_age = 0
                refresh = newton == "full"
            # co-rotated reuse: for a configuration rigidly rotated by Q the iteration matrix is
            # P S P^T with P = diag(Q on nodal translations, I on material rotations) (M is
            # isotropic, the rotational dofs are material): S'^-1 = P S^-1 P^T. Q is estimated
            # from the rotation of a reference node since the factorization.
            Q = R1[kref] @ R_fac.T
            rhs = -r
            rhs[:, :3] = rhs[:, :3] @ Q
            dvd = band.solve(fac, rhs.ravel()).reshape(nn, 6)
            dvd[:, :3] = dvd[:, :3] @ Q.T
            iters_total += 1
            dx = beta_p * np.abs(dvd[:, :3]).max()
            dth = beta_p * np.abs(dvd[:, 3:]).max()
            corr = max(dx / tol_x, dth / tol)
            if corr > prev and fac_age > 0:
                # a stale iteration matrix made the iteration diverge: drop this correction, go back to
                # the best iterate and continue from there with a fresh matrix
                vd1 = vd_best
                refresh = True
                prev = float("nan")
                continue
            vd_best = vd1
            # damped Newton: a correction may turn a node by at most 0.1 rad and move it by at most
            # a tenth of an element (a suddenly applied nodal moment on a node with small rotary
            # inertia can otherwise throw the first iterates out of the basin of convergence)
            damp = min(1.0, 0.1 / max(dth, 1e-300), 0.1 * mesh.Le / max(dx, 1e-300))
            vd1 = vd1 + damp * dvd
            converged = corr < 1.0
            if corr > 0.1 * prev:  # slow contraction: fresh iteration matrix for the next correction
                refresh = True
            prev = corr
        fac_age += 1
        if it > 3 or fac_age >= jacobian_age:
            refresh = True
        # dvd for prescribed dofs is zero; keep drive accelerations there
        vd_prev = vd0
        R_prev = R0
        x, R, v, vd = x1, R1, v1.copy(), vd1
        a = base_a + ca * vd1
        p1 = record(n + 1, x, R, v, vd, r, F, T, fa, st)
        work[n + 1] = work[n] + 0.5 * h * (power + p1)
        power = p1
        if progress is not None and ((n + 1) % every == 0 or n + 1 == nsteps):
            progress(float(t1), T_end)

    P = _port_outputs(mesh, sc, times, nodes_r, Rp_hist, V_hist, res_hist, acc_hist, h)
    e_kin = mesh.kinetic_energy(V_hist)
    # energy error of the run: |kinetic + strain - work - initial energy| relative to the largest
    # energy level;
    # O(h^2) plus the rho_inf dissipation. Large values flag a step too large for the spin rate:
    # generalized-alpha (like every Newmark-type scheme) has no nonlinear stability guarantee, and
    # a stiff beam spinning fast (B1 profile at 12 rad/s with h = 20 ms, rho_inf 0.8) can go
    # unstable; measured energy errors are ~0.2 % for B1 at h = 20 ms.
    scale = max(float(np.max(np.abs(e_kin + e_str))), float(np.max(np.abs(work))), 1e-300)
    energy_error = float(np.max(np.abs(e_kin + e_str - work - e_kin[0] - e_str[0]))) / scale
    if energy_error > ENERGY_ERROR_SUSPECT:
        warnings.warn(
            f"reference: energy error {100 * energy_error:.2g} % of the energy level (h = {h:.3g} s, "
            f"rho_inf = {rho}): the step is probably too large for this motion; halve it and compare",
            RuntimeWarning,
            stacklevel=2,
        )
    wall = time.perf_counter() - t_wall
    return ReferenceResult(
        t=times,
        ports=P,
        nodes_r=nodes_r,
        energy={"kinetic": e_kin, "strain": e_str, "work_external": work},
        wall_time_s=wall,
        newton_iterations_mean=iters_total / nsteps,
        port_reference={p.name: mesh.X[mesh.port_node[p.name]].copy() for p in body.ports},
        info={"n_elements": mesh.ne, "step": h, "rho_inf": rho, "n_steps": nsteps, "tol": tol,
              "factorizations": n_factor, "newton": newton, "cpu_time_s": time.process_time() - t_cpu,
              "energy_error": energy_error},
        mass=mass_hist,
    )


# ============================================================================ statics
def relaxed_shape(mesh: Mesh, body: Body, displacements: dict, *, load_steps: int = 5, tol: float = 1e-10,
                  max_iterations: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """The initially deformed body (scene.initial.port_displacements {port: u}), as the runtime makes it
    (BodySystem._relax): static equilibrium without loads or inertia with every undisplaced port's
    translation and rotation fixed, each displaced port fixed only along its u (at u.(x - X) = |u|, free
    across u: a force along u moved it there) and its rotation free unless motion-driven: for a free beam
    with its far end displaced, the cantilever shape. The constraints enter as Lagrange multipliers: two
    banded solves per constraint and iteration (bordered system). Nodal (x, R) with R including the section
    frame Lam0; the reference configuration when nothing is displaced."""
    nn = mesh.nn
    x = mesh.X.copy()
    R = np.repeat(mesh.Lam0[None], nn, axis=0)
    if not displacements:
        return x, R
    unknown = set(displacements) - {p.name for p in body.ports}
    if unknown:
        raise ValueError(f"reference: initial displacements of unknown ports {sorted(unknown)}")
    presc = np.zeros((nn, 6), bool)
    displaced = []  # (node, unit direction, |u|) of the displaced ports
    for p in body.ports:
        k = mesh.port_node[p.name]
        u = np.asarray(displacements.get(p.name, np.zeros(3)), float)
        if np.linalg.norm(u) == 0.0:
            presc[k, :3] = True
        else:
            displaced.append((k, u / np.linalg.norm(u), float(np.linalg.norm(u))))
        if p.name not in displacements or p.rotation == "motion":
            presc[k, 3:] = True
    band = _Banded(mesh, (~presc).ravel(), with_mass=False)
    C = np.zeros((len(displaced), nn, 6))
    for j, (k, e, _) in enumerate(displaced):
        C[j, k, :3] = e
    C = C.reshape(len(displaced), -1)
    d = np.zeros((nn, 6))
    for step in range(1, load_steps + 1):
        for _ in range(max_iterations):
            fint, st = _internal(mesh, x, R)
            try:
                fac = band.factor(mesh.elements.tangent_from(st), None)
            except np.linalg.LinAlgError:  # the fixed parts leave the body a mechanism: no unique shape
                d[:] = np.inf
                break
            y1 = band.solve(fac, -fint.ravel())
            Y2 = np.column_stack([band.solve(fac, c) for c in C] or [np.zeros(len(y1))])[:, : len(C)]
            gap = np.array([step / load_steps * size - e @ (x[k] - mesh.X[k]) for k, e, size in displaced])
            lam = np.linalg.solve(C @ Y2, gap - C @ y1)
            d = (y1 + Y2 @ lam).reshape(nn, 6)
            if not np.all(np.isfinite(d)):
                break
            x, R, converged = newton_update(x, R, d, mesh.length, tol)
            if converged:
                break
        else:
            d[:] = np.inf
        if not np.all(np.isfinite(d)):
            raise RuntimeError(f"reference: initial port displacements {sorted(displacements)}: no static equilibrium "
                               f"of the deformed body ({max_iterations} Newton iterations); smaller displacements, or "
                               "ports whose displacements the body can hold")
    return x, R


def static_reference(
    body: Body,
    loads: dict,
    fixed=None,
    n_elements: int | None = None,
    *,
    gravity=(0.0, 0.0, 0.0),
    load_steps: int = 10,
    tol: float = 1e-10,
    max_iterations: int = 30,
) -> StaticResult:
    """Static equilibrium under dead port loads {port: (force(3), moment(3))} in world axes
    (and gravity acting on the consistent mass, scaled with the loads).

    fixed: port names clamped at the reference (position and rotation); None -> every port part
    whose causality is "motion" in the body is fixed at the reference. Newton with `load_steps`
    equal load increments.
    """
    mesh = Mesh(body, n_elements)
    nn = mesh.nn
    presc = np.zeros((nn, 6), bool)
    for p in body.ports:
        k = mesh.port_node[p.name]
        if fixed is None:
            presc[k, :3] |= p.translation == "motion"
            presc[k, 3:] |= p.rotation == "motion"
        elif p.name in set(fixed):
            presc[k] = True
    if fixed is not None:
        unknown = set(fixed) - {p.name for p in body.ports}
        if unknown:
            raise ValueError(f"reference: unknown fixed ports {sorted(unknown)}")
    free = ~presc
    band = _Banded(mesh, free.ravel(), with_mass=False)
    Ftot = np.zeros((nn, 3))
    Ttot = np.zeros((nn, 3))
    for name, (f, m) in loads.items():
        k = mesh.port_node[body.port(name).name]
        Ftot[k] += np.asarray(f, float)
        Ttot[k] += np.asarray(m, float)
    g = np.asarray(gravity, dtype=float)
    Ftot += (mesh.md + np.concatenate([mesh.mo, [0.0]]) + np.concatenate([[0.0], mesh.mo]))[:, None] * g
    x = mesh.X.copy()
    R = np.repeat(mesh.Lam0[None], nn, axis=0)
    for step in range(1, load_steps + 1):
        lam = step / load_steps
        for it in range(max_iterations):
            fint, st = _internal(mesh, x, R)
            Tmat = np.einsum("nji,nj->ni", R, lam * Ttot)
            r = fint.copy()
            r[:, :3] -= lam * Ftot
            r[:, 3:] -= Tmat
            Ke = mesh.elements.tangent_from(st)
            Kr = -skew(Tmat)
            d = band.solve(band.factor(Ke, Kr), -r.ravel()).reshape(nn, 6)
            x, R, converged = newton_update(x, R, d, mesh.length, tol)
            if converged:
                break
        else:
            raise RuntimeError(f"reference: static Newton did not converge at load factor {lam:.3g}")
    return StaticResult(r=x, R=R @ mesh.Lam0.T)


def tip_from_hub(result: ReferenceResult, hub: str = "hub", tip: str = "tip") -> np.ndarray:
    """Elastic tip displacement seen from the hub, eq. (92) (runtime/outputs.py tip_from_hub):
    R_hub^T (r_tip - r_hub) - X_tip.

    X_tip is the tip's reference position relative to the hub's (world-aligned reference frame,
    so the components are along the model axes at rest). Shape (nt, 3).
    """
    ph, pt = result.ports[hub], result.ports[tip]
    X_tip = result.port_reference[tip] - result.port_reference[hub]
    return eq92_tip_from_hub(ph["R"], ph["r"], pt["r"], X_tip)
