"""Pick the cheapest adequate configuration (superelements, modes, term set, step) for a scene
and a tolerance on its primary metric, from indicators that need no reference run.

    ffrf-fmu advise MODEL --scene NAME --tolerance 1% [--fmu] [--check [--chart chart.csv]]

Every choice is printed with its reason and numbers; docs/accuracy.md (section 4) has the
derivations and their check against the B1 chart. The tolerance is shared as an error budget: the
chain may use CHAIN_SHARE of it, the step what the chain leaves up to RESERVE; the rest is kept for
what no rule estimates (modal truncation, interactions).

1. Stiffening and superelements, from the spin. A beam spun about its root has its first bending
   frequency omega^2 = omega_1^2 + K Omega^2 in the rotating frame (Southwell): K = S1 - 1 in the
   plane of rotation, S1 = 1.193 (`southwell_coefficient`). When sigma = (Omega_max/omega_1)^2
   reaches STIFFENING_SIGMA, stiffening is turned on: each superelement then carries its own
   centrifugal axial force (docs/equations.md), and what a chain of N still misses is predicted as
   STIFFENED_ERROR (Omega_max/omega_se)^2, omega_se the first free-free frequency of one of its
   superelements (Witteveen's in-superelement centrifugal indicator); N is the smallest count within
   CHAIN_SHARE x tolerance. (Before stiffening existed, this rule predicted the deficit of a chain of
   linear superelements with a constant calibrated on B1 and checked on B1: gone.)
2. Modes per superelement, from the excitation band (`excitation`): free-free modes above
   MODE_BAND x the highest excitation frequency respond quasi-statically and are dropped, but the
   first bending pair is always kept (static response to distributed inertial loads).
3. Term set: Witteveen's indicators (invariants.body_inertia_report) are computed and reported, and
   `linear` is chosen: measured on B1 and on the centrifugally soft coned_beam, the gyroscopic and
   full sets with one superelement are further from the full-order beam than linear
   (docs/inertia-terms.md), so no indicator threshold is known that would pick them with benefit.
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

from ..model import Body, Model, Port, effective_ports, load_model

# Error budget: the chain (geometric stiffening) may take CHAIN_SHARE of the tolerance; the step
# gets what the chain leaves up to RESERVE x tolerance (the rest is kept for the modal truncation
# and what the estimates miss).
CHAIN_SHARE = 0.85
RESERVE = 0.9
# Stiffened superelements (docs/equations.md, "Geometric stiffening"): each superelement carries its
# own centrifugal axial force, so a single one has the Southwell stiffening of the whole beam. What
# it still misses grows with the spin against its own first free-free frequency omega_se, which is
# Witteveen's in-superelement centrifugal indicator (Omega/omega_se)^2 (docs/inertia-terms.md): the
# predicted error of the peak deflection is STIFFENED_ERROR x (Omega_max/omega_se)^2.
# Calibration, on ONE point: B1, 1 SE, 2 modes, h = 10 ms, 4 rad/s, omega_se = 18.55 rad/s: +0.16 %
# measured for (4/18.55)^2 = 0.0465, i.e. 0.034; rounded up to 0.04. Checked on data not used here
# (tests/test_advise.py): B3 1 SE at 8, 12, 14 rad/s (measured 0.44 %, 0.78 %, 1.03 %; predicted
# 0.74 %, 1.67 %, 2.28 %: an upper bound, 1.7-2.2 x) and generated bodies (other length and stiffness).
STIFFENED_ERROR = 0.04
# Stiffening on when the spin's Southwell ratio (Omega/omega_1)^2 reaches 1 % (the stiffening
# changes the first frequency by more than ~0.5 %: NEGLIGIBLE of docs/inertia-terms.md).
STIFFENING_SIGMA = 0.01
# The stiffened law is checked up to Omega/omega_se = 0.75 (B3 at 14 rad/s, 1 SE).
SPIN_RATIO_CHECKED = 0.75
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
# Resolve the drive's time scale (a spin-up's T) with at least this many steps: on B1 (T = 15 s)
# Newton converges at h = 40 ms (T/375) with 2 and 4 superelements and fails at 50 ms (T/300) and
# above (measured; docs/accuracy.md). An empirical robustness limit of the nonlinear solver.
STEPS_PER_DRIVE_TIME = 400
MAX_SUPERELEMENTS = 32


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
    from ..runtime.drives import evaluate

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
    from ..reduction import build_body

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
    from ..linear import natural_frequencies

    f = natural_frequencies(_body_data(body)[0])
    return float(f[0]) if len(f) else math.nan


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
    stiffening: bool = False

    @property
    def overrides(self) -> list[str]:
        return [f"superelements={self.superelements}", f"modes={self.modes}", f"terms={self.terms}",
                f"step={self.step:g}", f"stiffening={'true' if self.stiffening else 'false'}"]

    @property
    def label(self) -> str:
        from .chart import label

        return label({"superelements": self.superelements, "modes": self.modes, "terms": self.terms,
                      "step": self.step}) + ("/stiff" if self.stiffening else "")

    def as_dict(self) -> dict:
        return {"configuration": {"superelements": self.superelements, "modes": self.modes, "terms": self.terms,
                                  "step": self.step, "stiffening": self.stiffening}, "label": self.label, "overrides": self.overrides,
                "tolerance": self.tolerance, "predicted": self.predicted, "indicators": self.indicators,
                "reasons": self.reasons, "warnings": self.warnings}


def spin_history(scene, n_max: int = 200_001):
    """(t, rate, acc, axis, source) of the scene's fastest rotation drive, or of its initial spin
    (constant rate, no acceleration); None when nothing spins."""
    from ..runtime.drives import evaluate

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
    from ..invariants import body_inertia_report

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

    # --- stiffening and superelements: the smallest chain whose stiffened superelements' predicted error
    # STIFFENED_ERROR (Omega/omega_se)^2 fits CHAIN_SHARE x tolerance (omega_se ~ N^2)
    stiff = spin > 0 and sigma >= STIFFENING_SIGMA
    n_se, e_n, tried = valid_count(body, 1), 0.0, {}
    if stiff:
        while True:
            w_se = 2 * math.pi * float(free_free_frequencies(body, n_se, 2)[0])
            e_n = STIFFENED_ERROR * (spin / w_se) ** 2
            tried[n_se] = (e_n, w_se)
            if e_n <= CHAIN_SHARE * tolerance or n_se >= MAX_SUPERELEMENTS:
                break
            n_se = valid_count(body, n_se + 1)
        w_se = tried[n_se][1]
        why["stiffening"] = (
            f"spin up to {spin:.3g} rad/s ({source}) against the first bending frequency {f1:.4g} Hz "
            f"({w1:.3g} rad/s): sigma = (Omega/omega_1)^2 = {sigma:.3g} >= {STIFFENING_SIGMA:g}: geometric stiffening "
            f"(Southwell, S1 = {S1:.4f}: omega^2 = omega_1^2 + {K:.3f} Omega^2 in the plane of rotation) matters; "
            "stiffened superelements carry their own centrifugal axial force (docs/equations.md) -> on")
        why["superelements"] = (
            f"stiffened superelements miss STIFFENED_ERROR x (Omega/omega_se)^2 = {STIFFENED_ERROR:g} x "
            f"({spin:.3g}/{w_se:.4g})^2 = {e_n:.2%} of the peak deflection for N = {n_se} (omega_se: first "
            "free-free frequency of one superelement, ~N^2; the constant from one B1 run, docs/accuracy.md)"
            + "".join(f"; {v[0]:.2%} for N = {k}" for k, v in tried.items() if k != n_se)
            + f"; within {CHAIN_SHARE:.0%} of the tolerance ({CHAIN_SHARE * tolerance:.2%})")
    elif spin > 0:
        why["stiffening"] = (f"spin {spin:.3g} rad/s: sigma = (Omega/omega_1)^2 = {sigma:.3g} < {STIFFENING_SIGMA:g}: "
                             "the stiffening changes the first frequency by < 0.5 % -> off")
        why["superelements"] = f"no stiffening at stake: {n_se} superelement(s)"
    else:
        why["stiffening"] = "no spin in the scene: nothing to stiffen -> off"
        why["superelements"] = f"no spin in the scene: no geometric stiffening to recover; {n_se} superelement(s)"
    ind["stiffening"] = stiff
    ind["chain_error_estimate"] = e_n
    ind["chain_error_by_n"] = {str(k): v[0] for k, v in tried.items()}
    if tried:
        ind["spin_over_superelement_frequency"] = spin / tried[n_se][1]

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
    need = max(cor_eff, soft) > tolerance
    terms = "linear"
    ind |= {"coriolis": cor, "coriolis_at_excitation": cor_eff, "softening": soft, "gyroscopic_needed": need}
    why["terms"] = (
        f"Witteveen indicators (worst superelement of {n_se}): Coriolis {cor:.2g} for modes at their own frequency, "
        f"{cor_eff:.2g} at the excitation band (x {f_exc:.3g} / {f_low:.3g} Hz: the modes respond quasi-statically), "
        f"centrifugal softening {soft:.2g}; tolerance {tolerance:.2g}: " + ("above" if need else "below") + ". "
        "linear: the CM frames of the two-field equations carry these effects; measured, the gyroscopic and full "
        "sets with one superelement are further from the full-order beam than linear (B1 +0.46 % against +0.16 %, "
        "coned_beam -2.4 % against -0.2 %; docs/inertia-terms.md), so the indicators alone do not justify them")

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
    if stiff and ind["spin_over_superelement_frequency"] > SPIN_RATIO_CHECKED:
        warn.append(f"Omega/omega_se = {ind['spin_over_superelement_frequency']:.3g} > {SPIN_RATIO_CHECKED:g}: beyond the "
                    "spin range the stiffened-superelement law was checked on: verify with --check")
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
    return Advice(n_se, modes, terms, h, tolerance, predicted, ind, why, warn, stiff)


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
              "step": f"{advice.step:g}", "stiffening": "true" if advice.stiffening else "false"}
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
             f"--set step={advice.step:g} --set stiffening={'true' if advice.stiffening else 'false'}"]
    for key in ("stiffening", "superelements", "modes", "terms", "step"):
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
