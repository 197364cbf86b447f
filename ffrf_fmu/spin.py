"""The spin of a scene: the rate history of its fastest rotation drive, or its initial angular velocity.
The one place `info` (invariants.scene_spin), the term-set rule (term_rule.steady_term_effects) and the
advisor (studies/indicators.spin_history) read it from.

The history is sampled on the scene's own step grid, at most SPIN_GRID_POINTS points: a drive's rate is
a smooth function of time (runtime/drives.py) whose peak the grid finds to (grid spacing)^2 relative
for a plateau and to its spacing times the slope for a monotonic ramp (haug_spinup reaches its plateau
at T, a grid point when T is a whole number of steps).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .runtime.drives import evaluate
from .runtime.steps import whole_steps

# 100,001 points: the 20 s scenes of the bundled models at their 1e-3 s step (20,001 points) are
# sampled at every step; the cost is one Python evaluation per point (about 0.1 s at the cap)
SPIN_GRID_POINTS = 100_001


@dataclass(frozen=True)
class SpinHistory:
    """Rate history of the spin about a fixed unit axis: rate [rad/s] and its time derivative [rad/s^2]
    at times t [s]; port: the driven port (None for an initial angular velocity); source: as text."""

    t: np.ndarray
    rate: np.ndarray
    acceleration: np.ndarray
    axis: np.ndarray
    port: str | None
    source: str

    @property
    def peak(self) -> float:
        """max |rate| over the scene."""
        return float(np.max(np.abs(self.rate)))


def spin_grid(scene) -> np.ndarray:
    """The times the spin is sampled at: the scene's (model.Scene) steps, at most SPIN_GRID_POINTS points.
    (No import of model.py: spin.py sits below it, and model's readers import this.)"""
    return np.linspace(0.0, scene.duration, min(SPIN_GRID_POINTS, whole_steps(scene.duration, scene.step).n + 1))


def scene_spin(scene) -> SpinHistory | None:
    """The scene's spin: its rotation drive with the highest peak rate (the first of equals), else its
    initial angular velocity (a constant rate), else None (nothing spins)."""
    t = spin_grid(scene)
    best = None
    for d in scene.drives:
        if d.rotation is None:
            continue
        tf = d.rotation.angle
        vals = np.array([evaluate(tf.kind, dict(tf.params), float(x))[1:] for x in t])
        axis = np.asarray(d.rotation.axis, dtype=float)
        history = SpinHistory(t, vals[:, 0], vals[:, 1], axis / np.linalg.norm(axis), d.port,
                              f"drive {d.port}.rotation ({tf.kind})")
        if history.peak > 0.0 and (best is None or history.peak > best.peak):
            best = history
    if best is None and any(scene.initial.angular_velocity):
        w = np.asarray(scene.initial.angular_velocity, dtype=float)
        best = SpinHistory(t, np.full_like(t, np.linalg.norm(w)), np.zeros_like(t), w / np.linalg.norm(w), None,
                           "initial angular_velocity")
    return best


def spin_drive_rotation(body, scene) -> tuple[SpinHistory, str] | None:
    """The scene's spin (scene_spin) and how `body` holds the rotation of the port that drives it ("motion",
    "compliant" for a drive spring, "force"), else None (nothing spins, or an initial angular velocity: no port)."""
    spin = scene_spin(scene)
    if spin is None or spin.port is None:
        return None
    return spin, body.port(spin.port).rotation
