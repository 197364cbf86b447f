"""Pick the cheapest adequate configuration (superelements, modes, term set, step) for a scene
and a tolerance on its primary metric, from indicators that need no reference run.

    ffrf-fmu advise MODEL --scene NAME --tolerance 1% [--fmu] [--check [--chart chart.csv]]

Every choice is printed with its reason and numbers; docs/accuracy.md (section 4) has the
derivations and their check against the B1 chart. The tolerance is shared as an error budget: the
chain may use CHAIN_SHARE of it, the step what the chain leaves up to RESERVE; the rest is kept for
what no rule estimates (modal truncation, interactions).

1. Superelements, from the spin (geometric stiffening). A beam spun about its root has its first
   bending frequency omega^2 = omega_1^2 + K Omega^2 in the rotating frame (Southwell): K = S1 - 1
   in the plane of rotation, S1 = 1.193 (`southwell_coefficient`). A chain of N linear
   superelements carries centrifugal effects only on the polygon of its boundary nodes and misses
   D_N ~ 0.38/N^2 of it (`polygon_deficit`), scaled by CHAIN_CALIBRATION (B1). The first in-plane
   mode driven by the scene's spin-up, q'' + (omega_1^2 + (K - D_N) Omega(t)^2) q = -Omega'(t), gives
   the predicted error of the peak deflection (`chain_error`); N is the smallest count within
   CHAIN_SHARE x tolerance. sigma = (Omega_max/omega_1)^2 (omega_1 from linear.natural_frequencies)
   is reported as the measure of the stiffening at stake.
2. Modes per superelement, from the excitation band (`excitation`): free-free modes above
   MODE_BAND x the highest excitation frequency respond quasi-statically and are dropped, but the
   first bending pair is always kept (static response to distributed inertial loads).
3. Term set, from Witteveen's indicators (invariants.body_inertia_report): `gyroscopic` only if the
   Coriolis indicator (scaled to the excitation band: quasi-static modes move at f_exc, not at their
   own frequency) or the centrifugal-softening indicator exceeds the tolerance, AND the spin stays
   below the first bending frequency of the superelement at the driven port (GYRO_STABILITY):
   beyond it the terms bring softening that nothing balances (benchmark B3).
4. Step, from the highest relevant (kept and excited) frequency and the drive's time scale: the
   integrator's period error (`period_error`, from its amplification matrix) times
   STEP_ERROR_FACTOR (+ FMU_INPUT_FACTOR through the FMU) within the budget the chain leaves, and
   at least STEPS_PER_DRIVE_TIME steps per spin-up time (Newton robustness); rounded down to a
   value that divides the duration (`nice_step`). Kept modes above the excitation band need not be
   resolved: generalized-alpha is unconditionally stable and damps them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .model import Body, Model, Port, effective_ports, load_model

# Error budget: the chain (geometric stiffening) may take CHAIN_SHARE of the tolerance; the step
# gets what the chain leaves up to RESERVE x tolerance (the rest is kept for the modal truncation
# and what the estimates miss).
CHAIN_SHARE = 0.85
RESERVE = 0.9
# Stiffening deficit of a chain of N linear superelements: its rotating-frame first bending
# frequency is omega^2 = omega_1^2 + (K - D_N) Omega^2 (K = S1 - 1 in the plane of rotation).
# Physics: the chain carries centrifugal effects only on the polygon of its boundary nodes; the
# Rayleigh quotients of the first cantilever mode and of its N-chord interpolant give the deficit
# D_N = (S1 - S_N) - (1 - M_N) (`polygon_deficit`: 0.193, 0.090, 0.042, 0.024, 0.006 for N = 1, 2,
# 3, 4, 8; -> 0.38 / N^2). Calibration: the deficits that make the first-mode model reproduce B1's
# measured errors are 1.52 (N = 1), 1.25 (2), 1.30 (3), 1.35 (4) x the polygon's (docs/accuracy.md).
# We take 1.35 (N = 4, where the advice lives) and, for a single superelement, 1.52: it also softens
# (its rotating frequency after the spin-up, 0.425 Hz, is below the 0.464 Hz at rest). Check on
# independent data (the B3 spin map: T = 7.5 s, Omega = 2..6 rad/s, 2 and 4 SE): predicted errors
# within 10 % of the measured ones.
CHAIN_CALIBRATION = 1.35
SINGLE_CALIBRATION = 1.52
# Step: B1's measured step error of the maximum deflection is 2.1 x the integrator's relative
# period error at the spin rate, for 2 and 4 superelements alike (0.115 % at h = 20 ms, 0.46 % at
# 40 ms; h^2). A one-mode model integrated with the same scheme predicts 20 x less: the step error
# comes from the large-rotation kinematics of the frames, not from the modal dynamics. Calibrated.
STEP_ERROR_FACTOR = 2.1
# Through the FMU with communication step = internal step, the hub motion is extrapolated over each
# communication step from (R, w) at its start (docs/fmu.md): the angular acceleration is missed over
# the step. Measured on B1 (5 SE): +0.024 % (8 ms), +0.10 % (16 ms), +0.41 % (32 ms): h^2, 2.9 x
# the period error at the spin rate on top of the standalone step error (2 SE: +0.41 % at 32 ms too).
FMU_INPUT_FACTOR = 2.9
SOUTHWELL_FALLBACK = 1.1933  # S1 of the uniform cantilever (southwell_coefficient() recomputes it)
MODE_BAND = 3.0  # modes above MODE_BAND x the highest excitation frequency are dropped
MIN_MODES = 2  # the first bending pair
# Gyroscopic terms only while the spin stays below the first bending frequency of the superelement at
# the driven port (clamped there): beyond it they add softening that nothing balances. Measured: B1's
# single superelement with gyroscopic terms still completes at 4 rad/s = 1.37 x (13.97 % error, linear
# 13.07 %) and diverges at 8 rad/s = 2.7 x (B3 spin map): the threshold is conservative.
GYRO_STABILITY = 1.0
# Resolve the drive's time scale (a spin-up's T) with at least this many steps: on B1 (T = 15 s)
# Newton converges at h = 40 ms (T/375) with 2 and 4 superelements and fails at 50 ms (T/300) and
# above (measured; docs/accuracy.md). An empirical robustness limit of the nonlinear solver.
STEPS_PER_DRIVE_TIME = 400
MAX_SUPERELEMENTS = 32
SIGMA_CHECKED = 4.5  # the chain-error law matches measurements within 10 % up to sigma = 4.2 (B3 spin map)


# ------------------------------------------------------------------------------ physics helpers
_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # numpy 2 renamed trapz


def southwell_coefficient(n: int = 20001) -> float:
    """S1 = int_0^L (L^2 - x^2)/2 w'^2 dx / int_0^L w^2 dx for the first Euler-Bernoulli cantilever
    mode w (L = 1): omega^2 = omega_0^2 + S1 Omega^2 for a beam spun about its root, bending out of
    the plane of rotation (Southwell; 1.1933); in the plane of rotation the centrifugal load turns
    with the deflection and takes 1 off: S1 - 1 = 0.193."""
    x = np.linspace(0.0, 1.0, n)
    w, dw = _cantilever_mode(x)
    return float(_trapezoid((1.0 - x**2) / 2.0 * dw**2, x) / _trapezoid(w**2, x))


def _cantilever_mode(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    bl = 1.8751040687119611
    s = (math.cosh(bl) + math.cos(bl)) / (math.sinh(bl) + math.sin(bl))
    w = np.cosh(bl * x) - np.cos(bl * x) - s * (np.sinh(bl * x) - np.sin(bl * x))
    dw = bl * (np.sinh(bl * x) + np.sin(bl * x) - s * (np.cosh(bl * x) - np.cos(bl * x)))
    return w, dw


def polygon_deficit(n_se: int, n: int = 20001) -> float:
    """In-plane stiffening coefficient that a chain of n_se rigid chords misses (physics estimate):
    (S1 - S_N) - (1 - M_N), S_N = int T w_N'^2 / int w^2 and M_N = int w_N^2 / int w^2 for the
    piecewise-linear interpolant w_N of the first cantilever mode at the chain's nodes (L = 1,
    T = (1 - x^2)/2). Tends to 0.38 / n_se^2."""
    x = np.linspace(0.0, 1.0, n)
    w, dw = _cantilever_mode(x)
    xn = np.linspace(0.0, 1.0, n_se + 1)
    wn = np.interp(x, xn, np.interp(xn, x, w))
    dwn = np.gradient(wn, x)
    T = (1.0 - x**2) / 2.0
    den = _trapezoid(w**2, x)
    S1, SN = _trapezoid(T * dw**2, x) / den, _trapezoid(T * dwn**2, x) / den
    MN = _trapezoid(wn**2, x) / den
    return float((S1 - SN) - (1.0 - MN))


def modal_peak(w1: float, K: float, t: np.ndarray, rate: np.ndarray, acc: np.ndarray) -> float:
    """max |q| of the first in-plane bending mode of a beam on a driven hub, in the hub frame:
    q'' + (w1^2 + K rate(t)^2) q = -acc(t) (unit participation; rate and acc sampled on t,
    linearly interpolated). Fixed-step RK4 with at least 40 steps per period at the top frequency.
    Returns inf if the stiffness turns negative (the model diverges)."""
    k_min = w1**2 + min(0.0, K) * float(np.max(rate**2))
    if k_min <= 0.0:
        return math.inf
    w_top = math.sqrt(w1**2 + max(K, 0.0) * float(np.max(rate**2)))
    dt = min(2 * math.pi / w_top / 40.0, (t[-1] - t[0]) / 200.0)
    n = int(math.ceil((t[-1] - t[0]) / dt))
    dt = (t[-1] - t[0]) / n
    tt = t[0] + dt * np.arange(2 * n + 1) / 2.0  # half steps for RK4
    r2 = np.interp(tt, t, rate) ** 2
    a = np.interp(tt, t, acc)
    q, v, peak = 0.0, 0.0, 0.0
    for i in range(n):
        j = 2 * i

        def f(qq, vv, k):
            return vv, -(w1**2 + K * r2[k]) * qq - a[k]

        k1 = f(q, v, j)
        k2 = f(q + 0.5 * dt * k1[0], v + 0.5 * dt * k1[1], j + 1)
        k3 = f(q + 0.5 * dt * k2[0], v + 0.5 * dt * k2[1], j + 1)
        k4 = f(q + dt * k3[0], v + dt * k3[1], j + 2)
        q += dt / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v += dt / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        peak = max(peak, abs(q))
    return peak


def chain_deficit(n_se: int) -> float:
    """D_N: the part of the rotating beam's stiffening coefficient a chain of n_se linear
    superelements misses (calibrated polygon estimate; see CHAIN_CALIBRATION)."""
    return (SINGLE_CALIBRATION if n_se == 1 else CHAIN_CALIBRATION) * polygon_deficit(n_se)


def chain_error(n_se: int, w1: float, K: float, t, rate, acc) -> float:
    """Predicted relative error of the peak deflection of a chain of n_se linear superelements:
    the modal model with the chain's stiffening K - chain_deficit(n_se) against the exact K; for
    a constant spin (no angular acceleration) the quasi-static stiffness ratio at the top rate."""
    K_n = K - chain_deficit(n_se)
    if np.any(acc):
        exact = modal_peak(w1, K, t, rate, acc)
        return modal_peak(w1, K_n, t, rate, acc) / exact - 1.0 if exact > 0 else 0.0
    r2 = float(np.max(rate**2))
    stiff = w1**2 + K_n * r2
    return (w1**2 + K * r2) / stiff - 1.0 if stiff > 0 else math.inf


def amplification(wh: float, rho_inf: float) -> complex:
    """Principal root of the first-order generalized-alpha method (runtime/integrator.py) on
    y' = i omega y: per step, z ~ exp(i omega h)."""
    am = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf))
    af = 1.0 / (1.0 + rho_inf)
    g = 0.5 + am - af
    lam = 1j * wh
    # am a1 + (1 - am) a0 = af lam y1 + (1 - af) lam y0,  y1 = y0 + (1 - g) a0 + g a1   (h = 1)
    lhs = np.array([[1.0, -g], [-af * lam, am]])
    rhs = np.array([[1.0, 1.0 - g], [(1.0 - af) * lam, -(1.0 - am)]])
    z = np.linalg.eigvals(np.linalg.solve(lhs, rhs))
    return complex(z[np.argmin(np.abs(z - np.exp(lam)))])


def period_error(wh: float, rho_inf: float) -> float:
    """Relative period (frequency) error of the integrator at omega h (negative: too slow)."""
    return float(np.angle(amplification(wh, rho_inf)) / wh - 1.0)


def largest_step(omega: float, rho_inf: float, max_error: float) -> float:
    """Largest h with |period_error(omega h)| <= max_error (bisection on omega h in (0, 1.5])."""
    lo, hi = 1e-6, 1.5
    if abs(period_error(hi, rho_inf)) <= max_error:
        return hi / omega
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if abs(period_error(mid, rho_inf)) <= max_error else (lo, mid)
    return lo / omega


def _band(signal: np.ndarray, dt: float, energy_fraction: float) -> float:
    """Frequency above which the spectrum of `signal` holds at most energy_fraction of its energy."""
    x = np.asarray(signal, dtype=float)
    if not np.any(x):
        return 0.0
    x = x * np.hanning(len(x))  # no jump from the periodic extension of a signal that ends high
    X = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(len(x), dt)
    tail = np.cumsum(X[::-1])[::-1]  # energy at and above each frequency
    above = tail / tail[0]
    k = int(np.argmax(above <= energy_fraction)) if np.any(above <= energy_fraction) else len(f) - 1
    return float(f[max(k - 1, 0)])


def excitation(scene, tolerance: float) -> tuple[float, list[str]]:
    """(highest excitation frequency [Hz], the contributions as text)."""
    from .runtime.drives import evaluate

    n = min(200_001, int(round(scene.duration / scene.step)) + 1)
    t = np.linspace(0.0, scene.duration, n)
    dt = t[1] - t[0]
    parts: list[tuple[float, str]] = []
    for d in scene.drives:
        for kind, drive in (("rotation", d.rotation), ("translation", d.translation)):
            if drive is None:
                continue
            tf = drive.angle if kind == "rotation" else drive.displacement
            vals = np.array([evaluate(tf.kind, dict(tf.params), float(x)) for x in t])
            rate, acc = vals[:, 1], vals[:, 2]
            fb = _band(acc, dt, tolerance**2)
            parts.append((fb, f"band of {d.port}.{kind} acceleration {fb:.3g} Hz"))
            if kind == "rotation":
                fc = _band(rate**2, dt, tolerance**2)
                parts.append((fc, f"band of the squared {d.port} rate (centrifugal load) {fc:.3g} Hz"))
                spin = float(np.max(np.abs(rate)))
                parts.append((spin / (2 * math.pi), f"spin rate {spin:.3g} rad/s = {spin / (2 * math.pi):.3g} Hz "
                              "(Coriolis coupling, loads fixed in space seen from the body)"))
            if tf.kind == "sine":
                fs = dict(tf.params)["frequency_hz"]
                parts.append((fs, f"sine drive {fs:.3g} Hz"))
    for ld in scene.loads:
        if math.isfinite(ld.t_end):
            fw = 1.0 / (ld.t_end - ld.t_start)
            parts.append((fw, f"load window on {ld.port} of {ld.t_end - ld.t_start:g} s: {fw:.3g} Hz"))
    if any(scene.initial.angular_velocity):
        w = float(np.linalg.norm(scene.initial.angular_velocity))
        parts.append((w / (2 * math.pi), f"initial spin {w:.3g} rad/s"))
    if not parts:
        return 0.0, ["no drives or loads with a time scale: quasi-static"]
    parts.sort(key=lambda p: -p[0])
    return parts[0][0], [p[1] for p in parts]


def drive_time_scale(scene) -> float | None:
    """Shortest characteristic time of the drives: T of a spin-up, the period of a sine."""
    out = []
    for d in scene.drives:
        for drive in (d.rotation, d.translation):
            if drive is None:
                continue
            tf = drive.angle if d.rotation is drive else drive.displacement
            p = dict(tf.params)
            if tf.kind == "haug_spinup":
                out.append(p["T"])
            elif tf.kind == "sine" and p["frequency_hz"] > 0:
                out.append(1.0 / p["frequency_hz"])
    return min(out) if out else None


def _body_data(body: Body):
    from .reduction import build_body

    return build_body(body)


def rechain(body: Body, n_se: int, modes: int | None = None) -> Body:
    """The body as a chain of n_se superelements: ports keep their place along the beam (node k of
    n becomes node k n_se / n, which must be whole: see `valid_counts`)."""
    n0 = body.superelements
    ports = []
    for p in body.ports:
        k, r = divmod(p.node * n_se, n0)
        if r:
            raise ValueError(f"port {p.name!r} at node {p.node} of {n0} is not on a boundary node of {n_se} "
                             "superelements")
        ports.append(dataclasses.replace(p, node=k))
    return dataclasses.replace(body, superelements=n_se, ports=tuple(ports),
                               modes=body.modes if modes is None else modes)


def valid_count(body: Body, n_min: int) -> int:
    """Smallest chain length >= n_min that keeps every port on a boundary node."""
    n0 = body.superelements
    step = n0 // math.gcd(n0, math.gcd(*[p.node for p in body.ports], n0)) if body.ports else 1
    return max(step, step * math.ceil(n_min / step))


def first_frequency(body: Body) -> float:
    """First natural frequency [Hz] of the chain with the motion-driven port parts held."""
    from .linear import natural_frequencies

    f = natural_frequencies(_body_data(body)[0])
    return float(f[0]) if len(f) else math.nan


def attached_superelement_frequency(body: Body, n_se: int) -> tuple[float, str]:
    """First bending frequency [Hz] of one superelement of a chain of n_se, held as at the body's
    first motion-driven port (clamped where the port rotation is driven, pinned where only its
    translation is), or free-free when no port is motion-driven."""
    driven = [p for p in body.ports if "motion" in (p.translation, p.rotation)]
    length = body.length / n_se
    if driven:
        p0 = min(driven, key=lambda p: p.node)
        ports = (Port("root", 0, p0.translation, p0.rotation), Port("end", 1, "force", "force"))
        how = "clamped" if p0.rotation == "motion" else "pinned"
    else:
        ports = (Port("a", 0, "force", "force"), Port("b", 1, "force", "force"))
        how = "free-free"
    sub = dataclasses.replace(body, length=length, superelements=1, ports=ports, modes=max(body.modes, 2))
    from .linear import natural_frequencies

    f = natural_frequencies(_body_data(sub)[0])
    if how == "free-free":
        f = f[f > 1e-6]
    return float(f[0]), how


def free_free_frequencies(body: Body, n_se: int, n_modes: int) -> np.ndarray:
    """Free-free frequencies [Hz] of one superelement of a chain of n_se (its kept-mode candidates)."""
    sub = dataclasses.replace(body, superelements=n_se, modes=n_modes, ports=())
    data, _ = _body_data(sub)
    return np.asarray(data.superelements[0].frequencies_hz, dtype=float)


def nice_step(h_max: float, duration: float) -> float:
    """The largest of 1, 1.25, 1.6, 2, 2.5, 3.2, 4, 5, 6.4, 8 x 10^k not above h_max that divides the
    duration into whole steps."""
    e = math.floor(math.log10(h_max))
    mant = (1, 1.25, 1.6, 2, 2.5, 3.2, 4, 5, 6.4, 8)
    cands = sorted({float(f"{m * 10.0**k:.6g}") for k in range(e - 3, e + 1) for m in mant}, reverse=True)
    for h in cands:
        if h <= h_max * (1 + 1e-12) and abs(duration / h - round(duration / h)) < 1e-9 * duration / h:
            return float(f"{h:.6g}")
    return float(f"{h_max:.3g}")


# ------------------------------------------------------------------------------ the advice
@dataclass
class Advice:
    superelements: int
    modes: int
    terms: str
    step: float
    tolerance: float
    predicted: dict = field(default_factory=dict)  # error estimates by source
    indicators: dict = field(default_factory=dict)
    reasons: dict = field(default_factory=dict)  # choice -> text
    warnings: list = field(default_factory=list)  # where the advice leaves the range its rules were checked on

    @property
    def overrides(self) -> list[str]:
        return [f"superelements={self.superelements}", f"modes={self.modes}", f"terms={self.terms}",
                f"step={self.step:g}"]

    @property
    def label(self) -> str:
        from .chart import label

        return label({"superelements": self.superelements, "modes": self.modes, "terms": self.terms,
                      "step": self.step})

    def as_dict(self) -> dict:
        return {"configuration": {"superelements": self.superelements, "modes": self.modes, "terms": self.terms,
                                  "step": self.step}, "label": self.label, "overrides": self.overrides,
                "tolerance": self.tolerance, "predicted": self.predicted, "indicators": self.indicators,
                "reasons": self.reasons, "warnings": self.warnings}


def spin_history(scene, n_max: int = 200_001):
    """(t, rate, acc, axis, source) of the scene's fastest rotation drive, or of its initial spin
    (constant rate, no acceleration); None when nothing spins."""
    from .runtime.drives import evaluate

    t = np.linspace(0.0, scene.duration, min(n_max, int(round(scene.duration / scene.step)) + 1))
    best = None
    for d in scene.drives:
        if d.rotation is None:
            continue
        tf = d.rotation.angle
        vals = np.array([evaluate(tf.kind, dict(tf.params), float(x))[1:] for x in t])
        if best is None or np.max(np.abs(vals[:, 0])) > np.max(np.abs(best[1])):
            best = (t, vals[:, 0], vals[:, 1], np.asarray(d.rotation.axis, float), f"drive {d.port}.rotation ({tf.kind})")
    if best is None and any(scene.initial.angular_velocity):
        w = np.asarray(scene.initial.angular_velocity, dtype=float)
        best = (t, np.full_like(t, np.linalg.norm(w)), np.zeros_like(t), w, "initial angular velocity")
    if best is None or not np.any(best[1]):
        return None
    t, rate, acc, axis, src = best
    return t, rate, acc, axis / np.linalg.norm(axis), src


def advise(model: Model | str, scene_name: str | None = None, tolerance: float = 0.01,
           overrides: Sequence[str] = (), fmu: bool = False) -> Advice:
    """The configuration for `scene_name` at `tolerance` (relative error of the scene's primary
    metric); module doc for the rules. fmu: the body will run as an FMU with communication step =
    internal step, whose input extrapolation adds a step error (FMU_INPUT_FACTOR)."""
    from .invariants import body_inertia_report

    if not 0.0 < tolerance < 1.0:
        raise ValueError(f"tolerance must be in (0, 1), got {tolerance}")
    if not isinstance(model, Model):
        model = load_model(model, overrides)
    scene = model.scene(scene_name)
    body = dataclasses.replace(model.body, ports=effective_ports(model, scene))
    ind: dict[str, Any] = {}
    why: dict[str, str] = {}

    # --- spin against the first bending frequency
    f1 = first_frequency(body)
    w1 = 2 * math.pi * f1
    hist = spin_history(scene)
    S1 = southwell_coefficient()
    K = S1 - 1.0  # in the plane of rotation: the drive's angular acceleration loads the beam there
    if hist is not None:
        t, rate, acc, axis, source = hist
        e_beam = np.asarray(body.direction, dtype=float) / np.linalg.norm(body.direction)
        normal = float(np.linalg.norm(np.cross(axis, e_beam)))  # spin component normal to the beam
        rate, acc = rate * normal, acc * normal
        spin = float(np.max(np.abs(rate)))
    else:
        t = rate = acc = axis = None
        source, spin, normal = "none", 0.0, 0.0
    sigma = (spin / w1) ** 2 if w1 > 0 else 0.0
    ind |= {"first_frequency_hz": f1, "spin_rad_s": spin, "spin_source": source, "sigma": sigma,
            "southwell_S1": S1, "stiffening_K": K, "spin_axis": None if axis is None else [float(x) for x in axis]}

    # --- superelements: smallest chain whose predicted stiffening error fits CHAIN_SHARE x tolerance
    n_se, e_n, tried = valid_count(body, 1), 0.0, {}
    if spin > 0:
        while True:
            e_n = chain_error(n_se, w1, K, t, rate, acc)
            tried[n_se] = e_n
            if e_n <= CHAIN_SHARE * tolerance or n_se >= MAX_SUPERELEMENTS:
                break
            n_se = valid_count(body, n_se + 1)
        prev = max((n for n in tried if n < n_se), default=None)
        why["superelements"] = (
            f"spin up to {spin:.3g} rad/s ({source}) against the first bending frequency {f1:.4g} Hz "
            f"({w1:.3g} rad/s): sigma = (Omega/omega_1)^2 = {sigma:.3g}. Geometric stiffening (Southwell, "
            f"S1 = {S1:.4f}: omega^2 = omega_1^2 + {K:.3f} Omega^2 in the plane of rotation) is recovered by a chain "
            f"of N linear superelements only up to a deficit D_N Omega^2 (the chain's polygon misses "
            f"{polygon_deficit(n_se):.3g} for N = {n_se}, ~0.38/N^2; x {CHAIN_CALIBRATION} calibrated on B1); "
            f"the first-mode model q'' + (omega_1^2 + (K - D_N) Omega(t)^2) q = -Omega'(t) driven by the scene's "
            f"spin-up predicts a peak-deflection error of {e_n:.2%} for N = {n_se}"
            + (f" ({tried[prev]:.2%} for N = {prev})" if prev else "")
            + f", within {CHAIN_SHARE:.0%} of the tolerance ({CHAIN_SHARE * tolerance:.2%})")
    else:
        why["superelements"] = f"no spin in the scene: no geometric stiffening to recover; {n_se} superelement(s)"
    ind["chain_error_estimate"] = e_n
    ind["chain_error_by_n"] = {str(k): v for k, v in tried.items()}

    # --- modes
    f_exc, exc_parts = excitation(scene, tolerance)
    n_cand = min(12, 6 * (body.elements_per_superelement - 1))
    ff = free_free_frequencies(body, n_se, n_cand)
    keep = int(np.sum(ff <= MODE_BAND * f_exc))
    while 0 < keep < len(ff) and ff[keep] <= ff[keep - 1] * (1 + 1e-6):  # do not split a degenerate pair
        keep += 1
    modes = min(max(MIN_MODES, keep), n_cand)
    ind |= {"excitation_hz": f_exc, "excitation_parts": exc_parts,
            "free_free_hz": [float(x) for x in ff[: max(modes + 2, 4)]]}
    why["modes"] = (
        f"highest excitation frequency {f_exc:.3g} Hz ({exc_parts[0]}); free-free modes of one superelement "
        f"of {n_se}: {', '.join(f'{x:.3g}' for x in ff[:4])} Hz; {keep} below {MODE_BAND:g} x {f_exc:.3g} = "
        f"{MODE_BAND * f_exc:.3g} Hz" + (f"; kept {modes}: at least the first bending pair, which carries the static "
                                          "response to distributed inertial loads" if modes > keep else ""))

    # --- terms (Witteveen's indicators on the chosen chain)
    cand = rechain(body, n_se, modes)
    data, reds = _body_data(cand)
    rep = body_inertia_report(cand, spin or None, axis if spin else None, first_frequency_hz=f1, reductions=reds)
    worst = lambda k: max((s.get(k, 0.0) for s in rep["superelements"]), default=0.0)  # noqa: E731
    cor, soft = worst("coriolis"), worst("softening")
    # Witteveen's Coriolis indicator 2 Omega |G Omega^-1| takes each mode vibrating at its own
    # frequency (qdot = omega_j q). Modes above the excitation band respond quasi-statically, at the
    # excitation frequencies: qdot ~ omega_exc q, so the Coriolis force is smaller by f_exc / f_j.
    f_low = float(ff[0]) if len(ff) else math.inf
    cor_eff = cor * min(1.0, f_exc / f_low) if f_low > 0 else cor
    f_att, how = attached_superelement_frequency(body, n_se)
    stable = spin <= GYRO_STABILITY * 2 * math.pi * f_att
    need = max(cor_eff, soft) > tolerance
    terms = "gyroscopic" if need and stable else "linear"
    ind |= {"coriolis": cor, "coriolis_at_excitation": cor_eff, "softening": soft, "attached_superelement_hz": f_att,
            "attached_superelement": how, "gyroscopic_needed": need, "gyroscopic_stable": stable}
    why["terms"] = (
        f"Witteveen indicators (worst superelement of {n_se}): Coriolis {cor:.2g} for modes at their own frequency, "
        f"{cor_eff:.2g} at the excitation band (x {f_exc:.3g} / {f_low:.3g} Hz: the modes respond quasi-statically), "
        f"centrifugal softening {soft:.2g}; tolerance {tolerance:.2g}: " + ("above" if need else "below") + "; "
        f"first bending frequency of the {how} superelement {f_att:.3g} Hz ({2 * math.pi * f_att:.3g} rad/s): "
        + (f"spin {spin:.3g} rad/s {'<=' if stable else '>'} {GYRO_STABILITY} x that, gyroscopic terms "
           f"{'stay stable' if stable else 'would diverge (softening without stiffening)'}")
        + f" -> {terms}")

    # --- step: the budget the chain leaves, the relevant frequency, the drive's time scale
    w_rot = math.sqrt(w1**2 + K * spin**2)
    f_rel = max(f_exc, w_rot / (2 * math.pi))
    step_budget = max(RESERVE * tolerance - e_n, 0.05 * tolerance)
    factor = STEP_ERROR_FACTOR + (FMU_INPUT_FACTOR if fmu else 0.0)
    h_acc = largest_step(2 * math.pi * f_rel, scene.rho_inf, step_budget / factor)
    T_drive = drive_time_scale(scene)
    h_drive = T_drive / STEPS_PER_DRIVE_TIME if T_drive else math.inf
    h = nice_step(min(h_acc, h_drive, scene.duration / 10), scene.duration)
    e_h = factor * abs(period_error(2 * math.pi * f_rel * h, scene.rho_inf))
    ind |= {"relevant_frequency_hz": f_rel, "stiffened_first_frequency_hz": w_rot / (2 * math.pi),
            "step_budget": step_budget, "step_accuracy_s": h_acc,
            "step_drive_s": h_drive if math.isfinite(h_drive) else None,
            "highest_kept_free_free_hz": float(ff[modes - 1]) if len(ff) >= modes else None}
    limits = [f"error {factor:g} x the integrator's period error at {f_rel:.3g} Hz"
              + (" (standalone 2.1 + FMU input extrapolation 2.9)" if fmu else "") + " within the "
              f"{step_budget:.2%} left by the chain: h <= {h_acc:.3g} s"]
    if T_drive:
        limits.append(f"the drive's time scale {T_drive:g} s / {STEPS_PER_DRIVE_TIME}: h <= {h_drive:.3g} s")
    why["step"] = (
        f"highest relevant frequency {f_rel:.3g} Hz (excitation {f_exc:.3g} Hz; first bending stiffened at the "
        f"top spin {w_rot / (2 * math.pi):.3g} Hz); " + "; ".join(limits) + f" -> h = {h:g} s (predicted step "
        f"error {e_h:.2%}). The kept modes (up to {ind['highest_kept_free_free_hz']:.3g} Hz) lie above the "
        f"excitation band and respond quasi-statically; generalized-alpha (rho_inf = {scene.rho_inf:g}) is "
        "unconditionally stable" + (" and damps them" if scene.rho_inf < 1 else "") + ": they need not be resolved")
    predicted = {"chain": e_n, "step": e_h, "total_estimate": e_n + e_h}
    ind["runner"] = "fmu" if fmu else "standalone"
    warn = []
    if sigma > SIGMA_CHECKED:
        warn.append(f"sigma = {sigma:.3g} > {SIGMA_CHECKED:g}: beyond the spin range the chain-error law was checked on "
                    "(docs/accuracy.md 4.1; it under-predicts there): verify with --check")
    if spin > 0 and (axis is None or abs(float(np.dot(axis, np.asarray(body.direction) / np.linalg.norm(body.direction))))
                     > 1e-6):
        warn.append("spin axis not normal to the beam: the stiffening law was checked for a normal axis only")
    from .chart import PRIMARY_METRIC

    if scene.metrics not in PRIMARY_METRIC:
        warn.append("the scene has no primary metric (chart.PRIMARY_METRIC): the tolerance is read as one on the "
                    "elastic deflection, and --check reports the trajectory's RMS error")
    if n_se >= MAX_SUPERELEMENTS:
        warn.append(f"capped at {MAX_SUPERELEMENTS} superelements: the predicted chain error {e_n:.2%} may exceed the "
                    "tolerance")
    return Advice(n_se, modes, terms, h, tolerance, predicted, ind, why, warn)


def check(model_path, scene_name: str | None, advice: Advice, *, overrides: Sequence[str] = (),
          reference_elements: int | None = None, cache_dir=None, chart_csv=None) -> dict:
    """(advice.indicators["runner"] says whether it runs standalone or through its FMU.)"""
    """Run the advised configuration standalone and the reference; achieved errors and cost.
    With chart_csv, compare with the cheapest chart configuration that meets the tolerance."""
    from .chart import PRIMARY_METRIC, errors, read_csv, run_configuration, run_reference

    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    ref = run_reference(str(model_path), scene.name, list(overrides), reference_elements, None, cache_dir)
    values = {"superelements": str(advice.superelements), "modes": str(advice.modes), "terms": advice.terms,
              "step": f"{advice.step:g}"}
    runner = advice.indicators.get("runner", "standalone")
    run = run_configuration(str(model_path), scene.name, list(overrides), values, runner)
    metric = PRIMARY_METRIC.get(scene.metrics)
    err = errors(run, ref, metric)
    out = {"label": advice.label, "runner": runner, "completed": run["completed"], "failure": run["failure"],
           "wall_time_s": run.get("wall_time_s"), "cpu_time_s": run.get("cpu_time_s"), "metric_name": metric,
           **err, "metric_reference": ref["metrics"].get(metric) if metric else None,
           "reference": {k: ref[k] for k in ("n_elements", "step", "wall_time_s", "cached")}}
    key = "metric_error_rel" if metric else "rms_error_rel"
    out["within_tolerance"] = bool(run["completed"] and err[key] is not None and err[key] <= advice.tolerance)
    if chart_csv:
        rows = [r for r in read_csv(chart_csv) if r["runner"] == runner and r["completed"]
                and r[key] is not None and r[key] <= advice.tolerance]
        if rows:
            best = min(rows, key=lambda r: r["wall_time_s"])
            best_cpu = min(rows, key=lambda r: r["cpu_time_s"] or math.inf)
            out["chart_cheapest"] = {"label": best["label"], "wall_time_s": best["wall_time_s"], key: best[key]}
            out["wall_ratio_to_cheapest"] = out["wall_time_s"] / best["wall_time_s"] if out["wall_time_s"] else None
            if best_cpu.get("cpu_time_s") and out.get("cpu_time_s"):
                out["chart_cheapest_cpu"] = {"label": best_cpu["label"], "cpu_time_s": best_cpu["cpu_time_s"]}
                out["cpu_ratio_to_cheapest"] = out["cpu_time_s"] / best_cpu["cpu_time_s"]
            same = [r for r in read_csv(chart_csv) if r["runner"] == runner and r["label"] == advice.label]
            if same:
                out["chart_same_configuration"] = {"wall_time_s": same[0]["wall_time_s"], key: same[0][key]}
    return out


def format_advice(advice: Advice, model_name: str = "", scene_name: str = "") -> str:
    via = " through the FMU (communication step = step)" if advice.indicators.get("runner") == "fmu" else ""
    lines = [f"advice for {model_name}/{scene_name} at tolerance {advice.tolerance:.3g} "
             f"({advice.tolerance:.1%}){via}: {advice.label}",
             f"  --set superelements={advice.superelements} --set modes={advice.modes} --set terms={advice.terms} "
             f"--set step={advice.step:g}"]
    for key in ("superelements", "modes", "terms", "step"):
        lines.append(f"  {key} = {getattr(advice, key)}: {advice.reasons[key]}")
    p = advice.predicted
    lines.append(f"  predicted error: chain {p['chain']:.2%} + step {p['step']:.2%} = {p['total_estimate']:.2%} "
                 f"(modal truncation not estimated: {1 - RESERVE:.0%} of the tolerance is kept for it)")
    lines += [f"  warning: {w}" for w in advice.warnings]
    return "\n".join(lines)


def format_check(res: dict, tolerance: float) -> str:
    pct = lambda v: "-" if v is None else f"{v:.2%}"  # noqa: E731
    ref = res["reference"]
    ref_cost = "cached" if ref["cached"] else f"{ref['wall_time_s']:.1f} s wall"
    if res.get("wall_time_s") is None:
        return f"check: {res['label']} FAILED: {res['failure']}"
    status = "completed" if res["completed"] else "FAILED: " + str(res["failure"])
    within = "within" if res["within_tolerance"] else "NOT within"
    lines = [f"check: {res['label']} ({res['runner']}) {status}, wall {res['wall_time_s']:.2f} s, cpu {res['cpu_time_s']:.2f} s",
             f"  against the reference ({ref['n_elements']} elements, h = {ref['step']:g} s, {ref_cost}): "
             f"{res['metric_name']} {res['metric']:.6g} vs {res['metric_reference']:.6g}: error "
             f"{pct(res['metric_error_rel'])} ({within} {tolerance:.2%}); trajectory RMS error {pct(res['rms_error_rel'])}"]
    if "chart_cheapest" in res:
        c = res["chart_cheapest"]
        lines.append(f"  cheapest chart configuration within {tolerance:.2%}: {c['label']} ({c['wall_time_s']:.2f} s "
                     f"wall): this run costs {res['wall_ratio_to_cheapest']:.2f} x")
        if "cpu_ratio_to_cheapest" in res:
            lines.append(f"  by CPU time: cheapest {res['chart_cheapest_cpu']['label']} "
                         f"({res['chart_cheapest_cpu']['cpu_time_s']:.2f} s): {res['cpu_ratio_to_cheapest']:.2f} x")
        if "chart_same_configuration" in res:
            s = res["chart_same_configuration"]
            lines.append(f"  the same configuration in the chart: {s['wall_time_s']:.2f} s wall")
    return "\n".join(lines)
