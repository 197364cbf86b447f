"""A body's start state made at build time: the static equilibrium or the steady spin of the scene an FMU
is built from (ffrf_fmu/initial_state.py settles the body; `capture` keeps its state), and the state an FMU
takes at its initialization (`mismatch`, `adopt`). The native FMU's twin is fmu/native/initialize.c
`fmu_start_body`, with the same checks and messages.

The start holds for the inputs and parameters it was made with: the motion-driven ports where the scene's
drives put them at t0 (their positions, rotations and rates are compared with the inputs an FMU is given,
to MOTION_TOL: a start elsewhere would put the body off its own ports) and the scene's gravity (checked by
the FMU). Load inputs are taken as they come: the port loads of the start are those acting at t0, and a load
other than the scene's starts a transient from the equilibrium, as it would in a standalone run.

Runtime module: numpy only (it ships inside the pythonfmu FMU).
"""
from __future__ import annotations

import numpy as np

# what a start state holds (BodySystem._STATE_FIELDS without the port loads, which are recomputed at t0)
START_FIELDS = ("xN", "RN", "x0", "R0", "eta", "v", "yd", "yd_prev", "yd_prev2", "a")
MOTION_TOL = 1e-9  # relative to max(1, |value|): the inputs at t0 against the start's motion-driven ports
# relative to max(1, |built gravity|): the gravity parameter against the one the start is the equilibrium of
# (a parameter set to the scene's value is that value to round-off); fmu/native/model.c start_state the same
GRAVITY_TOL = 1e-12


def capture(system) -> dict[str, np.ndarray]:
    """The start state of a settled BodySystem: copies of its START_FIELDS."""
    return {k: np.array(getattr(system, k), dtype=float) for k in START_FIELDS}


def mismatch(system, start: dict) -> str:
    """'' when the motion-driven ports of the initialized `system` (at the inputs of t0) are where `start` has
    them (positions, rotations, their rates), else the first difference named."""
    fields = {"translation": (("r", "xN", None), ("v", "yd", slice(0, 3))),
              "rotation": (("R", "RN", None), ("w", "yd", slice(3, 6)))}
    for p in system.data.ports:
        k = int(p.node)
        for part, checks in fields.items():
            if getattr(p, part) != "motion":
                continue
            for name, key, sl in checks:
                now = np.ravel(getattr(system, key)[k] if sl is None else getattr(system, key)[6 * k:6 * k + 6][sl])
                want = np.ravel(start[key][k] if sl is None else np.asarray(start[key])[6 * k:6 * k + 6][sl])
                if np.any(np.abs(now - want) > MOTION_TOL * np.maximum(1.0, np.abs(want))):
                    what = "rate" if name in ("v", "w") else "value"
                    return (f"the start state (made at build from the scene's initial state) has port {p.name}'s "
                            f"{part} {what} {np.round(want, 9).tolist()}, the inputs at t0 give "
                            f"{np.round(now, 9).tolist()}: set {p.name}'s inputs at t0 as the scene's drives give them, "
                            "or build the FMU from a scene that starts there")
    return ""


def parameter_mismatch(state: str, built_gravity, gravity, velocity, angular_velocity, displacements) -> str:
    """'' when the FMU's parameters are those the start state was made with: the scene's gravity (the
    equilibrium depends on it), no initial velocities or port displacements (the state sets them); else why
    not, naming the parameter."""
    if np.any(np.abs(np.asarray(gravity, float) - np.asarray(built_gravity, float)) > GRAVITY_TOL * max(1.0, float(np.abs(built_gravity).max()))):
        return (f"parameter gravity = {np.asarray(gravity, float).tolist()} is not the {np.asarray(built_gravity, float).tolist()} "
                f"the start state ({state}, made at build) is the equilibrium of: build the FMU for this gravity")
    for name, value in (("initial_velocity", velocity), ("initial_angular_velocity", angular_velocity),
                        *((f"initial.{k}.d", u) for k, u in displacements)):
        if np.any(np.asarray(value, float)):
            return f"parameter {name} is set, but the FMU starts in the start state ({state}), which sets the body's motion"
    return ""


def finish(system, f_in, t_in) -> None:
    """The port loads (inputs, reactions on motion-driven parts, springs) and the external power at the
    start, from the state as it is; no work done yet, no factorization kept."""
    n_node = 6 * system.layout.n_nodes
    system.fN, system.tN = np.array(f_in, dtype=float), np.array(t_in, dtype=float)
    F = system._local(system.xN, system.RN, system.x0, system.R0, system.eta, system.v, system.yd, False)
    F[:n_node] += system._loads(system.RN, f_in, t_in).ravel()
    system._update_port_loads(F, f_in, t_in)
    system.power = system._external_power()
    system.work = 0.0
    system._lu = None


def adopt(system, start: dict, f_in, t_in) -> None:
    """Put the initialized `system` (checked by `mismatch`) in the start state, port loads at t0 from the load
    inputs f_in, t_in (BodySystem._read_inputs)."""
    for k in START_FIELDS:
        setattr(system, k, np.array(start[k], dtype=float).reshape(np.shape(getattr(system, k))))
    finish(system, f_in, t_in)
