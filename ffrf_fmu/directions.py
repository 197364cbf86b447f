"""Directions relative to a spin: a beam along e spun about a bends in the plane of rotation (along
t = a x e, lead-lag, "in-plane") or out of it (along n = e x t, the part of a normal to the beam, flap,
"out-of-plane"). The centrifugal load stiffens the two differently (Southwell: omega^2 = omega_0^2 +
K Omega^2 out of the plane, omega_0^2 + (K - 1) Omega^2 in it; docs/accuracy.md), so the advisor, the
linearization (linear.mode_directions) and the metrics (simulate.metrics, kind tip_deflection) tell them
apart with the same two vectors."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class SpinPlane(NamedTuple):
    """Unit vectors of the plane of rotation: in_plane = a x e / |a x e|, out_of_plane = e x in_plane."""

    in_plane: np.ndarray
    out_of_plane: np.ndarray


def cross3(a, b) -> np.ndarray:
    """a x b of two 3-vectors, the products np.cross forms (the same bits), without its axis handling
    (about 20 us a call, three calls a run's metrics)."""
    a0, a1, a2 = (float(x) for x in a)
    b0, b1, b2 = (float(x) for x in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def spin_plane(axis, beam_direction) -> SpinPlane:
    """The in-plane and out-of-plane unit vectors of a beam along beam_direction spun about axis. A spin
    about the beam's own axis has no plane of rotation: any normal pair is returned then."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    e = np.asarray(beam_direction, dtype=float) / np.linalg.norm(beam_direction)
    t = cross3(a, e)
    if np.linalg.norm(t) < 1e-9:
        t = cross3(e, [1.0, 0.0, 0.0] if abs(e[0]) < 0.9 else [0.0, 1.0, 0.0])
    t = t / np.linalg.norm(t)
    return SpinPlane(t, cross3(e, t))


def scene_spin_axis(scene) -> np.ndarray | None:
    """The spin axis of a scene: its first rotation drive's axis, else its initial angular velocity's
    direction, else None."""
    for d in scene.drives:
        if d.rotation is not None:
            a = np.asarray(d.rotation.axis, dtype=float)
            return a / np.linalg.norm(a)
    w = np.asarray(scene.initial.angular_velocity, dtype=float)
    return w / np.linalg.norm(w) if np.any(w) else None


def excites(vector, plane: SpinPlane, moment: bool = False) -> set:
    """The bending directions a load (force, or moment with moment=True) acting along `vector` excites:
    a force along in_plane bends the beam in the plane, one along out_of_plane out of it; a moment about
    out_of_plane bends it in the plane, one about in_plane out of it."""
    v = np.asarray(vector, dtype=float)
    size = np.linalg.norm(v)
    if size == 0.0:
        return set()
    along = {"in-plane": abs(v @ plane.in_plane) > 1e-12 * size, "out-of-plane": abs(v @ plane.out_of_plane) > 1e-12 * size}
    if moment:
        along = {"in-plane": along["out-of-plane"], "out-of-plane": along["in-plane"]}
    return {k for k, on in along.items() if on}


def exciting_events(scene, plane: SpinPlane) -> dict:
    """The time after which each bending direction vibrates freely: the end of the last event that excites
    it (a rotation drive's spin-up T for the plane of rotation; the end of each finite load window by the
    directions its force and moment excite). Directions nothing excites are absent."""
    ends: dict = {}
    for d in scene.drives:
        if d.rotation is not None:
            T = dict(d.rotation.angle.params).get("T")
            if T is not None:
                ends["in-plane"] = max(ends.get("in-plane", 0.0), float(T))
    for ld in scene.loads:
        if np.isfinite(ld.t_end):
            for k in excites(ld.force, plane) | excites(ld.moment, plane, moment=True):
                ends[k] = max(ends.get(k, 0.0), float(ld.t_end))
    return ends


def directional_tip_metrics(t: np.ndarray, d: np.ndarray, scene, beam_axis, frequency) -> dict:
    """The elastic tip deflection d (n, 3; seen from the hub, eq. 92) split by direction relative to the
    scene's spin axis (scene_spin_axis): tip_in_plane_max_m, tip_out_of_plane_max_m (maxima of |d . in_plane|,
    |d . out_of_plane|), and, with the scene's band_hz, the frequency of each direction's free vibration
    after the last event that excites it (exciting_events) up to the next load's start, when that leaves
    min_window_s:
    in_plane_frequency_hz, out_of_plane_frequency_hz (`frequency(t, y, f_min, f_max)`, the least-squares
    sinusoid of simulate.dominant_frequency). Empty without a spin axis."""
    axis = scene_spin_axis(scene)
    if axis is None:
        return {}
    plane = spin_plane(axis, beam_axis)
    parts = {"in-plane": d @ plane.in_plane, "out-of-plane": d @ plane.out_of_plane}
    out = {"tip_in_plane_max_m": float(np.max(np.abs(parts["in-plane"]))),
           "tip_out_of_plane_max_m": float(np.max(np.abs(parts["out-of-plane"])))}
    m = scene.metrics
    if m.band_hz:
        starts = sorted(ld.t_start for ld in scene.loads)
        for direction, t_free in exciting_events(scene, plane).items():
            # free from its last exciting event to the next event of any kind (a later load moves the body
            # in this direction too, through the coupling of the two)
            t_next = next((ts for ts in starts if ts >= t_free), np.inf)
            after = (t > t_free) & (t <= t_next)
            if min(t[-1], t_next) >= t_free + m.min_window_s and np.count_nonzero(after) > 8:
                key = direction.replace("-", "_") + "_frequency_hz"
                out[key] = float(frequency(t[after], parts[direction][after], *m.band_hz))
    return out
