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

Over 400 lines: the dynamic run, its step and its Newton share the state arrays of one loop; the mesh and mass data are in reference/mesh.py, the
banded matrix, scene tables and nodal forces both Newtons share in reference/assembly.py, the static
relaxation and equilibrium in reference/statics.py, the element forces and tangents in reference/beam.py,
the steady start in reference/steady.py.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..model import Body, Scene, scene_body
from ..runtime.drives import window_share
from ..runtime.outputs import tip_from_hub as eq92_tip_from_hub
from ..runtime.rotation import cross, expm, skew, tangent
from ..runtime.steps import whole_steps
from .assembly import _applied, _Banded, _internal, _Scene
from .mesh import Mesh, mass_properties
from .statics import relaxed_shape, static_reference


# an energy error (|kinetic + strain - work - initial| / energy level) above this makes the run suspect:
# the solver warns, and the chart and the spin map mark what they compared against it
ENERGY_ERROR_SUSPECT = 0.02



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
    if getattr(scene, "unbalances", ()):
        raise ValueError(f"reference: scene {scene.name!r} has scenes.{scene.name}.unbalances, which the full-order "
                         "reference does not model (it has constant loads only); run it with the reduced body")
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


def tip_from_hub(result: ReferenceResult, hub: str = "hub", tip: str = "tip") -> np.ndarray:
    """Elastic tip displacement seen from the hub, eq. (92) (runtime/outputs.py tip_from_hub):
    R_hub^T (r_tip - r_hub) - X_tip.

    X_tip is the tip's reference position relative to the hub's (world-aligned reference frame,
    so the components are along the model axes at rest). Shape (nt, 3).
    """
    ph, pt = result.ports[hub], result.ports[tip]
    X_tip = result.port_reference[tip] - result.port_reference[hub]
    return eq92_tip_from_hub(ph["R"], ph["r"], pt["r"], X_tip)
