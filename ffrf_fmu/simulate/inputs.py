"""A scene's drives and loads as port inputs: a function of time for the stepped run
(scene_inputs) and the same inputs as arrays for the native run (scene_schedule)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..model import Scene
from ..runtime import drives
from ..runtime.data import BodyData
from ..runtime.input_rule import port_codes
from ..runtime.ports import PortValues
from ..runtime.rotation import expm


def _tf(fn, t):
    return drives.evaluate(fn.kind, dict(fn.params), t)


def unbalance_force(ub, drive, t: float) -> np.ndarray:
    """The inertia force of a rotating unbalance on the body at t, world axes (model.Unbalance):
    f = m e (psi'^2 rho - psi'' tau), psi = phi(t) + phase of the drive's rotation."""
    phi, dphi, ddphi = _tf(drive.rotation.angle, t)
    a = np.asarray(drive.rotation.axis, float)
    e1 = np.asarray(ub.reference, float)
    e1 = e1 - (e1 @ a) * a
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    psi = phi + ub.phase
    rho = np.cos(psi) * e1 + np.sin(psi) * e2
    return ub.mass_eccentricity * (dphi**2 * rho - ddphi * np.cross(a, rho))


def scene_inputs(body: BodyData, scene: Scene, load_interval: tuple[float, float] | None = None
                 ) -> Callable[[float], dict[str, PortValues]]:
    """Port inputs of a scene as a function of time: drives on motion parts (their values at t), loads on
    force parts. load_interval None: each load window's value at t (on when t_start <= t < t_end); (a, b):
    each window's mean over (t + a, t + b] (runtime/drives.window_share). The standalone run steps with
    (-h, 0), the step that ends at t, where the integrator enforces the equations, so that a window's impulse
    is its load times its length to round-off whether or not the steps land on its ends (build_system;
    docs/equations.md, "Loads between steps"); an FMU's input table takes (0, H): the value set at a
    communication point t is held over the communication step (t, t + H] (fmu/run.py)."""
    drive_of = {d.port: d for d in scene.drives}
    loads = scene.loads
    a, b = (0.0, 0.0) if load_interval is None else load_interval

    def inputs(t: float) -> dict[str, PortValues]:
        out = {}
        for p in body.ports:
            pv = PortValues()
            d = drive_of.get(p.name)
            if p.translation in ("motion", "compliant"):  # compliant: the far end of the spring
                r0 = body.node_positions[p.node]
                if d is not None and d.translation is not None:
                    u, du, ddu = _tf(d.translation.displacement, t)
                    e = np.asarray(d.translation.direction, float)
                    pv.r, pv.v, pv.a = r0 + u * e, du * e, ddu * e
                else:
                    pv.r, pv.v, pv.a = r0.copy(), np.zeros(3), np.zeros(3)
            if p.rotation in ("motion", "compliant"):
                if d is not None and d.rotation is not None:
                    phi, dphi, ddphi = _tf(d.rotation.angle, t)
                    axis = np.asarray(d.rotation.axis, float)
                    pv.R, pv.w, pv.dw = expm(phi * axis), dphi * axis, ddphi * axis
                else:
                    pv.R, pv.w, pv.dw = np.eye(3), np.zeros(3), np.zeros(3)
            f, m = np.zeros(3), np.zeros(3)
            for ld in loads:
                share = drives.window_share(ld.t_start, ld.t_end, t + a, t + b) if ld.port == p.name else 0.0
                if share:
                    f += share * np.asarray(ld.force, float)
                    m += share * np.asarray(ld.moment, float)
            for ub in scene.unbalances:  # at t (the end of the step, where the equations are enforced)
                if ub.port == p.name:
                    f += unbalance_force(ub, drive_of[ub.drive], t)
            if p.translation == "force":
                pv.f = f
            if p.rotation == "force":
                pv.t = m
            out[p.name] = pv
        return out

    return inputs


def scene_schedule(body: BodyData, scene: Scene) -> tuple:
    """The inputs of `scene_inputs` as arrays, for the native run (runtime/native/advance.c `ffrf_body_advance`, which
    evaluates them at every step as scene_inputs does): per port its node, part causalities (0 force,
    1 motion, 2 compliant), spring index among the compliant ports (-1: none), reference position,
    drive time functions (code, parameters; -1: no drive) and direction / axis; per load its port,
    time window, force and moment."""
    drive_of = {d.port: d for d in scene.drives}
    P = len(body.ports)
    node, mode, spring = port_codes(body.ports)
    kind = np.full((P, 2), -1, dtype=np.int64)
    r0, prm, axis = np.zeros((P, 3)), np.zeros((P, 2, 3)), np.zeros((P, 2, 3))
    for j, p in enumerate(body.ports):
        r0[j] = body.node_positions[p.node]
        d = drive_of.get(p.name)
        for part, drive in ((0, d and d.translation), (1, d and d.rotation)):
            if drive:
                fn = drive.displacement if part == 0 else drive.angle
                kind[j, part], prm[j, part] = drives.encode(fn.kind, dict(fn.params))
                axis[j, part] = drive.direction if part == 0 else drive.axis
    port_index = {p.name: j for j, p in enumerate(body.ports)}
    loads = [ld for ld in scene.loads if ld.port in port_index]
    load_port = np.array([port_index[ld.port] for ld in loads], dtype=np.int64)
    load_window = np.array([[ld.t_start, ld.t_end] for ld in loads], dtype=float).reshape(-1, 2)
    load_fm = np.array([[ld.force, ld.moment] for ld in loads], dtype=float).reshape(-1, 2, 3)
    return node, mode, spring, r0, kind, prm, axis, load_port, load_window, load_fm


def rule_error(scene: Scene, H: float, ports: dict) -> dict:
    """Per driven part ("port.translation" / "port.rotation") what an FMU's input rule misses of the drive over a
    communication step H (runtime/input_rule.py). A drive u(t) sampled at t_c with (u, u', u'') and extrapolated
    to second order misses u''' s^3 / 6 in u and u''' s^2 / 2 in u' at s = t - t_c <= H, so with
    J = max |u'''|: rate error <= J H^2 / 2, displacement error <= J H^3 / 6; a compliant part's spring
    (stiffness k, damping c, the largest per axis) sees a force error <= (c H^2 / 2 + k H^3 / 6) J, second order
    in H while c J H^2 leads. J: the drive's acceleration differenced at min(H, step) / 8; `rate_error`: the
    rule's largest rate error at the internal step ends (what the body sees). ports: {name: (translation,
    rotation causality, coupling table)}."""
    from ..runtime.steps import communication_grid, whole_steps

    dt = min(H, scene.step) / 8
    fine = np.arange(0.0, scene.duration + 0.5 * dt, dt)
    grid = communication_grid(scene.duration, H)
    out = {}
    for d in scene.drives:
        for part, drive in (("translation", d.translation), ("rotation", d.rotation)):
            if drive is None:
                continue
            fn = drive.displacement if part == "translation" else drive.angle
            u = np.array([_tf(fn, t) for t in fine])
            J = float(np.max(np.abs(np.diff(u[:, 2])))) / dt
            worst = 0.0
            for t_c, t_end in zip(grid[:-1], grid[1:]):
                n, h = whole_steps(t_end - t_c, scene.step)
                _, v_c, a_c = _tf(fn, t_c)
                worst = max(worst, *(abs(_tf(fn, t_c + j * h)[1] - v_c - a_c * j * h) for j in range(1, n + 1)))
            row = {"jerk_max": J, "rate_error": worst, "rate_error_bound": 0.5 * J * H * H,
                   "displacement_error_bound": J * H**3 / 6, "rate_peak": float(np.max(np.abs(u[:, 1])))}
            translation, rotation, coupling = ports[d.port]
            rot = part == "rotation"
            if (rotation if rot else translation) == "compliant":
                k = float(np.max(coupling.get("rotational_stiffness" if rot else "stiffness", 0.0)))
                c = float(np.max(coupling.get("rotational_damping" if rot else "damping", 0.0)))
                row |= {"force_error_bound": (0.5 * c * H * H + k * H**3 / 6) * J, "group": f"{d.port}.{'t' if rot else 'f'}"}
            out[f"{d.port}.{part}"] = row
    return out
