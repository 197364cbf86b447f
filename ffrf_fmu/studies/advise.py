"""Pick the cheapest adequate configuration (superelements, modes, term set, step) for a scene
and a tolerance on its primary metric, from indicators that need no reference run.

    ffrf-fmu advise MODEL --scene NAME --tolerance 1% [--fmu] [--check [--chart chart.csv]]

Every choice is printed with its reason and numbers; docs/accuracy.md (section 4) has the
derivations and their check against the B1 chart. The tolerance is shared as an error budget: the
chain may use CHAIN_SHARE of it, the step what the chain leaves up to RESERVE; the rest is kept for
what no rule estimates (modal truncation, interactions).

1. Stiffening and superelements, from the spin. A beam spun about its root stiffens (Southwell): its
   first bending frequency in the rotating frame is omega^2 = omega_1^2 + S1 Omega^2 out of the plane
   of rotation and omega_1^2 + (S1 - 1) Omega^2 in it (S1 = 1.193 for a cantilever,
   `southwell_coefficient`; 0.83 against 0.53 Hz on B1 at 4 rad/s). The advice takes both from the body
   itself (`stiffened_frequencies`: the reduced chain with stiffening linearized about the scene's steady
   spin, linear.directional_spin_modes, each mode with its direction), Southwell's law with each
   direction's coefficient only where the body has no steady spin to linearize about. When
   sigma = (Omega_max/omega_1)^2 reaches STIFFENING_SIGMA, stiffening is turned on: each superelement
   then carries its own centrifugal axial force (docs/equations.md), and what a chain of N still misses
   is predicted as STIFFENED_ERROR (Omega_max/omega_se)^2, omega_se the first free-free frequency of
   one of its superelements (Witteveen's in-superelement centrifugal indicator); N is the smallest
   count within CHAIN_SHARE x tolerance.
2. Modes per superelement, from the excitation band (`excitation`): free-free modes above
   MODE_BAND x the highest excitation frequency respond quasi-statically and are dropped, but the
   first bending pair is always kept (static response to distributed inertial loads).
3. The chain's linear range and the term set, from the steady spin of the reduced chain at the scene's
   top drive rate (term_rule.steady_term_effects; no reference, no time run). The deflection inside one
   superelement, theta = u_max / (N L), costs NONLINEAR_ERROR theta^2 (its elastic kinematics are
   linear): N grows until chain + this fit CHAIN_SHARE x tolerance. The term set is the rule shared with
   `info` (term_rule.choose_term_set): linear when `full` changes the steady displacements by at most
   TERM_SHARE x tolerance, else the cheapest set within that of `full`. The other fix of what one
   superelement misses is more linear superelements (their frames carry the terms between them): the
   smallest such chain within TERM_SHARE x tolerance of full is taken when its predicted cost per step
   (`step_cost`, measured per backend) is lower. Measured on disk_rotor, where the terms matter: on numpy
   3 linear superelements are cheaper than 1 with `full` (1.26 against 2.71), on the C runtime 1 with `full`
   is (1.03 against 1.28): the advice depends on the backend that runs the body (docs/inertia-terms.md).
4. Step, from the highest relevant (kept and excited) frequency and the drive's time scale (the first
   bending frequency at the top spin of each direction the scene excites, `excited_directions`: the
   drive in the plane of rotation, loads and gravity by their direction): the
   integrator's period error (`period_error`, from its amplification matrix) times
   STEP_ERROR_FACTOR (+ FMU_INPUT_FACTOR through the FMU) within the budget the chain leaves, and
   at least STEPS_PER_DRIVE_TIME steps per spin-up time (Newton robustness); rounded down to a
   value that divides the duration (`nice_step`). Kept modes above the excitation band need not be
   resolved: generalized-alpha is unconditionally stable and damps them.
"""

from __future__ import annotations


import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..model import Model, load_model, scene_body
from .calibration import (CHAIN_SHARE, FMU_INPUT_FACTOR, MAX_SUPERELEMENTS, MIN_MODES, MODE_BAND, NONLINEAR_ERROR, RESERVE,
                          SPIN_RATIO_CHECKED, STEP_ERROR_FACTOR, STEPS_PER_DRIVE_TIME, STIFFENED_ERROR,
                          STIFFENING_SIGMA)
from .chart import label, primary_metric
from .indicators import (excitation, drive_time_scale, first_frequency, free_free_frequencies, largest_step,
                         excited_directions, nice_step, period_error, rechain, southwell_coefficient,
                         spin_history, step_cost, stiffened_frequencies, valid_count)


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
    backend: str = "native"  # the backend the costs were priced on, and the one --check runs

    @property
    def overrides(self) -> list[str]:
        return [f"superelements={self.superelements}", f"modes={self.modes}", f"terms={self.terms}",
                f"step={self.step:g}", f"stiffening={'true' if self.stiffening else 'false'}"]

    @property
    def label(self) -> str:
        return label({"superelements": self.superelements, "modes": self.modes, "terms": self.terms,
                      "step": self.step}) + ("/stiff" if self.stiffening else "")

    def as_dict(self) -> dict:
        return {"configuration": {"superelements": self.superelements, "modes": self.modes, "terms": self.terms,
                                  "step": self.step, "stiffening": self.stiffening}, "label": self.label, "overrides": self.overrides,
                "tolerance": self.tolerance, "predicted": self.predicted, "indicators": self.indicators,
                "reasons": self.reasons, "warnings": self.warnings, "backend": self.backend}


def pricing_backend(backend: str) -> str:
    """The backend whose measured costs price a configuration (runtime/body.py check_backend refuses
    an unknown or retired one)."""
    from ..runtime.body import check_backend

    check_backend(backend)
    return backend


def advise(model: Model | str, scene_name: str | None = None, tolerance: float = 0.01,
           overrides: Sequence[str] = (), fmu: bool = False, backend: str = "native") -> Advice:
    """The configuration for `scene_name` at `tolerance` (relative error of the scene's primary
    metric); module doc for the rules. fmu: the body will run as an FMU with communication step =
    internal step, whose input extrapolation adds a step error (FMU_INPUT_FACTOR). backend: the one that
    will run the body; costs per step are priced on it."""
    from ..term_rule import TERM_SHARE, choose_term_set, steady_term_effects

    if not 0.0 < tolerance < 1.0:
        raise ValueError(f"tolerance must be in (0, 1), got {tolerance}")
    price_on = pricing_backend(backend)
    if not isinstance(model, Model):
        model = load_model(model, overrides)
    scene = model.scene(scene_name)
    body = scene_body(model.body, scene)
    if body.solid is not None:
        from ..checked_toml import ModelError

        raise ModelError(f"{model.path}: advise sizes chains of beam superelements; a solid is one superelement: "
                         "`ffrf-fmu info` prints its indicators and the term set the shared rule advises")
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
        rate = acc = axis = None
        source, spin, normal = "none", 0.0, 0.0
    sigma = (spin / w1) ** 2 if w1 > 0 else 0.0
    # the first bending frequency of each direction at the top spin, from the body linearized about it
    f_dir = stiffened_frequencies(body, scene, spin, axis)
    excited = sorted(d for d in excited_directions(scene, axis, body.direction) if d in ("in-plane", "out-of-plane"))
    ind |= {"stiffened_frequencies_hz": {d: f_dir[d] for d in ("in-plane", "out-of-plane")},
            "stiffened_frequencies_source": f_dir["source"], "excited_directions": excited}
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
            f"(at {spin:.3g} rad/s the first bending frequency is {f_dir['in-plane']:.4g} Hz in the plane of rotation and "
            f"{f_dir['out-of-plane']:.4g} Hz out of it: {f_dir['source']}) matters; "
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

    # --- the chain's linear range and the term set: ONE rule with `info` (term_rule.choose_term_set) on the
    # steady spin of the chosen chain; the deformation inside a superelement must stay in its linear range
    cand = rechain(body, n_se, modes)
    eff = steady_term_effects(cand, scene, stiffening=stiff)
    e_nl, grown = 0.0, {}
    while eff.get("status") == "ok":
        theta = eff["displacement_m"] / (n_se * body.length)  # deflection inside one superelement / its length
        e_nl = NONLINEAR_ERROR * theta**2
        grown[n_se] = e_nl
        if e_n + e_nl <= CHAIN_SHARE * tolerance or n_se >= MAX_SUPERELEMENTS:
            break
        n_se = valid_count(body, n_se + 1)
        cand = rechain(body, n_se, modes)
        eff = steady_term_effects(cand, scene, stiffening=stiff)
    if len(grown) > 1 or (grown and e_nl >= 0.1 * tolerance):  # said when it moved N or takes a share of the budget
        why["superelements"] += (
            f"; the steady deflection inside a superelement ({eff['displacement_m']:.3g} m over {n_se} of "
            f"{body.length / n_se:.3g} m) leaves the superelement's linear kinematics an error NONLINEAR_ERROR x "
            f"theta^2 = " + ", ".join(f"{v:.2%} (N = {k})" for k, v in grown.items())
            + f" (constant from coned_beam's steady spin, docs/inertia-terms.md) -> N = {n_se}")
    terms, why["terms"] = choose_term_set(eff, tolerance)
    alt = None
    if terms != "linear":  # the other fix: more linear superelements (their frames carry the terms between them)
        for n_alt in range(n_se + 1, MAX_SUPERELEMENTS + 1):
            n_alt = valid_count(body, n_alt)
            e_alt = steady_term_effects(rechain(body, n_alt, modes), scene, stiffening=stiff)
            if e_alt.get("status") == "ok" and e_alt["to_full"]["linear"] <= TERM_SHARE * tolerance:
                alt = (n_alt, e_alt["to_full"]["linear"])
                break
        if alt is not None:
            c_terms, c_alt = step_cost(n_se, terms, price_on), step_cost(alt[0], "linear", price_on)
            cheaper = c_alt <= c_terms
            why["terms"] += (
                f"; the other fix, linear with more superelements: N = {alt[0]} is within {alt[1]:.2%} of full; "
                f"cost per step against 1 SE linear on {price_on} (step_cost: LINEAR_COST_PER_SE, TERM_COST from benchmarks/term_cost.py) {c_alt:.2f} against {c_terms:.2f} for {terms} "
                f"with N = {n_se} -> " + (f"more superelements are cheaper: linear, N = {alt[0]}" if cheaper
                                           else f"{terms} is cheaper"))
            if cheaper:
                n_se, terms = alt[0], "linear"
                why["superelements"] += f"; raised to {n_se}: cheaper than a larger term set (see terms)"
    # what the chosen set lacks against full on the chosen chain (steady spin): part of the error estimate
    e_t = (alt[1] if alt is not None and n_se == alt[0] else eff["to_full"][terms]) if eff.get("status") == "ok" else 0.0
    ind |= {"term_effects": eff, "nonlinear_error_estimate": e_nl, "terms_alternative": alt, "terms_error_estimate": e_t}
    e_n = e_n + e_nl

    # --- step: the budget the chain leaves, the relevant frequency, the drive's time scale
    f_stiff = {d: f_dir[d] for d in excited if math.isfinite(f_dir[d])}
    top_dir = max(f_stiff, key=f_stiff.get) if f_stiff else "in-plane"
    w_rot = 2 * math.pi * f_stiff[top_dir] if f_stiff else math.sqrt(w1**2 + K * spin**2)
    f_rel = max(f_exc, w_rot / (2 * math.pi))
    # the body's own modes about the steady spin (directions excited) that lie in the excitation band
    # (MODE_BAND x f_exc: the band the kept modes come from) respond dynamically: the step resolves them too
    # (blade: a 0.3 s out-of-plane kick excites the second flap mode at 6.2 Hz; measured step error of its
    # peak 1.4 % at 8 ms sized on the window's 3.33 Hz, 0.46 % at 5 ms)
    in_band = [(f, d) for f, d in f_dir["modes"] if d in excited and math.isfinite(f) and f <= MODE_BAND * f_exc]
    f_mode, mode_dir = max(in_band) if in_band else (0.0, "")
    if f_mode > f_rel:
        f_rel = f_mode
    step_budget = max(RESERVE * tolerance - e_n - e_t, 0.05 * tolerance)
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
              + (f" (standalone {STEP_ERROR_FACTOR:g} + FMU input extrapolation {FMU_INPUT_FACTOR:g})" if fmu else "") + " within the "
              f"{step_budget:.2%} left by the chain and the terms: h <= {h_acc:.3g} s"]
    if T_drive:
        limits.append(f"the drive's time scale {T_drive:g} s / {STEPS_PER_DRIVE_TIME}: h <= {h_drive:.3g} s")
    why["step"] = (
        f"highest relevant frequency {f_rel:.3g} Hz (excitation {f_exc:.3g} Hz; first bending at the top spin "
        f"{w_rot / (2 * math.pi):.3g} Hz {top_dir}, the highest of the excited directions ({', '.join(excited)})"
        + (f"; the body's {mode_dir} mode at {f_mode:.3g} Hz about the steady spin lies in the excitation band "
           f"({MODE_BAND:g} x {f_exc:.3g} Hz)" if f_mode and f_mode >= f_rel else "") + "); " + "; ".join(limits) + f" -> h = {h:g} s (predicted step "
        f"error {e_h:.2%}). Kept modes above the excitation band (the highest kept: {ind['highest_kept_free_free_hz']:.3g} Hz) "
        f"respond quasi-statically; generalized-alpha (rho_inf = {scene.rho_inf:g}) is "
        "unconditionally stable" + (" and damps them" if scene.rho_inf < 1 else "") + ": they need not be resolved")
    predicted = {"chain": e_n, "terms": e_t, "step": e_h, "total_estimate": e_n + e_t + e_h}
    ind["runner"] = "fmu" if fmu else "standalone"
    warn = []
    if stiff and ind["spin_over_superelement_frequency"] > SPIN_RATIO_CHECKED:
        warn.append(f"Omega/omega_se = {ind['spin_over_superelement_frequency']:.3g} > {SPIN_RATIO_CHECKED:g}: beyond the "
                    "spin range the stiffened-superelement law was checked on: verify with --check")
    if spin > 0 and (axis is None or abs(float(np.dot(axis, np.asarray(body.direction) / np.linalg.norm(body.direction))))
                     > 1e-6):
        warn.append("spin axis not normal to the beam: the stiffening law was checked for a normal axis only")
    if primary_metric(scene) is None:
        warn.append("the scene has no primary metric ([scenes.NAME.metrics] primary): the tolerance is read as one on the "
                    "elastic deflection, and --check reports the trajectory's RMS error")
    if fmu and scene.metrics.kind == "momentum":
        warn.append("the free-body metrics (kind 'momentum') read the body's CM, inertia and momenta, which a standalone "
                    "run records and an FMU does not output: --check through the FMU cannot measure them; check standalone")
    if n_se >= MAX_SUPERELEMENTS:
        warn.append(f"capped at {MAX_SUPERELEMENTS} superelements: the predicted chain error {e_n:.2%} may exceed the "
                    "tolerance")
    return Advice(n_se, modes, terms, h, tolerance, predicted, ind, why, warn, stiff, price_on)


def format_advice(advice: Advice, model_name: str = "", scene_name: str = "") -> str:
    via = " through the FMU (communication step = step)" if advice.indicators.get("runner") == "fmu" else ""
    lines = [f"advice for {model_name}/{scene_name} at tolerance {advice.tolerance:.3g} "
             f"({advice.tolerance:.1%}){via}: {advice.label}",
             f"  --set superelements={advice.superelements} --set modes={advice.modes} --set terms={advice.terms} "
             f"--set step={advice.step:g} --set stiffening={'true' if advice.stiffening else 'false'}"]
    for key in ("stiffening", "superelements", "modes", "terms", "step"):
        lines.append(f"  {key} = {getattr(advice, key)}: {advice.reasons[key]}")
    p = advice.predicted
    lines.append(f"  predicted error: chain {p['chain']:.2%} + terms {p['terms']:.2%} + step {p['step']:.2%} = {p['total_estimate']:.2%} "
                 f"(modal truncation not estimated: {1 - RESERVE:.0%} of the tolerance is kept for it)")
    lines += [f"  warning: {w}" for w in advice.warnings]
    return "\n".join(lines)
