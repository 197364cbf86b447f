"""Port values exchanged with the environment (docs/fmu.md): all vectors in world axes, SI."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PortValues:
    """Values of one port. As input only the parts named by the causality are read:
    motion translation -> r, v; motion rotation -> R, w; force translation -> f; force rotation -> t.
    As output every field is filled (a, dw: the node's accelerations at the end of the step)."""

    r: np.ndarray | None = None  # (3,) position of the nodal frame origin [m]
    R: np.ndarray | None = None  # (3, 3) nodal axes in world axes
    v: np.ndarray | None = None  # (3,) velocity [m/s]
    w: np.ndarray | None = None  # (3,) angular velocity, world axes [rad/s]
    f: np.ndarray | None = None  # (3,) force ON the body [N]
    t: np.ndarray | None = None  # (3,) moment ON the body [N m]
    a: np.ndarray | None = None  # (3,) acceleration of the node [m/s^2] (input of a motion-driven translation)
    dw: np.ndarray | None = None  # (3,) angular acceleration, world axes [rad/s^2] (input of a motion-driven rotation)


class StepFailure(RuntimeError):
    """A time step that could not be completed: Newton did not converge, a NaN, a bad input."""

    def __init__(self, time: float, cause: str):
        super().__init__(f"step failed at t = {time:.6g} s: {cause}")
        self.time = time
        self.cause = cause


class NotConverged(StepFailure):
    """Newton ran out of iterations without converging (step.c FFRF_NOT_CONVERGED): the one failure that an
    iteration cap turns into IterationCapReached; a NaN or an unfactorable matrix stays what it is."""


class IterationCapReached(StepFailure):
    """A step that needs more Newton iterations than its cap (BodySystem.iteration_cap: a scene's
    max_newton_iterations, an FMU's solver.max_newton_iterations, the hard real-time bound of docs/fmu.md): it
    fails; an unconverged iterate is never accepted."""

    def __init__(self, time: float, cap: int):
        super().__init__(time, f"Newton did not converge within max_newton_iterations = {cap} iterations (the cap "
                               "of a step's iterations: a step that needs more fails)")
        self.cap = cap
