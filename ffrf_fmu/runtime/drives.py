"""Scalar time functions s(t), s'(t), s''(t) for drives and loads (kinds listed in model.TimeFunction).

Runtime module: numpy only, no import from the rest of ffrf_fmu, so that it ships inside FMUs.
"""
from __future__ import annotations

import math

KINDS = {
    "constant": ("value",),
    "haug_spinup": ("omega", "T"),
    "ramp": ("rate", "t_start"),
    "window": ("value", "t_start", "t_end"),
    "sine": ("amplitude", "frequency_hz", "phase"),
    "bump": ("value", "t_start", "duration"),
}

CODES = {kind: i for i, kind in enumerate(KINDS)}  # the kind's number in the C twin (runtime/native/advance.c time_function)


def encode(kind: str, params: dict) -> tuple[int, list[float]]:
    """(code, parameters in KINDS order, padded to 3): a time function as the C runtime reads it."""
    if kind not in KINDS:
        raise ValueError(f"unknown time function kind {kind!r}; known: {sorted(KINDS)}")
    values = [float(params.get(k, 0.0)) for k in KINDS[kind]]
    return CODES[kind], values + [0.0] * (3 - len(values))


def evaluate(kind: str, params: dict, t: float) -> tuple[float, float, float]:
    """Return (s, ds/dt, d2s/dt2) at time t."""
    p = params
    if kind == "constant":
        return p["value"], 0.0, 0.0
    if kind == "haug_spinup":
        # docs/background.md B1, with the 1/(2 pi)^2 factor that geradin eq. (93) misprints
        w, T = p["omega"], p["T"]
        if t < T:
            tau = t / T
            two_pi = 2.0 * math.pi
            phi = w * T * (tau**2 / 2.0 + (math.cos(two_pi * tau) - 1.0) / two_pi**2)
            dphi = w * (tau - math.sin(two_pi * tau) / two_pi)
            ddphi = (w / T) * (1.0 - math.cos(two_pi * tau))
            return phi, dphi, ddphi
        return w * T * (t / T - 0.5), w, 0.0
    if kind == "ramp":
        dt = t - p["t_start"]
        return (p["rate"] * dt, p["rate"], 0.0) if dt > 0.0 else (0.0, 0.0, 0.0)
    if kind == "window":
        inside = p["t_start"] <= t < p["t_end"]
        return (p["value"] if inside else 0.0), 0.0, 0.0
    if kind == "sine":
        a, f, ph = p["amplitude"], p["frequency_hz"], p.get("phase", 0.0)
        w = 2.0 * math.pi * f
        return a * math.sin(w * t + ph), a * w * math.cos(w * t + ph), -a * w * w * math.sin(w * t + ph)
    if kind == "bump":  # value sin^4(pi tau), tau = (t - t_start) / duration in [0, 1): C2 at both ends
        v, d = p["value"], p["duration"]
        tau = (t - p["t_start"]) / d
        if not 0.0 <= tau < 1.0:
            return 0.0, 0.0, 0.0
        sn, cs, k = math.sin(math.pi * tau), math.cos(math.pi * tau), math.pi / d
        return v * sn**4, 4.0 * v * k * sn**3 * cs, 4.0 * v * k * k * (3.0 * sn * sn * cs * cs - sn**4)
    raise ValueError(f"unknown time function kind {kind!r}; known: {sorted(KINDS)}")


def window_share(t_start: float, t_end: float, t0: float, t1: float) -> float:
    """The share of the step (t0, t1] that the load window [t_start, t_end) covers: a piecewise-constant
    load applied at a step's end t1 (where the integrator enforces the equations) as its mean over the
    step, so that the impulse the body receives is the load times the window's length to round-off for
    any step, whether or not the steps land on the window's ends (docs/equations.md, "Loads between
    steps"). t1 == t0: whether t0 lies in the window. The C runtime's twin: advance.c."""
    h = t1 - t0
    if h <= 0.0:
        return 1.0 if t_start <= t0 < t_end else 0.0
    return max(0.0, min(t1, t_end) - max(t0, t_start)) / h
