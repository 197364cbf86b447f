"""`advise` and `advise --check` where no full-order reference runs the scene: a solid or shell body (one
superelement, its FE model the whole truth), or a scene whose loads or drives the full-order beam refuses (a rotating
unbalance, a drive through a compliant drive spring). The reference is then the same scene with all modes up to a cutoff that converges the metric
(Craig-Bampton-like: the reduced model tends to the FE model as its free-free modes are added, eq. 76), at a
step that converges it too; both convergences are shown.

Advice (the budget of advise.py: the step gets RESERVE x tolerance, the rest is kept for modal truncation):
- term set: term_rule.choose_term_set on term_rule.steady_term_effects (the rule `info` and `advise` share);
- modes: every free-free mode below MODE_BAND x the highest excitation frequency (indicators.excitation:
  the drives' acceleration bands, the spin rate, load windows), at least MIN_MODES per superelement;
- step: the integrator's period error (indicators.period_error) times STEP_ERROR_FACTOR within RESERVE x
  tolerance at the highest relevant frequency, the larger of the excitation's and the first kept mode's (the
  body rings in it after a transient), and at most MAX_SPIN_PER_STEP rad of spin per step (Newton
  robustness: the Jeffcott run-up fails Newton at 0.29 rad per step (gyroscopic; 0.31 with full W1 + W2),
  completes at 0.17;
  docs/inertia-terms.md), rounded down to a step that divides the duration (indicators.nice_step).

Metric (the scene's peak response): the largest |eq. 92 probe| of the scene's first `outputs` entry, else the
largest displacement of the loaded force-driven port (an unbalance's or a load's; with no load the first
force-driven port: GenStruct's corner frame): seen from the port whose
motion-driven rotation spins the scene (eq. 92: its elastic part), else |r_P - X_P| (the Jeffcott rotor's whirl
on its compliant bearings, in world axes); with no such port, a compliant support's peak displacement across the
gravity and the spin axis (_support_across: the balanced Jeffcott rotor's sideways bearing force / k).
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .calibration import MIN_MODES, MODE_BAND, RESERVE, STEP_ERROR_FACTOR
from .indicators import excitation, largest_step, nice_step

MAX_SPIN_PER_STEP = 0.2  # rad: between the run-up's 0.17 (completes) and 0.29 / 0.31 (fails Newton)
CONVERGED_SHARE = 0.1  # the reference is converged when the last refinement moves the metric by < 0.1 x tolerance
MAX_HALVINGS = 3  # of the reference's step: a metric still moving after three halvings gives no verdict
VERDICT = {True: "within", False: "NOT within", None: "no verdict (reference not converged), against"}  # by within_tolerance


def switch_suffix(terms: str, full_terms) -> str:
    """A label's [W1+W2] of full's switches ("" with another set)."""
    return f"[{'+'.join(s.replace('inertia_', '') for s in full_terms)}]" if terms == "full" else ""


def needs_modal_reference(model, scene) -> bool:
    """A solid/shell body, a scene with unbalances, or a drive of a port whose driven part is not motion-driven (a
    compliant drive spring): the full-order reference refuses them."""
    kinds = {p.name: (p.translation, p.rotation) for p in model.body.ports}
    spring_drive = any((d.translation is not None and kinds[d.port][0] != "motion")
                       or (d.rotation is not None and kinds[d.port][1] != "motion") for d in scene.drives)
    return model.body.solid is not None or bool(scene.unbalances) or spring_drive


@dataclass
class ModalAdvice:
    terms: str
    modes: int  # per superelement
    step: float
    tolerance: float
    superelements: int = 1
    reasons: dict = field(default_factory=dict)
    full_terms: tuple = ()  # the switches of `full` it needs (term_rule.choose_full_terms); () with another set

    @property
    def overrides(self) -> list[str]:
        return [f"modes={self.modes}", f"terms={self.terms!r}".replace("'", '"'), f"step={self.step!r}"] + self.switches

    @property
    def switches(self) -> list[str]:
        """The full_terms override of a `full` advice ([] otherwise)."""
        return [f"full_terms={json.dumps(list(self.full_terms))}"] if self.terms == "full" else []

    @property
    def label(self) -> str:
        return f"{self.superelements}SE/{self.modes}m/{self.terms}{switch_suffix(self.terms, self.full_terms)}/{self.step * 1e3:g}ms"


def _frequencies(model, scene, modes: int) -> np.ndarray:
    """Free-free frequencies [Hz] of the first superelement reduced with `modes` modes."""
    from ..body_cache import scene_body_data
    from ..model import load_model

    m = load_model(model.path, [f"modes={modes}"])
    data = scene_body_data(m.body, m.scene(scene.name))
    return np.asarray(data.superelements[0].frequencies_hz if hasattr(data.superelements[0], "frequencies_hz")
                      else _se_frequencies(data.superelements[0]))


def _se_frequencies(se) -> np.ndarray:
    import scipy.linalg as sla

    n_b = se.K.shape[0] - se.n_modes if hasattr(se, "n_modes") else None
    lam = sla.eigh(se.K, se.M, eigvals_only=True) if n_b is None else sla.eigh(se.K, se.M, eigvals_only=True)
    return np.sqrt(np.clip(lam[lam > 1e-6 * lam.max()], 0, None)) / (2 * math.pi)


def advise_modal(model, scene, tolerance: float, max_modes: int | None = None) -> ModalAdvice:
    from ..spin import scene_spin
    from ..term_rule import choose_full_terms, choose_term_set, steady_term_effects

    reasons = {}
    from ..model import scene_body

    ini = scene.initial
    if not (scene.drives or scene.loads or scene.unbalances or any(scene.gravity) or any(ini.velocity)
            or any(ini.angular_velocity) or ini.port_displacements):
        from ..checked_toml import ModelError

        raise ModelError(f"{model.path}: scene {scene.name}: nothing in it moves the body (no drives, loads, unbalances, "
                         "gravity or initial motion): its motion comes from partners outside the model file, a system "
                         "that advise, which runs a model's scene, cannot advise as a whole; where the system is one advise "
                         "knows, name it (--system crank: the conrod in the crank drive; docs/cosim.md, \"Advice at "
                         "1 % on the scenes\")")

    effects = steady_term_effects(scene_body(model.body, scene), scene)  # as `info` does
    terms, reasons["terms"] = choose_term_set(effects, tolerance)
    full_terms = ()
    if terms == "full":  # which of full's switches (Witteveen's 7.3.3: W2 for a structure soft against widening)
        full_terms, reasons["full_terms"] = choose_full_terms(effects, tolerance)
    f_exc, parts = excitation(scene, tolerance)
    n_avail = max_modes or model.body.modes  # reduce with this many to see the modes below the band
    freqs = np.sort(_frequencies(model, scene, n_avail))
    n, f_rel, h = modes_and_step(freqs, f_exc, n_avail, scene.rho_inf, tolerance)
    reasons["modes"] = (f"highest excitation {f_exc:.3g} Hz ({parts[0]}); free-free modes {freqs[0]:.3g} .. "
                        f"{freqs[min(len(freqs), n_avail) - 1]:.3g} Hz; {n} below {MODE_BAND:g} x {f_exc:.3g} = "
                        f"{MODE_BAND * f_exc:.3g} Hz (at least {MIN_MODES})")
    why = (f"{STEP_ERROR_FACTOR:g} x the period error at {f_rel:.3g} Hz (the larger of the excitation and the first "
           f"mode) within {RESERVE:g} x tolerance: h <= {h:.3g} s")
    spin = scene_spin(scene)
    if spin is not None and spin.peak > 0:
        h_spin = MAX_SPIN_PER_STEP / spin.peak
        why += f"; {MAX_SPIN_PER_STEP:g} rad of spin per step at {spin.peak:.3g} rad/s: h <= {h_spin:.3g} s"
        h = min(h, h_spin)
    step = nice_step(h, scene.duration)
    reasons["step"] = why + f" -> h = {step:g} s"
    supers = len(scene_body_superelements(model))
    return ModalAdvice(terms, n, step, tolerance, supers, reasons, tuple(full_terms))


def modes_and_step(freqs, f_exc: float, n_avail: int, rho_inf: float, tolerance: float) -> tuple[int, float, float]:
    """The rule of the module doc at the highest excitation frequency f_exc [Hz] and free-free frequencies freqs
    [Hz] of a body reduced with n_avail modes: the mode count, the relevant frequency f_rel [Hz] (the larger of
    f_exc and the first mode) and the largest step [s] whose period error at f_rel, times STEP_ERROR_FACTOR,
    is within RESERVE x tolerance (before the caller's other caps and nice_step)."""
    n = min(max(MIN_MODES, int(np.sum(np.asarray(freqs) < MODE_BAND * f_exc))), n_avail)
    f_rel = max(f_exc, float(np.min(freqs)))
    return n, f_rel, largest_step(2 * math.pi * f_rel, rho_inf, RESERVE * tolerance / STEP_ERROR_FACTOR)


def scene_body_superelements(model) -> list:
    return [None] * (model.body.superelements if model.body.solid is None else 1)


def scene_metric(model, scene, result) -> float:
    """The metric of the module doc from a standalone result."""
    from ..runtime.outputs import tip_from_hub

    if scene.outputs:
        a, b = scene.outputs[0].split("_from_")
        rA, rB = result.port(a, "r"), result.port(b, "r")
        d = tip_from_hub(result.port(b, "R"), rB, rA, rA[0] - rB[0])
        return float(np.linalg.norm(d, axis=1).max())
    ports = ([u.port for u in scene.unbalances] + [ld.port for ld in scene.loads]
             or [p.name for p in model.body.ports if p.translation == "force"])  # unloaded: the free frame (GenStruct)
    if not ports:
        return _support_across(model, scene, result)
    r = result.port(ports[0], "r")
    hub = _motion_spin_port(model, scene)
    if hub is not None:  # seen from the driven port: the elastic part, not the swing of the rigid rotation
        rB = result.port(hub, "r")
        return float(np.linalg.norm(tip_from_hub(result.port(hub, "R"), rB, r, r[0] - rB[0]), axis=1).max())
    return float(np.linalg.norm(r - r[0], axis=1).max())


def _support_across(model, scene, result) -> float:
    """A body held only by compliant supports, spun under gravity (jeffcott_rotor.toml, scene spin): the peak
    displacement of the first support across the gravity and the spin axis, its spring's sideways force / k. The
    weight's share is the same with every term set (the reactions carry it); the sideways one is what the disc's
    gyroscopic coupling with the supports' compliance sets (docs/inertia-terms.md, "The Jeffcott rotor")."""
    from ..spin import scene_spin

    spin = scene_spin(scene)
    supports = [p.name for p in model.body.ports if p.translation == "compliant"]
    across = np.cross(spin.axis, scene.gravity) if spin is not None else np.zeros(3)
    if not supports or not np.any(across):
        raise ValueError(f"{model.path}: scene {scene.name}: no outputs probe, no loaded or free port, and no "
                         "compliant support spun under gravity across the spin axis to measure")
    r = result.port(supports[0], "r")
    return float(np.abs((r - r[0]) @ (across / np.linalg.norm(across))).max())


def _motion_spin_port(model, scene) -> str | None:
    """The port whose motion-driven rotation spins the scene (spin.scene_spin), else None."""
    from ..spin import spin_drive_rotation

    driven = spin_drive_rotation(model.body, scene)
    return driven[0].port if driven is not None and driven[1] == "motion" else None


@dataclass
class MetricRun:
    label: str
    modes: int
    terms: str
    step: float
    metric: float
    wall: float
    completed: bool


def run_metric(model_path, scene_name: str, modes: int, terms: str, step: float, overrides=()) -> MetricRun:
    from ..model import load_model
    from ..simulate import run_scene

    o = [*overrides, f"modes={modes}", f'terms="{terms}"', f"step={step!r}"]
    m = load_model(model_path, o)
    t0 = time.perf_counter()
    res = run_scene(m, scene_name)
    return MetricRun(f"{modes}m/{terms}/{step * 1e3:g}ms", modes, terms, step, scene_metric(m, m.scene(scene_name), res),
                     time.perf_counter() - t0, bool(res.summary["completed"]))


@dataclass
class Convergence:
    """A reference converged over mode cutoffs, then over halvings of the step (converge)."""

    table: list  # the runs over the cutoffs
    mode_moves: list  # moved(previous cutoff, next)
    steps: list  # the runs at the step halved
    step_moves: list  # moved(previous step, its half)
    resolved: bool  # a cutoff and a halving each moved it by < share

    @property
    def reference(self):
        return self.steps[-1]


def converge(run, cutoffs, step: float, moved, share: float) -> Convergence:
    """run(modes, step) over the cutoffs (ascending) at `step` until a cutoff moves the response by < share
    (moved(previous, next)), then that cutoff's run at the step halved until a halving moves it by < share (at
    most MAX_HALVINGS times; the reference is the last run)."""
    table, mode_moves, converged = [], [], False
    for n in cutoffs:
        table.append(run(n, step))
        if len(table) > 1:
            mode_moves.append(moved(table[-2], table[-1]))
            if mode_moves[-1] < share:
                converged = True
                break
    steps, step_moves, prev = [], [], table[-1]
    for _ in range(MAX_HALVINGS):
        steps.append(run(prev.modes, prev.step / 2))
        step_moves.append(moved(prev, steps[-1]))
        prev = steps[-1]
        if step_moves[-1] < share:
            break
    return Convergence(table, mode_moves, steps, step_moves, converged and step_moves[-1] < share)


def check_modal(model_path, scene_name: str, advice: ModalAdvice, cutoffs, reference_terms: str = "full",
                overrides=()) -> dict:
    """The advised run against the converged reference: the scene at `reference_terms` and the advised step
    over the mode cutoffs (ascending) until the metric moves by < CONVERGED_SHARE x tolerance, then the
    converged cutoff at the step halved until a halving moves the metric by < CONVERGED_SHARE x tolerance (at
    most MAX_HALVINGS times; the reference is the last run)."""
    from ..runtime.terms import FULL_TERMS

    share = CONVERGED_SHARE * advice.tolerance
    ref_overrides = [*overrides, f"full_terms={json.dumps(list(FULL_TERMS))}"] if reference_terms == "full" else overrides
    advised = [*overrides, *advice.switches]
    c = converge(lambda n, h: run_metric(model_path, scene_name, n, reference_terms, h, ref_overrides), cutoffs,
                 advice.step, lambda a, b: abs(b.metric - a.metric) / abs(b.metric), share)
    ref = c.reference
    run = run_metric(model_path, scene_name, advice.modes, advice.terms, advice.step, advised)
    err = abs(run.metric - ref.metric) / abs(ref.metric)
    return {"run": run, "reference": ref, "modes_table": c.table, "step_table": c.steps,
            "step_moves": c.step_moves[-1], "resolved": c.resolved, "error": err,
            "within_tolerance": (err <= advice.tolerance) if c.resolved else None}


def format_modal(advice: ModalAdvice, res: dict | None = None, name: str = "") -> str:
    lines = [f"advice for {name} at tolerance {advice.tolerance:g} ({advice.tolerance:.1%}): {advice.label}",
             "  " + " ".join(f"--set {o}" for o in advice.overrides)]
    lines += [f"  {k} : {v}" for k, v in advice.reasons.items()]
    if res:
        lines.append("  reference: the same scene, all modes up to a cutoff, "
                     f"{res['reference'].terms} terms, h = {res['modes_table'][0].step:g} s:")
        prev = None
        for r in res["modes_table"]:
            move = "" if prev is None else f"  (moves {abs(r.metric - prev) / abs(r.metric):.2e})"
            lines.append(f"    {r.modes:4d} modes: metric {r.metric:.6g}{move}  [{r.wall:.1f} s]")
            prev = r.metric
        prev = res["modes_table"][-1].metric
        for sc in res["step_table"]:
            lines.append(f"    {sc.modes:4d} modes at h = {sc.step:g} s: metric {sc.metric:.6g} (the halving moves it "
                         f"{abs(sc.metric - prev) / abs(sc.metric):.2e})  [{sc.wall:.1f} s]")
            prev = sc.metric
        r = res["run"]
        verdict = VERDICT[res["within_tolerance"]]
        lines.append(f"  check: {r.label} metric {r.metric:.6g} vs {res['reference'].metric:.6g}: error {res['error']:.3%} "
                     f"({verdict} {advice.tolerance:.1%}), wall {r.wall:.1f} s against the reference's {res['reference'].wall:.1f} s")
    return "\n".join(lines)


def advise_command(args, model, scene) -> int:
    """`ffrf-fmu advise` on a scene of this module: the advice, and with --check its check (exit 0 within the
    tolerance, 1 not within, 3 no verdict: the reference did not converge)."""
    advice = advise_modal(model, scene, args.tolerance, max_modes=2 * model.body.modes)
    name = f"{model.body.name}/{scene.name}"
    res = None
    if args.check:
        res = check_modal(args.model, scene.name, advice, reference_cutoffs(args, advice.modes, (1, 1.5, 2, 3, 4)),
                          overrides=args.overrides)
    if args.json:
        dump_json(advice, res, MetricRun, lambda r: r.__dict__)
    else:
        print(format_modal(advice, res, name))
    return exit_code(res)


def reference_cutoffs(args, modes: int, factors) -> list[int]:
    """The reference's mode cutoffs: --cutoffs, else the advised modes times the factors."""
    if args.cutoffs:
        return [int(x) for x in args.cutoffs.split(",")]
    return sorted({max(modes, round(modes * f)) for f in factors})


def dump_json(advice: ModalAdvice, res: dict | None, run_type, conf) -> None:
    """--json: the advice and the check, each run (a run_type) as conf(run)."""
    import sys

    out = {"advice": {**advice.__dict__, "label": advice.label}}
    if res:
        out["check"] = {k: (conf(v) if isinstance(v, run_type) else [conf(r) for r in v]
                            if k in ("modes_table", "step_table") else v) for k, v in res.items()}
    json.dump(out, sys.stdout, indent=2, default=float)
    print()


def exit_code(res: dict | None) -> int:
    """0 without a check or within the tolerance, 1 not within, 3 no verdict (the reference does not resolve the
    metric at CONVERGED_SHARE x tolerance)."""
    if res is None:
        return 0
    return 3 if res["within_tolerance"] is None else 0 if res["within_tolerance"] else 1
