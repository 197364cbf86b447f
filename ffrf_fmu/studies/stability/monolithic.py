"""Monolithic references of the co-simulation scenes: each coupled system as one standalone run,
without FMUs and without the co-simulation master whose schemes the map judges.

 B5 (`b5_monolithic`): the beam, the torsional shaft, the hub inertia and the PI drive integrated
    together. The shaft is the beam's compliant hub rotation (runtime/coupling.py: stiffness
    [0, 0, k] in nodal axes, the two other axes free as in the force-driven B5; hub translation fixed
    at the origin), whose far end is the hub. The hub is a rigid inertia J about the fixed Z axis,
        J theta'' = Kp (omega_ref(t) - theta') + Ki z - t_s,     z' = omega_ref(t) - theta',
    with t_s the shaft moment on the beam (the spring's, read from the body) and z the controller's
    integral. With z(0) = theta(0) = 0, z = phi_ref(t) - theta exactly (phi_ref the Wu-Haug angle law,
    whose rate is omega_ref), so the PI law is a spring Ki and a damper Kp towards the reference
    motion and the hub has the state (theta, omega) only.
    Both are integrated by the body's first-order generalized-alpha (simulate/partner.py;
    runtime/integrator.py: the same rho_inf, am, af, gamma, equations enforced at t_{n+1}): per step the hub's one unknown,
    its angular acceleration rate s = omega'_{n+1}, fixes theta_{n+1} and omega_{n+1} (affine in s),
    which are the spring's far end for the body's step at t_{n+1}; the hub equation
        r(s) = J s - Kp (omega_ref - omega_{n+1}) - Ki (phi_ref - theta_{n+1}) + t_s,{n+1}(s) = 0
    is solved by secant steps from the saved body state (r is affine in s but for the beam root's
    response: 2-3 body steps a step). So both models' discrete equations hold together at every
    t_{n+1} to the tolerance below: the monolithic discrete solution at step h, whose own error is
    measured by halving h (docs/stability.md).
    Why not the hub inertia as a point mass on the body and the drive as a load law: with the shaft
    the hub turns relative to the beam root (a degree of freedom of its own, the 8 rad/s shaft mode),
    which no load on the body's nodes can carry; a rigid shaft would be another system.

 split beam (`split_monolithic`): the one-body scene run standalone at the coupled system's step
    (the two halves have the one body's superelements, so the split system solves its equations).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from ...runtime.ports import PortValues, StepFailure
from ...runtime.rotation import expm
from .case import CosimRun, CosimSettings, hub_profile, tip_deflection
from .compliant_b5 import SHAFT_K, beam_overrides

#: |r| below this fraction of the hub's torque scale (J |s| + |tau_m| + |t_s| + 1 N m): the hub
#: equation's residual left by the secant iteration (the body's own Newton tolerance is ~1e-10 of
#: its loads, so a tighter one would chase round-off)
HUB_TOLERANCE = 1e-10
HUB_ITERATIONS = 12


def _profile(t: float, omega: float, T: float) -> tuple[float, float]:
    """Wu-Haug angle and rate (runtime/drives `haug_spinup`): phi_ref, omega_ref."""
    from ...runtime.drives import evaluate

    phi, dphi, _ = evaluate("haug_spinup", {"omega": omega, "T": T}, t)
    return phi, dphi


def b5_monolithic(model_path, settings: CosimSettings, h: float, duration: float | None = None,
                  backend: str = "native", k: float = SHAFT_K) -> CosimRun:
    """The B5 system (beam + shaft k + hub J + PI drive on the Wu-Haug profile settings.T, omega of
    the beam model's driven scene) as one run at step h (module doc). The CosimRun has the tip
    deflection against the beam root frame (eq. 92), the beam root's rate about Z and the shaft
    moment on the beam about Z, at every step; `sweeps` is the mean number of body steps a step."""
    from ...model import load_model
    from ...reduction import reduce_scene_body
    from ...simulate import build_system, whole_steps
    from ...simulate.partner import PartnerDof

    duration = settings.duration if duration is None else duration
    b = settings.beam
    ov = beam_overrides(settings, k=k)
    model = load_model(model_path, ov)
    scene = dataclasses.replace(model.scene(b.free_scene), step=h)
    body = reduce_scene_body(model.body, scene).data
    hub, tip = b.hub, b.tip
    if not any(p.name == hub and p.rotation == "compliant" for p in body.ports):
        raise ValueError(f"{model_path}: port {hub!r} of scene {b.free_scene!r} must have a compliant rotation")
    omega_f = hub_profile(model, b)["omega"]
    p = settings.drive
    J, Kp, Ki = float(p["drive.J"]), float(p["drive.Kp"]), float(p["drive.Ki"])
    n_steps, h = whole_steps(duration, h)
    dof = PartnerDof(scene.rho_inf, h)  # the hub's (theta, omega)
    r0 = np.asarray(body.node_positions[next(q.node for q in body.ports if q.name == hub)], float)
    far = {"theta": 0.0, "omega": 0.0}

    def inputs(t: float) -> dict[str, PortValues]:
        out = {}
        for q in body.ports:
            pv = PortValues()
            if q.name == hub:
                pv.r, pv.v, pv.a = r0.copy(), np.zeros(3), np.zeros(3)
                pv.R, pv.w, pv.dw = expm(np.array([0.0, 0.0, far["theta"]])), np.array([0.0, 0.0, far["omega"]]), np.zeros(3)
            else:
                if q.translation == "force":
                    pv.f = np.zeros(3)
                if q.rotation == "force":
                    pv.t = np.zeros(3)
            out[q.name] = pv
        return out

    t0 = time.perf_counter()
    system, _ = build_system(body, scene, model.body.origin, backend)
    e = np.asarray(model.body.direction, float)
    X_tip = model.body.length * e / np.linalg.norm(e)
    t_list, defl, speed, torque = [0.0], [0.0], [0.0], [0.0]
    stopped, body_steps = "", 0

    def record():
        out = system.outputs()
        R, r = out[hub].R, out[tip].r
        d = tip_deflection(R[None], out[hub].r[None], r[None], X_tip)[0]
        return float(d), float(out[hub].w[2]), float(out[hub].t[2])

    for n in range(n_steps):
        t1 = (n + 1) * h
        phi_ref, omega_ref = _profile(t1, omega_f, settings.T)
        dof.begin()
        snap = system.snapshot()

        def residual(s):
            nonlocal body_steps
            theta1, omega1 = dof.state(s)
            far["theta"], far["omega"] = theta1, omega1
            system.restore(snap)
            system.step(h, inputs)
            body_steps += 1
            ts = float(system.outputs()[hub].t[2])
            tau_m = Kp * (omega_ref - omega1) + Ki * (phi_ref - theta1)
            return J * s - tau_m + ts, J * abs(s) + abs(tau_m) + abs(ts) + 1.0

        try:
            s1 = dof.solve(residual, J, HUB_TOLERANCE, HUB_ITERATIONS, t1,
                           "hub equation not solved in {it} body steps (residual {residual:.3g} N m)")
        except StepFailure as exc:
            stopped = f"monolithic B5: {exc}"
            break
        dof.accept(s1)
        d, w, ts = record()
        t_list.append(t1)
        defl.append(d)
        speed.append(w)
        torque.append(ts)
    wall = time.perf_counter() - t0
    return CosimRun(np.array(t_list), np.array(defl), np.array(speed), np.array(torque), stopped, wall,
                    body_steps / max(len(t_list) - 1, 1))


def split_monolithic(model_path, settings: CosimSettings, h: float, duration: float | None = None,
                     backend: str = "native") -> CosimRun:
    """The split beam's monolithic reference: the one-body driven scene (the fast spin-up
    settings.split_T) run standalone at step h; tip deflection against the driven hub frame (no
    speed: the hub is driven; no interface moment: the cut is inside the one body)."""
    from ...simulate import run_scene

    duration = settings.split_duration if duration is None else duration
    b = settings.beam
    sc = b.driven_scene
    ov = [*settings.overrides, f"scenes.{sc}.drives.{b.hub}.rotation.angle.T={settings.split_T!r}",
          f"scenes.{sc}.duration={duration!r}", f"scenes.{sc}.step={h!r}"]
    t0 = time.perf_counter()
    res = run_scene(model_path, sc, ov, backend=backend)
    c = res.columns
    pick = lambda port, fld: np.stack([c[n] for n in _names(port, fld)], -1)  # noqa: E731
    R = pick(b.hub, "R").reshape(-1, 3, 3)
    from ...model import load_model

    mb = load_model(model_path, ov).body
    e = np.asarray(mb.direction, float)
    X_tip = mb.length * e / np.linalg.norm(e)
    d = tip_deflection(R, pick(b.hub, "r"), pick(b.tip, "r"), X_tip)
    # the split runs' interface moment is the cut's, which the one body has inside, not at a port: NaN
    # (cosim.compare then judges the deflection only)
    nan = np.full(len(res.t), np.nan)
    return CosimRun(res.t, d, nan, nan, res.summary["failure"] or "", time.perf_counter() - t0)


def _names(port: str, fld: str) -> list[str]:
    from ...fmu.variables import port_variables

    return port_variables(port, fld)
