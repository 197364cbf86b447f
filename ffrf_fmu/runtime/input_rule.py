"""An FMU's input rule (fmu/variables.py INPUTS_BETWEEN_COMMUNICATION_POINTS): the inputs over a
communication step from its point values, the inputs as set at the communication point t_c; motions
extrapolated to second order in s = t - t_c, forces and moments held (kept constant over the step):

    r(t) = r_c + v_c s + a_c s^2/2,   v(t) = v_c + a_c s,
    R(t) = expm(skew(w_c s + dw_c s^2/2)) R_c,   w(t) = w_c + dw_c s,   f, t held,

the rotation exact for a fixed axis, otherwise missing (w x dw) s^3/12 (third order).

The point values are one row per port (`COLUMNS`), so that the C runtime evaluates the rule at every
internal step of the communication step in one call (runtime/native/advance.c `ffrf_extrapolated_inputs`,
in `ffrf_body_advance`); `extrapolate` here is its numpy twin and the oracle (tests/test_backends.py).
Runtime module: numpy only.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .ports import PortValues
from .rotation import expm

PART_CODES = {"force": 0, "motion": 1, "compliant": 2}  # a port part's causality as the C runtime reads it

# columns of a port's row of point values: position, velocity, acceleration, R (row-major), angular
# velocity, angular acceleration (world axes), force, moment
COLUMNS = {"r": slice(0, 3), "v": slice(3, 6), "a": slice(6, 9), "R": slice(9, 18), "w": slice(18, 21),
           "dw": slice(21, 24), "f": slice(24, 27), "t": slice(27, 30)}
WIDTH = 30


def port_codes(ports) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(node, mode, spring) per port in `ports` order: the boundary node, the causality codes of
    (translation, rotation) (PART_CODES), the index among the compliant ports (-1: not compliant;
    the order of BodySystem.compliant and of the C runtime's spring arrays)."""
    node = np.array([p.node for p in ports], dtype=np.int64)
    mode = np.array([[PART_CODES[p.translation], PART_CODES[p.rotation]] for p in ports], dtype=np.int64).reshape(-1, 2)
    spring, k = np.full(len(ports), -1, dtype=np.int64), 0
    for j, p in enumerate(ports):
        if "compliant" in (p.translation, p.rotation):
            spring[j], k = k, k + 1
    return node, mode, spring


def extrapolate(ports, values: np.ndarray, t_c: float) -> Callable[[float], dict[str, PortValues]]:
    """inputs(t) -> {port: PortValues} from the point `values` at t_c (one row per port, COLUMNS):
    motion and compliant parts give r, v (R, w), force parts f (t)."""
    c = COLUMNS
    parts = [(p.name, p.translation != "force", p.rotation != "force", row) for p, row in zip(ports, values)]

    def at(t: float) -> dict[str, PortValues]:
        dt = t - t_c
        out = {}
        for name, moves, turns, row in parts:
            q = PortValues()
            if moves:
                q.r = row[c["r"]] + row[c["v"]] * dt + (0.5 * dt * dt) * row[c["a"]]
                q.v = row[c["v"]] + dt * row[c["a"]]
            else:
                q.f = row[c["f"]]
            if turns:
                q.R = expm(row[c["w"]] * dt + (0.5 * dt * dt) * row[c["dw"]]) @ row[c["R"]].reshape(3, 3)
                q.w = row[c["w"]] + dt * row[c["dw"]]
            else:
                q.t = row[c["t"]]
            out[name] = q
        return out

    return at


def point_values(ports, values: dict[str, PortValues]) -> np.ndarray:
    """The point values (one row per port, COLUMNS) of the port inputs {port: PortValues} at t_c, as an FMU
    gathers them from its input variables; fields a port does not give stay 0."""
    out = np.zeros((len(ports), WIDTH))
    for j, p in enumerate(ports):
        for f, cols in COLUMNS.items():
            x = getattr(values[p.name], f)
            if x is not None:
                out[j, cols] = np.ravel(x)
    return out
