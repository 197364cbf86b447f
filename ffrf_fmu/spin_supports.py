"""The term rule's measurement for a spin held by compliant supports and loaded by a rotating unbalance
(the Jeffcott run-up, models/jeffcott_runup.toml; docs/inertia-terms.md, "The Jeffcott rotor").

term_rule.steady_term_effects measures the terms on the relative equilibrium of a body whose spin a
motion-driven rotation prescribes and whose other ports are free: a balanced rotor on compliant bearings,
spun through a compliant drive spring, spins there undeformed and shows nothing. What the terms change on
it is the whirl. A rotating unbalance m e is a load fixed in the spinning frame (m e Omega^2 along its
direction rho at psi = 0, simulate/inputs.unbalance_force at a constant rate), so the synchronous whirl of
the body on its bearings is, in the spinning frame, a relative equilibrium: the body's residual (runtime
equations, linear.py's block comment: J = F_y + F_ydot P) plus the supports' spring-dampers
(runtime/coupling.py) with their far ends fixed in space on the spin axis (a spring isotropic across the
axis gives the same force in every rotated frame, its damper C (0 - Omega x u) the stationary damping), the
drive spring's far end turning with the spin, and the unbalance forces.

Why the response at the scene's top rate measures a run-up's peak: one whirl mode passed at the angular
acceleration alpha peaks at A ~ e_eff omega_c / sqrt(alpha) (the Jeffcott equation z'' + omega_c^2 z = e
(psi'^2 - i psi'') exp(i psi) in tau = omega_c t has the one parameter alpha / omega_c^2, and for a slow
passage the Fresnel asymptote is ~ (omega_c^2 / alpha)^(1/2)), e_eff the modal unbalance over the modal mass.
Above the crossing the synchronous whirl is e_eff Omega^2 / (Omega^2 - omega_c^2): it carries e_eff and
omega_c alike (d ln / d ln omega_c = 2 omega_c^2 / (Omega^2 - omega_c^2), 2/3 at Omega = 2 omega_c, against 1
for the peak). Measured on the Jeffcott run-up (docs/inertia-terms.md): each term set's and switch's change of
this response against full is 0.84-1.33 x its change of the run-up's peak. What it cannot see: the Coriolis
coupling acts on velocities in the spinning frame, nil in a steady whirl, and on the passage's free whirl it moved
the peak by 0.45 % (W1 + W2 against all four switches). The critical speed of
each set (the undamped synchronous response's pole, by secant on Omega^2 / a(Omega^2), linear in Omega^2
for one mode) is reported beside it.

A balanced spin under gravity across the axis (jeffcott_rotor.toml, scene spin): the weight, constant in the world,
turns backward in the spinning frame at the spin rate, a load at the spin frequency as an unbalance is; the terms are
measured on its steady harmonic response about the undeformed relative equilibrium (gravity_whirl), read at the
boundary nodes and the CM frames (the supports' reactions carry the weight with every term set).
"""
from __future__ import annotations

import numpy as np

from .model import Body, Scene
from .spin import scene_spin

NEWTON_TOL = 1e-10  # m (and m/s, rad): the largest Newton correction at convergence
NEWTON_MAX = 40
# critical_speed's points: 3 % below the secant's estimate, in Newton's reach (the plain secant's points close in on
# the pole, where Newton lost the whirl); the estimate from two points 3 % below the pole is off by g's curvature:
# 7.5e-4 high on the Jeffcott rotor (linear 172.22 against 172.09 rad/s of a plain secant that converged)
APPROACH = 0.97


def _support_check(data, axis: np.ndarray, drive: str, length: float) -> str | None:
    """Why the compliant supports of `data` have no relative equilibrium spinning about `axis`, or None."""
    if np.count_nonzero(np.abs(axis) > 1e-12) != 1:
        return "spin axis not along a world axis: the supports' diagonal springs are not isotropic across it"
    a = int(np.argmax(np.abs(axis)))
    across = [i for i in range(3) if i != a]
    for p in data.ports:
        if "motion" in (p.translation, p.rotation):
            return f"port {p.name}: a motion-driven part beside a compliant drive spring"
        if not p.compliance:
            continue
        Kt, Ct, Kr, Cr = np.asarray(p.compliance, dtype=float).reshape(4, 3)
        if p.translation == "compliant":
            x = np.asarray(data.node_positions[p.node], dtype=float)
            if np.linalg.norm(np.cross(axis, x)) > 1e-9 * length:
                return f"support {p.name}: its housing is off the spin axis"
            if Kt[across[0]] != Kt[across[1]] or Ct[across[0]] != Ct[across[1]]:
                return f"support {p.name}: its spring is not isotropic across the spin axis"
        if p.rotation == "compliant" and p.name != drive and (Kr[a] != 0.0 or Cr[a] != 0.0):
            return f"support {p.name}: a rotational spring about the spin axis that is not the drive's brakes the spin"
    return None


def _forces(system, w: np.ndarray, unbalances, damping: bool, drive: str):
    """(F, J, F_ydot) on the unknowns: the spinning frame's residual and matrices (linear._spin_system) with the
    compliant supports' spring-dampers and the unbalance forces (module doc)."""
    from .linear import _spin_system
    from .runtime.coupling import spring_force, spring_moment
    from .runtime.rotation import skew

    F, J, Fz = _spin_system(system, w)
    F, J, Fz = F.copy(), J.copy(), Fz.copy()
    pos = np.full(system.layout.ny, -1)
    pos[system.unknowns] = np.arange(len(system.unknowns))
    data = system.data
    for name, (k, trans, rot) in system.compliant.items():
        Kt, Ct, Kr, Cr = (c if damping or i % 2 == 0 else 0.0 * c for i, c in enumerate(system.compliance[name]))
        i = 6 * k
        if trans:  # far end: the housing at the node's reference position, at rest
            f = spring_force(Kt, Ct, data.node_positions[k], np.zeros(3), system.xN[k], system.yd[i:i + 3])
            r = pos[i:i + 3]
            F[r] -= f
            J[np.ix_(r, r)] += np.diag(Kt) + np.diag(Ct) @ skew(w)  # d(xdot) = xi' + w x xi
            Fz[np.ix_(r, r)] += np.diag(Ct)
        if rot:  # the drive spring's far end turns with the spin; another's is fixed (no stiffness about the axis)
            w_in = w if name == drive else np.zeros(3)
            m, dm = spring_moment(Kr, Cr, np.eye(3), w_in, system.RN[k], system.yd[i + 3:i + 6])
            r = pos[i + 3:i + 6]
            F[r] -= m
            J[np.ix_(r, r)] += -dm + np.diag(Cr) @ skew(system.RN[k].T @ w)  # d(W) = dTheta' + W x dTheta
            Fz[np.ix_(r, r)] += np.diag(Cr)
    for node, f in unbalances:
        F[pos[6 * node:6 * node + 3]] -= f * float(w @ w)
    return F, J, Fz


def synchronous_whirl(system, rate: float, axis, unbalances, drive: str, damping: bool = True) -> np.ndarray:
    """The boundary nodes' displacements (N, 3; world = spinning frame at psi = 0) of the synchronous whirl
    at the constant rate about `axis` through the origin: Newton from the reference state spinning.
    unbalances: [(node, m e rho)] (the force per Omega^2)."""
    w = rate * np.asarray(axis, dtype=float)
    system.reset_reference()
    system.v[:, 0:3] = np.cross(w, system.x0)
    system.v[:, 3:6] = w @ system.R0
    for _ in range(NEWTON_MAX):
        F, J, _ = _forces(system, w, unbalances, damping, drive)
        d = np.zeros(system.layout.ny)
        d[system.unknowns] = np.linalg.solve(J, -F)
        system.move(d)
        if np.abs(d).max() < NEWTON_TOL:
            return system.xN - system.data.node_positions
    raise RuntimeError(f"synchronous whirl at {rate:.4g} rad/s: Newton did not converge "
                       f"(last correction {np.abs(d).max():.3g})")


def gravity_whirl(system, rate: float, axis, gravity, drive: str) -> np.ndarray:
    """The complex displacement amplitudes X (N + E, 3; spinning frame, xi = Re(X exp(i Omega t))) of the boundary
    nodes and then of the superelements' CM frames (the bearings' reactions carry the weight whatever the terms, so
    the shaft's sag is read at the CM frames)
    of the steady response of the balanced spin to the gravity across `axis` (module doc, last paragraph):
    about the undeformed relative equilibrium (synchronous_whirl without unbalance, the gravity along the
    axis in it), the linearized spinning-frame system F_ydot xi' + J xi + B g_s(t) = 0 with the world's g
    seen as g_s(t) = R(Omega t)^T g = Re((g + i axis x g) exp(i Omega t)), so (i Omega F_ydot + J) X = -B (g + i axis x g)."""
    a = np.asarray(axis, dtype=float)
    g = np.asarray(gravity, dtype=float)
    g_axis = float(g @ a) * a
    g_across = g - g_axis
    w = rate * a
    system.gravity = g_axis
    synchronous_whirl(system, rate, a, [], drive)
    F0, J, Fz = _forces(system, w, [], True, drive)
    B = []
    for v in (g_across, np.cross(a, g_across)):
        system.gravity = g_axis + v
        B.append(_forces(system, w, [], True, drive)[0] - F0)
    system.gravity = g_axis
    X = np.linalg.solve(1j * rate * Fz + J, -(B[0] + 1j * B[1]))
    d = np.zeros(system.layout.ny, dtype=complex)
    d[system.unknowns] = X
    nodes = np.arange(len(system.data.node_positions))
    return np.vstack([d[(6 * nodes)[:, None] + np.arange(3)], d[system.layout.cfg_map[:, 0:3]]])


def critical_speed(system, axis, unbalances, drive: str, top: float) -> float | None:
    """The lowest undamped critical speed [rad/s]: the pole of the synchronous whirl a (the first unbalance's
    node along its force), the zero of g(Omega^2) = Omega^2 / a, which is (omega_c^2 - Omega^2) / e_eff for one
    mode. Secant from 0.2 and 0.3 x `top`, each next point APPROACH below the secant's zero; None when the zero is not below 2 x `top` (the
    critical speed is reported, not used by the rule)."""
    node, f = unbalances[0]
    d = f / np.linalg.norm(f)
    g = lambda o2: o2 / float(synchronous_whirl(system, np.sqrt(o2), axis, unbalances, drive, False)[node] @ d)  # noqa: E731
    a, b = (0.2 * top) ** 2, (0.3 * top) ** 2
    zero = None
    try:
        ga, gb = g(a), g(b)
        for i in range(30):
            c = b - gb * (b - a) / (gb - ga)
            if not 0.0 < c < (2 * top) ** 2:
                return None
            done = i > 0 and abs(c - zero) < 1e-9 * c
            zero = c
            if done:
                break
            a, ga, b = b, gb, APPROACH**2 * c
            gb = g(b)
    except (RuntimeError, np.linalg.LinAlgError):
        pass  # Newton lost the whirl: the last estimate stands
    return None if zero is None else float(np.sqrt(zero))


def supported_measure(body: Body, scene: Scene, *, stiffening: bool = False) -> dict:
    """What term_rule.steady_term_effects measures the terms on for a spin through a compliant drive spring
    (spin.spin_drive_rotation "compliant"): the keyword arguments of term_rule.measured_term_effects but
    `stiffening` (the reduced data, displacements(system), its text, ...). On the synchronous whirl at the scene's
    top rate (module doc), with the critical speed per term set [rad/s] for an unbalance; or on the steady response
    to the gravity across the axis (gravity_whirl) of a balanced spin. {"status": why} when there is nothing to
    measure."""
    from .reduction import reduce_body

    spin = scene_spin(scene)
    rate, axis = spin.peak, spin.axis
    g = np.asarray(scene.gravity, dtype=float)
    g_across = g - float(g @ axis) * axis
    weighed = not scene.unbalances and np.linalg.norm(g_across) > 0.0
    if not scene.unbalances and not weighed:
        return {"status": f"spin through the compliant drive spring {spin.port}.rotation without an unbalance or "
                          "gravity across the axis: the balanced body spins undeformed, nothing steady to evaluate "
                          "the terms on"}
    data = reduce_body(body, stiffening=stiffening, inertia=True).data
    why = _support_check(data, axis, spin.port, float(np.ptp(data.node_positions, axis=0).max()) or 1.0)
    if why:
        return {"status": f"no synchronous whirl to evaluate the terms on: {why}"}
    unbalances = []
    for ub in scene.unbalances:
        e1 = np.asarray(ub.reference, dtype=float)
        e1 = e1 - (e1 @ axis) * axis
        e1 /= np.linalg.norm(e1)
        rho = np.cos(ub.phase) * e1 + np.sin(ub.phase) * np.cross(axis, e1)
        unbalances.append((data.port(ub.port).node, ub.mass_eccentricity * rho))
    if weighed:  # no unbalance to find a critical speed by
        whirl, critical = lambda system: gravity_whirl(system, rate, axis, g, spin.port), None  # noqa: E731
    else:
        whirl = lambda system: synchronous_whirl(system, rate, axis, unbalances, spin.port)  # noqa: E731
        critical = lambda system: critical_speed(system, axis, unbalances, spin.port, rate)  # noqa: E731
    return {"data": data, "displacements": whirl, "rate": rate, "axis": axis, "critical": critical,
            "failure": "synchronous whirl", "backend": "numpy",
            "measure": (f"the {'steady response to the gravity across the axis' if weighed else 'synchronous whirl of the unbalance'}"
                        f" at {rate:.3g} rad/s on the compliant supports (drive spring {spin.port}.rotation; spin_supports.py)")}
