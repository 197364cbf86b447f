"""What is computed from a result: the tip seen from the hub (eq. 92), the tip seen from a free
body's CM frame, the dominant frequency of a series, the energy balance, and the scene's summary
metrics (metrics)."""
from __future__ import annotations

import numpy as np

from ..directions import cross3, directional_tip_metrics
from ..model import Scene
from ..runtime.data import BodyData
from ..runtime.outputs import tip_from_hub
from ..runtime.rotation import logm
from .frequency import dominant_frequency
from .results import SimulationResult, free_body_keys, free_body_series


def end_ports(body: BodyData) -> tuple[str, str]:
    """The ports at the first and the last boundary node (hub/root and tip of a beam)."""
    by_node = sorted(body.ports, key=lambda p: p.node)
    return by_node[0].name, by_node[-1].name


def elastic_tip(result: SimulationResult, hub: str, tip: str) -> np.ndarray:
    """Eq. (92): d = R_hub^T (x_tip - x_hub) - X_tip, X_tip the tip seen from the hub at rest."""
    body = result.body
    X = body.node_positions[body.port(tip).node] - body.node_positions[body.port(hub).node]
    return tip_from_hub(result.port(hub, "R"), result.port(hub, "r"), result.port(tip, "r"), X)


class _LastFrequency:
    """dominant_frequency that gives the last call's result again for the same series and band (the
    tip_deflection metrics ask twice for one series: the oscillation after the spin-up is the in-plane
    vibration of directional_tip_metrics when the plane's vector is the one used here, bit for bit)."""

    def __init__(self):
        self.last = None

    def __call__(self, t, y, f_min, f_max) -> float:
        if self.last is not None:
            (t0, y0, band), f = self.last
            if band == (f_min, f_max) and np.array_equal(t0, t) and np.array_equal(y0, y):
                return f
        f = dominant_frequency(t, y, f_min, f_max)
        self.last = (t, y, (f_min, f_max)), f
        return f


def energy_balance(columns: dict[str, np.ndarray]) -> float:
    """max |E(t) - E(0) - W_ext(t)| over the peak of E = rigid + elastic kinetic + strain energy."""
    if "energy.kinetic" in columns:  # the full-order reference has no rigid/elastic split
        total = columns["energy.kinetic"] + columns["energy.strain"]
    else:
        total = columns["energy.kinetic_rigid"] + columns["energy.kinetic_elastic"] + columns["energy.strain"]
    gap = total - total[0] - columns["energy.work_external"]
    peak = max(np.max(np.abs(total)), np.max(np.abs(columns["energy.work_external"])))
    return float(np.max(np.abs(gap)) / peak) if peak > 0 else 0.0


def tip_from_cm(result: SimulationResult) -> np.ndarray:
    """The elastic deflection of the tip (the port at the last boundary node) seen from the body's CM frame,
    (nt, 3) = (0, along e2, along e3): e1 the body's axis of least inertia about its CM (for a beam, the
    line that fits its mass best; turned towards the tip), e3 the part of the angular momentum direction
    n = h_cm(0)/|h_cm(0)| normal to e1, e2 = e3 x e1 (for a tumbling beam: e2 in the plane the axis sweeps,
    e3 out of it). The frame comes from the whole mass (CM and inertia), not from one section: the bending
    modes' slopes at an end, which the reduced body truncates, do not turn it. The axial part (stretch,
    the axial modes) is left out (0): it is not bending. Same definition for every model; each computes CM,
    inertia and momenta from its own mass (runtime: free_body_state; reference: mass_properties).

    A body that starts without angular momentum about its CM has no such roll: a ValueError says so
    (cm_frame_roll_undefined), rather than a frame fixed by an arbitrary world axis, whose deflections
    would depend on that choice and not on the body."""
    _, tip = end_ports(result.body)
    c, J, h = (free_body_series(result, k) for k in ("cm", "J_cm", "h_cm"))
    why = cm_frame_roll_undefined(J[0], h[0])
    if why:
        raise ValueError(f"tip_from_cm: {why}")
    _, vec = np.linalg.eigh(J)
    e1 = vec[:, :, 0]  # eigh sorts ascending: the axis of least inertia
    r = result.port(tip, "r") - c
    e1 = e1 * np.sign(np.einsum("ni,ni->n", e1, r))[:, None]
    n = h[0] / np.linalg.norm(h[0])
    e3 = n - (e1 @ n)[:, None] * e1
    e3 = e3 / np.linalg.norm(e3, axis=1)[:, None]
    e2 = np.cross(e3, e1)
    return np.column_stack([np.zeros(len(r)), np.einsum("ni,ni->n", r, e2), np.einsum("ni,ni->n", r, e3)])


# below this angular rate (|h_cm(0)| over the largest principal inertia, rad/s: one turn in 200 years) a
# body's start has no angular momentum: h_cm(0) is round-off and its direction noise
NO_SPIN_RAD_S = 1e-9


def cm_frame_roll_undefined(J0: np.ndarray, h0: np.ndarray) -> str:
    """Why tip_from_cm's frame has no roll at the start (inertia J0 and angular momentum h0 about the CM),
    or "" when it has one."""
    rate = float(np.linalg.norm(h0)) / max(float(np.linalg.eigvalsh(J0)[-1]), 1e-300)
    if rate > NO_SPIN_RAD_S:
        return ""
    return (f"the body starts with no angular momentum about its CM (|h_cm(0)| / J_max = {rate:.3g} rad/s <= "
            f"{NO_SPIN_RAD_S:g}): the roll of its CM frame (e3 along h_cm(0)) is undefined; give the scene an "
            "initial angular velocity, or use another metrics kind than momentum")


def tip_trajectory(result: SimulationResult, scene: Scene) -> np.ndarray:
    """The elastic tip trajectory a chart compares, (n, 3): for a free body (metrics kind 'momentum') the
    tip seen from the body's CM frame (tip_from_cm), else the tip seen from the hub section (eq. 92)
    between the body's end ports."""
    if scene.metrics.kind == "momentum":
        return tip_from_cm(result)
    hub, tip = end_ports(result.body)
    return elastic_tip(result, hub, tip)


def metrics(result: SimulationResult, scene: Scene) -> dict:
    """The scene's summary metrics, by its [scenes.NAME.metrics] table (model.Metrics; the windows
    and bands are the benchmark's, from the model file):

    - tip_deflection: the maximum transverse elastic tip deflection (eq. 92, end ports), the axial
      part and the time there; with band_hz, the tip's vibration frequency after the end of the
      rotation drive's spin-up (its T), when the run lasts min_window_s longer;
    - hub_rates: with coast_end_s, the mean Omega_z of the root from the end of its torque load to
      coast_end_s; when the run lasts min_window_s past the end of the tip load: the mean Omega_y
      after it and, with band_hz, the tip's vibration frequency; the root's final rotation vector;
    - momentum (a free body): drifts of the linear and angular momentum (about the CM) and of the total
      energy; the tip's deflection seen from the CM frame (tip_from_cm): its maximum, its RMS over the run
      and, with band_hz, its dominant frequency out of the plane the axis sweeps (e3), when the run lasts
      min_window_s.
    """
    t, m = result.t, scene.metrics
    if m.kind == "tip_deflection":
        hub, tip = end_ports(result.body)
        d = elastic_tip(result, hub, tip)
        axis = result.body.node_positions[-1] - result.body.node_positions[0]
        axis = axis / np.linalg.norm(axis)
        axial = d @ axis
        transverse = np.linalg.norm(d - axial[:, None] * axis, axis=1)
        i = int(np.argmax(transverse))
        out = {"tip_deflection_max_m": float(transverse[i]), "tip_axial_at_max_m": float(axial[i]), "t_at_max_s": float(t[i])}
        T_spin = next((dict(dr.rotation.angle.params).get("T") for dr in scene.drives if dr.rotation), None)
        frequency = _LastFrequency()
        if m.band_hz and T_spin is not None and t[-1] > T_spin + m.min_window_s:
            after = t > T_spin
            signed = d[after] @ cross3([0, 0, 1.0], axis) if abs(axis[2]) < 0.9 else d[after, 0]
            out["oscillation_frequency_hz"] = frequency(t[after], signed, *m.band_hz)
        out |= directional_tip_metrics(t, d, scene, axis, frequency)  # 3D: in and out of the plane of rotation
        return out
    if m.kind == "hub_rates":
        root, tip = end_ports(result.body)
        w = result.port(root, "w")
        out = {}
        t_torque_end = max((ld.t_end for ld in scene.loads if ld.port == root), default=None)
        if m.coast_end_s is not None and t_torque_end is not None and t[-1] >= m.coast_end_s > t_torque_end:
            coast = (t >= t_torque_end) & (t <= m.coast_end_s)
            out[f"omega_z_at_{m.coast_end_s:g}s"] = float(np.mean(w[coast, 2]))
        t_load_end = max((ld.t_end for ld in scene.loads if ld.port == tip), default=None)
        if t_load_end is not None and t[-1] > t_load_end + m.min_window_s:
            after = t >= t_load_end
            out["omega_y_mean_after_load"] = float(np.mean(w[after, 1]))
            if m.band_hz:
                d = elastic_tip(result, root, tip)
                out["tip_frequency_hz"] = dominant_frequency(t[after], d[after, 2], *m.band_hz)
        R_end = result.port(root, "R")[-1]
        out["hub_rotation_vector_end"] = [float(x) for x in logm(R_end)]
        out["t_end_s"] = float(t[-1])
        return out
    if m.kind == "momentum":
        if free_body_keys("p")[0] not in result.columns:  # an FMU's run: no free-body state recorded
            return {}
        p, h = free_body_series(result, "p"), free_body_series(result, "h_cm")
        out = {  # over the largest momentum of the run: the start's for a free body, > 0 for one started at rest
            "linear_momentum_drift_rel": _drift(p),
            "angular_momentum_drift_rel": _drift(h),
            "total_energy_drift_rel": energy_balance(result.columns),
        }
        why = cm_frame_roll_undefined(free_body_series(result, "J_cm")[0], h[0])
        if why:  # no CM frame to see the tip from: the tip metrics are left out, and the note says why
            out["tip_from_cm"] = f"not computed: {why}"
            return out
        d = tip_from_cm(result)
        transverse = np.linalg.norm(d, axis=1)
        out["tip_from_cm_max_m"] = float(np.max(transverse))
        out["tip_from_cm_rms_m"] = float(np.sqrt(np.mean(transverse**2)))
        if m.band_hz and t[-1] - t[0] >= m.min_window_s:
            out["tip_from_cm_frequency_hz"] = dominant_frequency(t, d[:, 2], *m.band_hz)
        return out
    return {}


def _drift(x: np.ndarray) -> float:
    """max_t |x(t) - x(0)| over max_t |x(t)| (0 for a momentum that is 0 throughout)."""
    size = float(np.max(np.linalg.norm(x, axis=1)))
    return float(np.max(np.linalg.norm(x - x[0], axis=1))) / size if size > 0 else 0.0
