"""`advise --system crank`: term set, modes and step for the conrod in the crank drive (models/conrod_crank.toml,
ffrf_fmu/examples/crank_drive.py), and with --check their check against the drive's converged monolithic
reference (examples/crank_monolithic.py). The scene of the model file is the conrod with its ports open to its
partners (nothing in it moves the body); what moves it is the drive's kinematics (CrankDrive: crank speed
omega, radius r, piston mass m_p, gas force F_max over `width` of crank angle), and the rules of
modal_advice.py are applied to them:

- modes: every free-free mode below MODE_BAND x the highest excitation frequency, at least MIN_MODES. The
  excitation: the crank's second harmonic 2 omega / 2 pi (the slider-crank's inertia force m_p r omega^2
  (cos theta + (r / L) cos 2 theta)), and the gas pulse F_max sin^4(pi theta / width) of duration
  width / omega, whose highest harmonic is 2 omega / width (sin^4 x = 3/8 - cos 2x / 2 + cos 4x / 8): the
  larger (here the pulse, 9549 Hz);
- step: STEP_ERROR_FACTOR x the integrator's period error at the larger of that frequency and the first
  kept mode within RESERVE x tolerance, rounded to divide the duration (indicators.nice_step);
- term set: term_rule's criterion (the cheapest of TERM_SETS_BY_COST within TERM_SHARE x tolerance of
  `full`; then of `full`'s switches those whose removal alone moves the response by more than
  TERM_SHARE x tolerance / 4, choose_full_terms), measured on the drive itself: the monolithic run at the
  advised modes and twice the advised step (the terms' effect is a difference at equal discretization)
  per term set and per switch left out, the response being the mid-shank axial and bending deformation
  (crank_drive.deviation: max difference over the peak). The steady spin the rule measures for a
  model's scene does not exist here: the rod swings at up to omega r / L while its big eye accelerates at
  omega^2 r.

Check (`check_crank`): the reference is the monolithic run with all of full's terms over mode cutoffs
(ascending) at the advised step until a cutoff moves the response by < CONVERGED_SHARE x tolerance, then
that cutoff at the step halved until a halving moves it by less (at most MAX_HALVINGS); the advised
configuration against it, axial and bending each within the tolerance.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..examples import crank_drive as cd
from ..examples.crank_monolithic import monolithic
from ..runtime.steps import divides
from ..runtime.terms import FULL_TERMS
from ..term_rule import SWITCH_ALONE, TERM_SETS_BY_COST, TERM_SHARE, choose_full_terms
from .calibration import MIN_MODES, MODE_BAND, RESERVE, STEP_ERROR_FACTOR
from .indicators import nice_step
from .modal_advice import (CONVERGED_SHARE, VERDICT, ModalAdvice, converge, dump_json, exit_code, modes_and_step,
                           reference_cutoffs, switch_suffix)

DURATION = 7.5e-3  # s: the drive's run-up (one revolution in 2.5 ms) and four revolutions at speed, four firings


@dataclass
class CrankRunMetric:
    """One monolithic run: its configuration, the run (crank_drive.CrankRun) and its wall time."""

    modes: int
    terms: str
    full_terms: tuple
    step: float
    run: cd.CrankRun = field(repr=False)
    wall: float

    @property
    def label(self) -> str:
        return f"{self.modes}m/{self.terms}{switch_suffix(self.terms, self.full_terms)}/{self.step * 1e6:g}us"


class Runs:
    """Monolithic runs of the drive, the reduced bodies kept per mode count (a solid is reduced afresh each
    time it is loaded: ~9 s for the conrod's tet10 mesh)."""

    def __init__(self, drive: cd.CrankDrive, duration: float, model_path=cd.MODEL, overrides=()):
        self.drive, self.duration, self.model_path, self.overrides = drive, duration, model_path, list(overrides)
        self.bodies: dict = {}

    def frequencies(self, modes: int) -> np.ndarray:
        return np.asarray(self.body(modes).superelements[0].frequencies_hz)

    def body(self, modes: int):
        if modes not in self.bodies:
            self.bodies[modes] = cd.reduced_body(self.model_path, [*self.overrides, f"body.modes={modes}"])
        return self.bodies[modes]

    def run(self, modes: int, terms: str, full_terms, step: float) -> CrankRunMetric:
        o = [*self.overrides, f"body.modes={modes}", f'scenes.crank.terms="{terms}"',
             f"scenes.crank.full_terms={json.dumps(list(full_terms))}"]
        body = self.body(modes)
        t0 = time.perf_counter()
        r = monolithic(self.drive, step, self.duration, self.model_path, o, body=body)
        if r.stopped:
            raise RuntimeError(f"the monolithic crank drive at {modes} modes, {terms}, h = {step:g} s stopped: {r.stopped}")
        return CrankRunMetric(modes, terms, tuple(full_terms), step, r, time.perf_counter() - t0)


def moved(a: CrankRunMetric, b: CrankRunMetric) -> float:
    """The larger of the axial and bending difference of run a from run b, over b's peaks."""
    d = cd.deviation(a.run, b.run)
    return max(d.axial, d.bending)


def excitation(drive: cd.CrankDrive) -> tuple[float, str]:
    """The drive's highest excitation frequency [Hz] and what it is (module doc)."""
    f2 = 2 * drive.omega / (2 * math.pi)
    f_gas = 2 * drive.omega / drive.width  # 2 / (width / omega) [Hz]: the pulse's highest harmonic
    if f_gas >= f2:
        return f_gas, (f"the gas pulse sin^4 over {math.degrees(drive.width):.0f} deg at {drive.omega:g} rad/s "
                       f"({drive.width / drive.omega * 1e6:.1f} us; highest harmonic 2 omega / width = {f_gas:.4g} Hz)")
    return f2, f"the crank's second harmonic 2 omega = {f2:.4g} Hz"


def advise_crank(runs: Runs, tolerance: float, rho_inf: float, max_modes: int = 40) -> ModalAdvice:
    """The advice of the module doc for the drive of `runs` (rho_inf: the scene's; the modes seen up to
    max_modes)."""
    reasons = {}
    drive = runs.drive
    f_exc, what = excitation(drive)
    freqs = np.sort(runs.frequencies(max_modes))
    n, f_rel, h_max = modes_and_step(freqs, f_exc, max_modes, rho_inf, tolerance)
    reasons["modes"] = (f"highest excitation {f_exc:.4g} Hz ({what}; the crank at {drive.omega / 2 / math.pi:.1f} Hz); "
                        f"free-free modes {freqs[0]:.4g} .. {freqs[-1]:.4g} Hz; {n} below {MODE_BAND:g} x {f_exc:.4g} = "
                        f"{MODE_BAND * f_exc:.4g} Hz (at least {MIN_MODES})")
    step = nice_step(h_max, runs.duration)
    reasons["step"] = (f"{STEP_ERROR_FACTOR:g} x the period error at {f_rel:.4g} Hz within {RESERVE:g} x tolerance: "
                       f"h <= {h_max:.3g} s -> h = {step:g} s")
    h_terms = 2 * step if divides(runs.duration, 2 * step) else step
    budget = TERM_SHARE * tolerance
    full = runs.run(n, "full", FULL_TERMS, h_terms)
    to_full = {"full": 0.0}
    for s in TERM_SETS_BY_COST[:-1]:
        to_full[s] = moved(runs.run(n, s, FULL_TERMS, h_terms), full)
        if to_full[s] <= budget:
            break
    terms = next(s for s in TERM_SETS_BY_COST if s in to_full and to_full[s] <= budget)
    measure = (f"the monolithic drive over {runs.duration * 1e3:g} ms at {n} modes, h = {h_terms:g} s (mid-shank "
               "axial and bending: max difference over full's peak)")
    reasons["terms"] = (f"{measure}: from full {', '.join(f'{s} {v:.3%}' for s, v in to_full.items() if s != 'full')}; "
                        f"{terms} is the cheapest set within TERM_SHARE x tolerance = {budget:.2%} of full")
    full_terms = ()
    if terms == "full":
        for s in SWITCH_ALONE:
            to_full[f"full-{s}"] = moved(runs.run(n, "full", tuple(x for x in FULL_TERMS if x != s), h_terms), full)
        full_terms, reasons["full_terms"] = choose_full_terms(
            {"status": "ok", "to_full": to_full, "measure": measure, "scale_of": "full"}, tolerance)
    return ModalAdvice(terms, n, step, tolerance, 1, reasons, tuple(full_terms))


def check_crank(runs: Runs, advice: ModalAdvice, cutoffs) -> dict:
    """The advised configuration against the converged monolithic reference (module doc)."""
    c = converge(lambda n, h: runs.run(n, "full", FULL_TERMS, h), cutoffs, advice.step, moved,
                 CONVERGED_SHARE * advice.tolerance)
    ref = c.reference
    run = runs.run(advice.modes, advice.terms, advice.full_terms if advice.terms == "full" else FULL_TERMS, advice.step)
    dev = cd.deviation(run.run, ref.run)
    err = max(dev.axial, dev.bending)
    return {"run": run, "reference": ref, "modes_table": c.table, "mode_moves": c.mode_moves, "step_table": c.steps,
            "step_moves": c.step_moves, "resolved": c.resolved, "axial": dev.axial, "bending": dev.bending, "error": err,
            "within_tolerance": (err <= advice.tolerance) if c.resolved else None}


def format_crank(advice: ModalAdvice, res: dict | None, drive: cd.CrankDrive, duration: float) -> str:
    lines = [f"advice for the conrod in the crank drive (crank {drive.omega:g} rad/s, r = {drive.r:g} m, piston "
             f"{drive.m_p:g} kg, gas {drive.F_max:g} N; {duration * 1e3:g} ms) at tolerance {advice.tolerance:.1%}: "
             f"{advice.label}", "  " + " ".join(f"--set {o}" for o in advice.overrides)]
    lines += [f"  {k} : {v}" for k, v in advice.reasons.items()]
    if res:
        lines.append(f"  reference: the monolithic drive with all of full's terms, h = {res['modes_table'][0].step:g} s, "
                     "over the mode cutoffs, then the step halved:")
        for i, r in enumerate(res["modes_table"]):
            mv = f"  (moves {res['mode_moves'][i - 1]:.2e})" if i else ""
            lines.append(f"    {r.modes:4d} modes{mv}  [{r.wall:.1f} s]")
        for r, mv in zip(res["step_table"], res["step_moves"]):
            lines.append(f"    {r.modes:4d} modes at h = {r.step:g} s (the halving moves it {mv:.2e})  [{r.wall:.1f} s]")
        verdict = VERDICT[res["within_tolerance"]]
        lines.append(f"  check: {res['run'].label} against {res['reference'].label}: axial {res['axial']:.3%}, bending "
                     f"{res['bending']:.3%} of the reference's peaks ({verdict} {advice.tolerance:.1%}), wall "
                     f"{res['run'].wall:.1f} s against the reference's {res['reference'].wall:.1f} s")
    return "\n".join(lines)


def advise_command(args) -> int:
    """`ffrf-fmu advise MODEL --system crank`: exit 0 (within the tolerance), 1 (not), 3 (no verdict), 2 (a body
    not of the drive)."""
    import sys

    from ..model import load_model

    model = load_model(args.model, args.overrides)
    ports = {p.name for p in model.body.ports}
    if not {"big_eye", "small_eye", "mid_shank"} <= ports:
        print(f"ffrf-fmu advise: error: {args.model}: --system crank advises the conrod of the crank drive, whose "
              f"partners drive the ports big_eye, small_eye and mid_shank (models/conrod_crank.toml); this body has "
              f"{sorted(ports)}", file=sys.stderr)
        return 2
    drive = cd.CrankDrive()
    duration = args.duration or DURATION
    runs = Runs(drive, duration, args.model, args.overrides)
    advice = advise_crank(runs, args.tolerance, model.scene("crank").rho_inf)
    res = None
    if args.check:
        res = check_crank(runs, advice, reference_cutoffs(args, advice.modes, (1, 1.5, 2, 3)))
    if args.json:
        dump_json(advice, res, CrankRunMetric, lambda r: {"modes": r.modes, "terms": r.terms, "full_terms": r.full_terms,
                                                          "step": r.step, "wall": r.wall})
    else:
        print(format_crank(advice, res, drive, duration))
    return exit_code(res)
