"""The monolithic reference of the crank drive (ffrf_fmu/examples/crank_drive.py, models/conrod_crank.toml).

`monolithic`: the conrod's standalone system (the C runtime's BodySystem, the same
reduced body and small-eye spring), the crank pin's motion evaluated exactly at every step, and the
piston's equation m_p x'' = -f_y - F_gas(t) integrated together with the body by the body's
first-order generalized-alpha (simulate/partner.py; runtime/integrator.py: the same rho_inf, equations at t_{n+1}), as
studies/stability/monolithic.py does for B5's hub: per step the piston's acceleration s at t_{n+1}
fixes its position and velocity (affine in s), the far end of the spring for the body's step; the
piston equation r(s) = m_p s + f_y(s) + F_gas(t_{n+1}) = 0 is solved by secant steps from the saved
body state to 1e-10 of its force scale (at least m_p r omega^2 + F_max: the body's Newton leaves
~1e-10 of its loads). Same system: the same body, spring, piston mass and gas force;
only the coupling's sampling at H (the piston's held spring force, the body's extrapolated pin) is gone.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from .crank_drive import L_EYES, MODEL, CrankDrive, CrankRun, _laws, deformation

#: the piston equation's residual left by the secant iteration, relative to its force scale
PISTON_TOLERANCE = 1e-10
PISTON_ITERATIONS = 12


def monolithic(drive: CrankDrive, h: float, duration: float, model_path=MODEL, overrides=(),
               backend: str = "native", body=None) -> CrankRun:
    """The crank drive as one run at step h (module doc): the conrod, its small-eye spring and the
    piston integrated together, the crank pin's motion exact. body: the reduced BodyData of the model's
    scene when the caller has it (`reduced_body`), else reduced here."""
    from ..model import load_model
    from ..reduction import reduce_scene_body
    from ..runtime.ports import PortValues, StepFailure
    from ..simulate import build_system, whole_steps
    from ..simulate.partner import PartnerDof

    crank_law, piston_law = _laws()
    model = load_model(model_path, list(overrides))
    scene = dataclasses.replace(model.scene(), step=h, duration=duration)
    body = reduce_scene_body(model.body, scene).data if body is None else body
    node = {q.name: q.node for q in body.ports}
    n_steps, h = whole_steps(duration, h)
    dof = PartnerDof(scene.rho_inf, h)  # the piston's (x, v)
    y0 = L_EYES
    far = {"x": 0.0, "v": 0.0, "a": 0.0}
    I3, z3 = np.eye(3), np.zeros(3)

    def inputs(t: float) -> dict[str, PortValues]:
        r, v, a = (np.asarray(x) for x in crank_law.pin_motion(t, drive.r, drive.omega, drive.T))
        return {"big_eye": PortValues(r=r, v=v, a=a, t=z3.copy()),
                "small_eye": PortValues(r=np.array([0.0, y0 + far["x"], 0.0]), v=np.array([0.0, far["v"], 0.0]),
                                        a=np.array([0.0, far["a"], 0.0]), R=I3.copy(), w=z3.copy(), dw=z3.copy()),
                "mid_shank": PortValues(f=z3.copy(), t=z3.copy())}

    def gas(t):
        return piston_law.gas_force(t, drive.omega, drive.T, drive.F_max, drive.width)

    t0 = time.perf_counter()
    system, _ = build_system(body, scene, model.body.origin, backend)
    rows, stopped = [], ""
    load = drive.m_p * drive.r * drive.omega**2 + drive.F_max  # the piston's force scale [N]

    def record(t):
        xN = system.xN  # the port frames' origins (BodySystem.port_array's r)
        ax, be = deformation(xN[node["big_eye"]], xN[node["small_eye"]], xN[node["mid_shank"]])
        rows.append((t, crank_law.crank_motion(t, drive.omega, drive.T)[0], ax[0], be[0], dof.y[0],
                     float(system.fN[node["small_eye"], 1])))

    record(0.0)
    for n in range(n_steps):
        t1 = (n + 1) * h
        dof.begin()
        snap = system.snapshot()
        F = gas(t1)

        def residual(s):
            far["x"], far["v"] = dof.state(s)
            far["a"] = s
            system.restore(snap)
            system.step(h, inputs)
            fy = float(system.fN[node["small_eye"], 1])  # the spring's force on the conrod (port_array's f)
            return drive.m_p * s + fy + F, max(drive.m_p * abs(s) + abs(fy) + abs(F), load)

        try:
            s1 = dof.solve(residual, drive.m_p, PISTON_TOLERANCE, PISTON_ITERATIONS, t1,
                           "piston equation not solved in {it} body steps (residual {residual:.3g} N)")
        except StepFailure as exc:
            stopped = f"monolithic crank drive: {exc}"
            break
        dof.accept(s1)
        record(t1)
    cols = np.array(rows).T
    return CrankRun(*cols, stopped=stopped, wall=time.perf_counter() - t0)
