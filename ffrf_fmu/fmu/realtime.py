"""The hard real-time cap of a body FMU's Newton iterations (`solver.max_newton_iterations`, a scene's
`max_newton_iterations`; docs/fmu.md, "Real-time datasheet"), checked on its scene when the FMU is built.

The cap bounds a step's Newton iterations, a retry's counted (runtime/native/step.c bounds its loops by it;
the numpy path fails a step that needed more, the same verdict): a step that would need more fails, and the
FMU's doStep returns Error naming the cap. An unconverged iterate is never accepted, so a cap either leaves
a run bit-identical (no step reached it) or stops it. `check_iteration_cap` runs the built FMU through its
scene at H = h (one internal step per doStep: the real-time case) with the cap and without it, and refuses
the cap when the capped run stops, or when a port output of it differs from the uncapped run's by more than
CAP_TOLERANCE of that output's peak.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .run import run_fmu
from .variables import parse_port_variable

# 10x the Newton tolerance (BodySystem.tol = 1e-9 on the scaled increments): a deviation below it is what
# Newton's own convergence leaves in a step. With no unconverged iterate ever accepted it is 0 unless the
# capped run stops; the comparison guards that the cap changes nothing else (a refresh rule that came to
# depend on the iterations left would show here).
CAP_TOLERANCE = 1e-8


class IterationCapRefused(ValueError):
    """The iteration cap changes the scene's result beyond CAP_TOLERANCE (the message names the cap, the
    scene and the measured deviation, or the step that needed more)."""


def check_iteration_cap(fmu_path, scene) -> dict:
    """Run the FMU through `scene` at H = h with its cap (scene.max_newton_iterations, > 0) and without:
    {"cap", "scene", "deviation" (max over port outputs of max |capped - uncapped| / max |uncapped|), "worst"
    (that output)}. IterationCapRefused when the capped run stops or the deviation exceeds CAP_TOLERANCE."""
    cap = scene.max_newton_iterations
    free = run_fmu(fmu_path, dataclasses.replace(scene, max_newton_iterations=0))
    if not free.reached:
        raise IterationCapRefused(f"scene {scene.name!r}: the run without the iteration cap stops at t = "
                                  f"{free.t[-1]:.6g} s ({free.log[-1:]}): there is no result to check the cap "
                                  f"max_newton_iterations = {cap} against")
    from fmpy.fmi1 import FMICallException

    iterations = free.columns["solver.newton_iterations"]
    try:
        capped = run_fmu(fmu_path, scene)
        stopped = not capped.reached
    except FMICallException:  # fmpy raises on the doStep's Error (the cap's, named in the FMU's log)
        stopped = True
    if stopped:
        over = np.flatnonzero(iterations > cap)
        where = (f"the step to t = {free.t[over[0]]:.6g} s takes {int(iterations[over[0]])} Newton iterations without "
                 f"the cap" if over.size else "no step of the run without the cap takes more")
        raise IterationCapRefused(
            f"max_newton_iterations = {cap} changes the result of scene {scene.name!r}: the run with the cap stops "
            f"where the run without it completes ({where}; up to {int(iterations.max())} per step, "
            f"{int(np.sum(iterations > cap))} steps over the cap): raise the cap to {int(iterations.max())}, or 0 for none")
    deviation, worst = 0.0, ""
    for name, ref in free.columns.items():
        try:
            parse_port_variable(name)
        except ValueError:  # not a port's output (energies, probes, the solver's)
            continue
        peak = float(np.max(np.abs(ref)))
        if peak > 0.0:
            d = float(np.max(np.abs(capped.columns[name] - ref))) / peak
            if d > deviation or not worst:
                deviation, worst = d, name
    if deviation > CAP_TOLERANCE:
        raise IterationCapRefused(f"max_newton_iterations = {cap} changes the result of scene {scene.name!r}: "
                                  f"{worst} differs from the run without the cap by {deviation:.3g} of its peak "
                                  f"(tolerance {CAP_TOLERANCE:g})")
    return {"cap": cap, "scene": scene.name, "deviation": deviation, "worst": worst,
            "max_iterations": int(iterations.max())}
