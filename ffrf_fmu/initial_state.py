"""Where a scene's body starts ([scenes.NAME.initial] state, docs/model-format.md): "rest" (the undeformed
body, the rigid velocity field of the initial values: every run before this option), "static" (the static
equilibrium under gravity and the loads acting at t = 0, the motion-driven ports where their drives put
them) or "steady_spin" (the relative equilibrium of the body whose motion-driven ports spin at the rotation
drive's rate at t = 0: deformed by the centrifugal load, every point moving with the spin). Either way the
first step starts from an equilibrium, so a run, or a co-simulation, does not begin with the transient of
a body released undeformed. An FMU built from such a scene starts from the same state, made at build time
(fmu/builder.py `start_states`, runtime/start.py).

Both are the relative equilibrium of linear.py (block comment "The runtime equations linearized about a
steady spin"): with the rates of the steady motion ydot(y) = P-rule for the spin w (w = 0: static),
Newton on F(y, ydot(y)) + port loads = 0 with the matrix J = F_y + F_ydot P (the loads' dependence on the
node rotations is left out of J: a moment load converges linearly). The integrator's history (rates, the
generalized-alpha accelerations) is set to the steady rates: the equilibrium's accelerations are exact.
"""
from __future__ import annotations

import numpy as np

from .model import steady_spin_drive
from .runtime.ports import StepFailure


def _spin(scene, t0: float) -> np.ndarray:
    """The spin vector w of the scene's rotation drive at t0 (steady_spin): rate x axis; its angular
    acceleration must be 0 there (a steady spin: model.steady_spin_drive, which the parser checks at t = 0)."""
    d, rate = steady_spin_drive(scene.name, scene.drives, t0)
    axis = np.asarray(d.rotation.axis, dtype=float)
    return rate * axis / np.linalg.norm(axis)


def settle(system, scene, inputs, t0: float = 0.0, tol: float = 1e-10, max_iter: int = 40) -> None:
    """Bring an initialized BodySystem (BodySystem.initialize at t0) to the scene's initial state
    (module doc); "rest" leaves it as it is. inputs: the scene's input function (simulate.scene_inputs);
    the loads taken are those acting at t0 itself (a window from t0 on: the equilibrium it holds). Newton
    stops at a correction below tol (linear.correction)."""
    state = scene.initial.state
    if state == "rest":
        return
    from .linear import _spin_operator, _spin_rates, correction  # (scipy: only a scene that starts settled pays its import)
    from .runtime.drives import window_share

    if any("compliant" in (p.translation, p.rotation) for p in system.data.ports):
        raise ValueError(f"scene {scene.name!r}: initial state {state!r} is not available with compliant ports")
    w = _spin(scene, t0) if state == "steady_spin" else np.zeros(3)
    values = inputs(t0)
    # the loads at the instant t0 (inputs(t0) gives the mean over the step ending at t0)
    by_port = {p.name: p for p in system.data.ports}
    for name, pv in values.items():
        f, m = np.zeros(3), np.zeros(3)
        for ld in scene.loads:
            if ld.port == name:
                share = window_share(ld.t_start, ld.t_end, t0, t0)
                f += share * np.asarray(ld.force, float)
                m += share * np.asarray(ld.moment, float)
        if by_port[name].translation == "force":
            pv.f = f
        if by_port[name].rotation == "force":
            pv.t = m
    _, _, _, f_in, t_in = system._read_inputs(t0, values)
    L = system.layout
    fi = system.unknowns
    n_node = 6 * L.n_nodes
    if state == "steady_spin":  # every point moving with the spin
        system.v[:, 0:3] = np.cross(w, system.x0)
        system.v[:, 3:6] = w @ system.R0
    step = np.inf
    for _ in range(max_iter):
        system.yd = _spin_rates(system, w)
        F = np.zeros(L.ny)
        F[fi] = system.residual(system.yd)
        F[:n_node] += system._loads(system.RN, f_in, t_in).ravel()
        Fz, Fy = system.linearization()
        J = Fy + Fz @ _spin_operator(system, w)[np.ix_(fi, fi)]
        d = np.zeros(L.ny)
        try:
            d[fi] = np.linalg.solve(J, -F[fi])
        except np.linalg.LinAlgError:
            d[:] = np.inf
        if not np.all(np.isfinite(d)):
            raise StepFailure(t0, f"initial state {state!r}: the body has no unique equilibrium (a free body, or a "
                                  "mechanism: hold its rigid motion with motion-driven ports)")
        step = correction(system, d)
        system.move(d)
        if step < tol:
            break
    else:
        raise StepFailure(t0, f"initial state {state!r}: Newton did not converge in {max_iter} iterations (last "
                              f"correction {step:.3g}): the loads or the spin are beyond what the body holds")
    from .runtime.start import finish

    yd = _spin_rates(system, w)
    system.yd = yd
    system.yd_prev = yd.copy()
    system.yd_prev2 = yd.copy()
    system.a = yd.copy()
    finish(system, f_in, t_in)
