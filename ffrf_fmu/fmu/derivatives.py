"""Directional derivatives of a body FMU, in their two meanings (fmu/variables.py DIRECTIONAL_DERIVATIVES;
fmu/native/model.h DERIV_FMI, DERIV_STEP): FMI's (fmi2GetDirectionalDerivative), the partial derivatives
of the outputs with respect to the inputs at the current communication point, zero since no output
depends directly on an input; and the derivatives of the last communication step (ffrf2GetStepDerivative,
not an FMI function): central differences of re-runs of that step.

The FMU's state machine (fmu/core.py `BodyCoSim`) records each successful doStep as a `LastStep` and
calls `directional_derivative` with itself; the re-runs take the step exactly as doStep does
(`BodySystem.run_extrapolated` with the point values checked by `BodyCoSim._point_values`), from the saved state at
t_c, and leave the FMU at the end of the step as it was. Imports: numpy, the standard library and the
runtime package (relative): the builder ships this module inside every FMU.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.ports import StepFailure

# steps of the central differences, per kind of input: round-off and truncation put the two kinds at
# opposite ends (B1-like beam, tests/test_fmu_derivatives.py):
# - loads (f, t): a reaction is the small difference of world-axes node forces (stiffness x positions),
#   ~1e-9 N of round-off, so a 0.014 N/N derivative to 1e-5 needs a large step; the response to loads
#   is nearly linear (steps 0.1 and 0.01 N agree to 1e-7). Step: 1e-2 max(1, largest |load|).
# - motions: a jump of the prescribed frame strains the stiff axial field at once (central differences
#   1.4e-4 off at 1e-3 m, so 1.4e-8 at 1e-5 m), and the external work, a sum of reaction x velocity
#   products, carries ~1e-5 relative round-off at 1e-6 m. Step: the largest displacement the
#   perturbation makes over the step, 1e-5 max(1, largest |r|) m or rad: r, R move the frame by their
#   change, v, w by H times it, a, dw by H^2/2 times it.
DERIVATIVE_STEPS = {"load": 1e-2, "motion": 1e-5}


@dataclass(frozen=True)
class LastStep:
    """What the directional derivatives of the last communication step need: its start, size and
    internal steps, the body state at t_c (BodySystem.snapshot, for `restore`) and every variable value
    as set for it."""

    t_c: float
    H: float
    n: int
    state: tuple
    values: np.ndarray


def directional_derivative(cosim, knowns, seeds, unknowns, step: bool = True) -> tuple[np.ndarray | None, str]:
    """step False: FMI's meaning, zeros once the references are checked (in step mode only). step True:
    derivative of the outputs `unknowns` of the FMU `cosim` (a BodyCoSim) at the end of its last
    doStep(t_c, H) with respect to the inputs `knowns` as set for that step, along `seeds`, the state at
    t_c fixed (variables.DIRECTIONAL_DERIVATIVES): (values, '') or (None, why not). Central differences of
    two runs of the step from the saved state at t_c per kind of input (DERIVATIVE_STEPS), the same step
    the FMU takes (the body's Newton with its iteration matrix, predictor and stopping rule): the
    derivative of what the FMU computes, which is what finite differences of its runs see. Then the FMU
    is back at the end of the step exactly as it was."""
    variables = cosim.variables
    n = len(variables)
    if cosim.mode != "step":  # as model.c model_directional_derivative
        return None, (f"{'step' if step else 'directional'} derivative in initialization mode: the partial derivatives "
                      "of the initial unknowns are not provided; in step mode it gives " +
                      ("the derivatives of the last communication step" if step else "FMI's partial derivatives at the "
                       "communication point (zero: no output depends directly on an input)"))
    knowns, unknowns = np.asarray(knowns, dtype=int).ravel(), np.asarray(unknowns, dtype=int).ravel()
    seeds = np.asarray(seeds, dtype=float).ravel()
    name = lambda vr: variables[vr].name if 0 <= vr < n else f"value reference {vr}"  # noqa: E731
    bad = [name(vr) for vr in knowns if not (0 <= vr < n and cosim.causality[vr] == "input")]
    if bad:
        return None, (f"directional derivative: {', '.join(bad[:6])} not input(s): the derivatives are those "
                      "of outputs with respect to inputs")
    bad = [name(vr) for vr in unknowns if not (0 <= vr < n and cosim._is_output[vr] and not cosim.is_integer[vr])]
    if bad:
        return None, f"directional derivative: {', '.join(bad[:6])} not Real output(s)"
    if not np.isfinite(seeds).all():
        return None, "directional derivative: the seed vector is not finite"
    if not step:  # every output is a value at the end of the last step: no direct feedthrough
        return np.zeros(unknowns.size), ""
    rec, system = cosim.last_step, cosim.system
    if rec is None or system is None:
        return None, ("step derivative: no communication step to differentiate (they are the "
                      "derivatives of the last successful doStep; none since initialization, a failed doStep "
                      "or fmi2SetFMUstate)")
    if not seeds.any():
        return np.zeros(unknowns.size), ""
    field = [variables[vr].field for vr in knowns]
    is_load = np.array([f in ("f", "t") for f in field])
    H = rec.H  # displacement over the step per unit change (DERIVATIVE_STEPS)
    weight = np.array([{"v": H, "w": H, "a": 0.5 * H * H, "dw": 0.5 * H * H}.get(f, 1.0) for f in field])
    end = system.get_state()
    total = np.zeros(unknowns.size)
    try:
        with cosim.one_blas_thread():
            for kind, part in (("load", is_load), ("motion", ~is_load)):
                s = np.where(part, seeds, 0.0)
                if not s.any():
                    continue  # the derivative is linear in the seeds: each kind with its own step
                size = max(1.0, float(np.max(np.abs(rec.values[knowns[part]] * weight[part]))))
                eps = DERIVATIVE_STEPS[kind] * size / float(np.max(np.abs(s * weight)))
                sides = []
                for step in (eps, -eps):
                    values = rec.values.copy()
                    np.add.at(values, knowns, step * s)
                    point, msg = cosim._point_values(rec.t_c, values, strict=False)
                    if msg:
                        return None, f"directional derivative: {msg}"
                    system.restore(rec.state)
                    system.run_extrapolated(rec.H / rec.n, rec.n, rec.t_c, point, cosim._row)  # as doStep steps
                    dst, out = cosim._output_values(0, cosim._row)
                    full = np.zeros(n)
                    full[dst] = out
                    sides.append(full[unknowns])
                total += (sides[0] - sides[1]) / (2.0 * eps)
    except StepFailure as e:
        return None, (f"directional derivative of the step from t = {rec.t_c:.6g} s failed at t = {e.time:.6g} s: "
                      f"{e.cause}")
    finally:
        system.set_state(end)
    return total, ""
