"""`ffrf-fmu` subcommands on one model: info, simulate, build (the FMU) and validate (an FMU against the
Python runtime)."""
from __future__ import annotations

import json
import sys

from ..checked_toml import ModelError
from ..validate import DEFAULT_ATOL, DEFAULT_RTOL  # validate.py imports numpy only when it runs
from .common import BACKEND_ARG, MODEL_ARGS, PROG, _body_for_scene, _damping_report, _hz, _load, arg, command


def _his_row(name: str, inertia: dict):
    from ..witteveen_tables import his_row_for

    row = his_row_for(name, inertia)
    return None if row is None else row.as_dict()


@command(*MODEL_ARGS, arg("--json", action="store_true", help="print a JSON object instead of text"))
def info(args) -> int:
    """Summarize a model: superelements, dofs before/after reduction, modes and frequencies."""
    model, scene = _load(args)
    from ..linear import natural_frequencies  # after the model loads: file errors come first

    reduced = _body_for_scene(model, scene)
    body_data, reductions = reduced.data, reduced.reductions
    freqs = [float(f) for f in natural_frequencies(body_data)]  # fixed: the motion-driven port parts
    ses = [
        {
            "n_fe_dofs": int(red.n_fe_dofs),
            "n_reduced_dofs": int(red.data.n),
            "n_modes": int(len(red.data.frequencies_hz)),
            "orthogonality_error": float(red.orthogonality_error),
            "block_diagonality_error": float(red.block_diagonality_error),
            "frequencies_hz": [float(f) for f in red.data.frequencies_hz],
        }
        for red in reductions
    ]
    body, ports = model.body, body_data.ports
    n_nodes = len(body_data.node_positions)
    # two-field coordinates: boundary frames (shared by neighbours), one CM frame per superelement, modes
    # (with stiffening the modal coordinates hold the centrifugal correction modes beside the vibration modes)
    n_body_dofs = 6 * n_nodes + 6 * len(ses) + sum(se.n - se.n_boundary for se in body_data.superelements)
    fixed = [f"{p.name}.{part}" for p in ports for part in ("translation", "rotation") if getattr(p, part) == "motion"]
    from ..invariants import body_inertia_report, scene_spin  # Witteveen's invariants and indicators
    from ..model import scene_body

    spin, axis, spin_source = scene_spin(scene)
    inertia = body_inertia_report(scene_body(body, scene), spin, axis,
                                  first_frequency_hz=freqs[0] if freqs else None, reductions=reductions)
    inertia["spin_source"] = spin_source
    # what each term does on this chain's steady spin (the indicator of term_rule.choose_term_set), and
    # the recommendation: the advisor itself at INFO_TOLERANCE (one rule for info and advise)
    from ..term_rule import INFO_TOLERANCE, choose_term_set, steady_term_effects

    if body.solid is not None:  # one superelement, no stiffening: the term-set rule alone (the advisor sizes chains)
        inertia["term_effects"] = steady_term_effects(scene_body(body, scene), scene)
        terms, reason = choose_term_set(inertia["term_effects"], INFO_TOLERANCE)
        inertia["recommended"] = {"tolerance": INFO_TOLERANCE, "terms": terms, "superelements": 1,
                                  "stiffening": False, "reason": reason}
        if terms == "full":  # which of full's switches (term_rule.choose_full_terms)
            from ..term_rule import choose_full_terms

            ft, why_ft = choose_full_terms(inertia["term_effects"], INFO_TOLERANCE)
            inertia["recommended"] |= {"full_terms": list(ft), "full_terms_reason": why_ft}
    else:
        from ..studies.advise import advise

        advice = advise(model, scene.name, INFO_TOLERANCE)
        # W1 q is part of the stiffening option too: the terms are weighed with the stiffening the advisor picks
        inertia["term_effects"] = steady_term_effects(scene_body(body, scene), scene,
                                                      stiffening=advice.stiffening)
        inertia["recommended"] = {"tolerance": INFO_TOLERANCE, "terms": advice.terms,
                                  "superelements": advice.superelements,
                                  "stiffening": advice.stiffening, "reason": advice.reasons["terms"]}
        # the first bending frequency of each direction at the top spin (the body linearized about its steady spin)
        inertia["stiffened_frequencies_hz"] = advice.indicators["stiffened_frequencies_hz"]
        inertia["stiffened_frequencies_source"] = advice.indicators["stiffened_frequencies_source"]
    quality = None
    if body.solid is not None:  # what an FE analyst checks beside a reduced solid (reduction_quality.py)
        from ..reduction_quality import quality_report

        red = reductions[0]
        top = float(red.data.frequencies_hz[-1]) if len(red.data.frequencies_hz) else 0.0
        quality = quality_report(red, 2.0 * top if top else None)
    damping = _damping_report(body_data)
    if args.json:
        from dataclasses import asdict

        out = {
            "model": model.path,
            "body": body.name,
            "scene": scene.name,
            "length": body.length,
            "nodes": n_nodes,
            "ports": [asdict(p) for p in ports],
            "superelements": ses,
            "n_body_dofs": n_body_dofs,
            "fixed": fixed,
            "frequencies_hz": freqs,
            "inertia": inertia,
            **({"witteveen": _his_row(body.name, inertia)} if _his_row(body.name, inertia) is not None else {}),
            **({"reduction_quality": quality} if quality is not None else {}),
            **({"damping": damping} if damping is not None else {}),
        }
        json.dump(out, sys.stdout, indent=2)
        print()
        return 0
    print(f"model {model.path}: body {body.name!r}, scene {scene.name!r}")
    if body.solid is not None:
        import numpy as np

        red, spec = reductions[0], body.solid
        what = (f"{spec.element} mesh ({red.fe.source})" if spec.source == "mesh" else
                f"{spec.source} export ({red.fe.source}; units: {spec.units})")
        print(f"  solid: {what}, {red.fe.n_nodes} nodes, size {body.length:.4g} m (bounding-box diagonal), "
              f"mass {red.data.mass:.6g} kg, CM {np.round(red.data.x_cm, 6).tolist()} m")
        print(f"  1 superelement, {n_nodes} interface frames, "
              + (f"modes up to {spec.cutoff_hz:g} Hz" if spec.cutoff_hz else f"{body.modes} free-free modes kept"))
        for p, fr in zip(ports, red.frames):
            print(f"  port {p.name}: frame {p.node} at {np.round(fr.point, 6).tolist()} m on {fr.nodes.size} nodes "
                  f"({fr.coupling}), translation {p.translation}, rotation {p.rotation}")
    else:
        sec = body.section
        kind = "Timoshenko" if sec.GA2 is not None else "Euler-Bernoulli"
        print(f"  beam: L = {body.length:g} m from {list(body.origin)} along {list(body.direction)}, {kind}, "
              f"EA = {sec.EA:g} N, EI2 = {sec.EI2:g}, EI3 = {sec.EI3:g} N m^2, m = {sec.m:g} kg/m")
        print(f"  {len(ses)} superelements x {body.elements_per_superelement} elements, "
              f"{n_nodes} boundary nodes, {body.modes} free-free modes kept per superelement")
        for p in ports:
            print(f"  port {p.name}: node {p.node}, translation {p.translation}, rotation {p.rotation}")
    print("  superelement  FE dofs -> reduced  |U^T M Y|  block-diag  free-free modes [Hz]")
    for i, s in enumerate(ses):
        print(f"  {i:>12}  {s['n_fe_dofs']:>7} -> {s['n_reduced_dofs']:<7}  {s['orthogonality_error']:9.1e}  "
              f"{s['block_diagonality_error']:10.1e}  {_hz(s['frequencies_hz'])}")
    print(f"  body: {n_body_dofs} coordinates = {n_nodes} boundary frames x 6 + {len(ses)} CM frames x 6 "
          f"+ {n_body_dofs - 6 * (n_nodes + len(ses))} modal; fixed: {', '.join(fixed) or 'nothing (free-free)'}")
    print(f"  body frequencies [Hz]: {_hz(freqs, 8)}")
    if damping is not None:
        print(f"  damping ({damping['kind']}; docs/model-format.md): ratio of superelement 0's modes "
              f"{_hz(damping['mode_frequencies_hz'])} Hz: "
              + ", ".join(f"{z:.3g}" for z in damping["mode_ratios"][:8]) + (" ..." if len(damping["mode_ratios"]) > 8 else ""))
    if quality is not None and quality["modes"]:
        print(f"  reduction quality up to {quality['cutoff_hz']:.4g} Hz (2 x the highest kept mode; docs/solids.md): "
              "full -> reduced [Hz] (MAC)")
        print("    " + ", ".join(f"{m['full_hz']:.4g} -> {m['reduced_hz']:.4g} ({m['mac']:.3f})" for m in quality["modes"]))
        print("  effective mass clamped at a port, modes up to the cutoff, full FE model / reduced (x, y, z, rx, ry, rz):")
        for k, fr in quality["effective_mass_fraction"].items():
            full = quality["full_effective_mass"][k]["fraction"]
            print(f"    {k}: " + "  ".join(f"{a:.3f}/{b:.3f}" for a, b in zip(full, fr)))
    worst = lambda key: max(s.get(key, 0.0) for s in inertia["superelements"])  # noqa: E731
    print(f"  inertia terms (docs/inertia-terms.md; worst superelement, modes at {inertia['deflection']:.0%} "
          f"deflection):\n    about the worst axis W1 q/I0 {worst('W1q_over_I0_axis'):.1e}, "
          f"q W2 q/I0 {worst('qW2q_over_I0_axis'):.1e}, coupling q W3 {worst('W3q_over_I0_axis'):.1e}")
    if spin:
        print(f"  spin {spin:g} rad/s from {spin_source}, {inertia['spin_over_first_frequency'] or float('nan'):.2f} x "
              f"first frequency: about the spin axis W1 q/I0 {worst('W1q_spin_axis'):.1e}, "
              f"q W2 q/I0 {worst('qW2q_spin_axis'):.1e}\n    centrifugal softening {worst('softening'):.1e}, "
              f"Coriolis {worst('coriolis'):.1e}, widening {worst('widening'):.1e} of the length")
        sf = inertia.get("stiffened_frequencies_hz")  # beams only (the advisor's directions)
    if spin and sf:
        print(f"  first bending at {spin:g} rad/s: in the plane of rotation {sf['in-plane']:.4f} Hz, out of it "
              f"{sf['out-of-plane']:.4f} Hz ({inertia['stiffened_frequencies_source']})")
    needed = [k for k, v in inertia["needed"].items() if v]
    print(f"  Witteveen's flags (his section 8): {', '.join(needed) or 'nothing beyond the linear terms'}")
    eff = inertia["term_effects"]
    if eff["status"] == "ok":
        print(f"  {eff['measure']} on this chain "
              f"(stiffening {'on' if eff['stiffening'] else 'off'}): "
              f"each term changes the boundary displacements by (of linear's) "
              + ", ".join(f"{k.removeprefix('full[').removesuffix(']')} {v:.2%}" for k, v in eff["change"].items()
                          if k != "linear" and not k.startswith("full-")))
    else:
        print(f"  term effects not evaluated: {eff['status']}")
    rec = inertia["recommended"]
    how = "term_rule.choose_term_set" if body.solid is not None else "ffrf-fmu advise"
    print(f"  recommended at tolerance {rec['tolerance']:.0%} ({how}): {rec['superelements']} SE, term set "
          f"{rec['terms']}, stiffening {'on' if rec['stiffening'] else 'off'}: {rec['reason']}")
    if "full_terms" in rec:
        print(f"  full_terms = {rec['full_terms']}: {rec['full_terms_reason']}")
    from ..witteveen_tables import format_rows, his_row_for

    row = his_row_for(body.name, inertia)
    if row is not None:
        print(format_rows(row))
    return 0


@command(
    *MODEL_ARGS,
    arg("--out", metavar="results.csv", help="write time, every port's frame, velocity and load, and the energies"),
    arg("--summary", metavar="summary.json", help="write wall time, steps, Newton iterations, energy balance, metrics"),
    arg("--plot", metavar="fig.png", help="plot the tip deflection (or port angular velocity) and the energies"),
    BACKEND_ARG,
    arg("--solver", choices=("superelements", "reference"), default="superelements",
        help="superelements (the product) or reference: the full-order geometrically exact beam on the "
             "unreduced FE mesh (superelements x elements per superelement; change with --set elements=N)"),
)
def simulate(args) -> int:
    """Run a scene standalone (no FMU) and report the benchmark metrics."""
    from .. import simulate as sim

    model, scene = _load(args)
    if args.solver == "reference":
        result = sim.run_reference(model, scene)
    else:
        try:  # (a body reduced before loads from the cache, body_cache.py)
            result = sim.run_scene(model, scene.name, progress=True, backend=args.backend)
        except sim.InitializationFailure as e:
            print(f"{PROG}: error: {e}", file=sys.stderr)
            return 2
        if result.summary["backend_note"]:
            print(f"{PROG}: note: {result.summary['backend_note']}", file=sys.stderr)
    s = result.summary
    if args.out:
        result.write_csv(args.out)
    if args.summary:
        result.write_summary(args.summary)
    if args.plot:
        sim.plot(result, scene, args.plot)
    print(f"{model.body.name}/{scene.name}: {s['steps']} steps to t = {s['t_end']:.4g} s in {s['wall_time_s']:.2f} s "
          f"(real-time factor {s['real_time_factor']:.2f}), {s['newton_iterations_mean']:.2f} Newton iterations/step, "
          f"energy balance {s['energy_balance_max_rel']:.2e}")
    for k, v in s["metrics"].items():
        print(f"  {k} = {v}")
    if not s["completed"]:
        print(f"{PROG}: error: {s['failure']}", file=sys.stderr)
        return 1
    return 0


@command(
    arg("model", help="model file (TOML, see docs/model-format.md)"),
    arg("--scene", help="scene whose causality and parameters the FMU takes (default: the first)"),
    arg("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a model value (repeatable), e.g. --set superelements=2"),
    arg("-o", "--output", default=None, help="FMU file to write (default: <body name>.fmu in the current directory)"),
    arg("--runtime", choices=("native", "python"), default="native",
        help="native (default): the FMU in C over the C runtime, nothing needed beside it (docs/fmu.md); "
             "python: the pythonfmu FMU (the host needs a Python with numpy and scipy)"),
    arg("--platform", dest="platforms", action="append", choices=("linux64", "win64"), default=None,
        help="native: binaries to include (repeatable; default linux64 and win64)"),
    arg("--compiler", choices=("zig", "system"), default="zig",
        help="native: zig (default, the ziglang package: every platform) or the system C compiler (linux64)"),
    arg("--backend", choices=("native", "numpy"), default="native",
        help="python runtime: native (default), the slave steps in the C runtime shipped compiled in the FMU; "
             "numpy, the reference implementation"),
    arg("--fmi", type=int, choices=(2, 3), default=2,
        help="FMI version: 2 (default) or 3 (native runtime: port fields as arrays, binaries x86_64-linux and "
             "x86_64-windows; docs/fmu.md)"),
)
def build(args) -> int:
    """Build an FMI 2.0 (or, with --fmi 3, 3.0) co-simulation FMU of a model's body (reduced data only; see docs/fmu.md)."""
    from ..fmu.builder import BuildError, build_fmu

    try:
        out = build_fmu(args.model, args.output or ".", scene=args.scene, overrides=args.overrides,
                               backend=args.backend, runtime=args.runtime,
                               platforms=tuple(args.platforms or ("linux64", "win64")), compiler=args.compiler,
                               fmi=args.fmi)
    except (ModelError, BuildError, OSError) as e:
        print(f"{PROG} build: error: {e}", file=sys.stderr)
        return 2
    import json
    import zipfile

    from fmpy import read_model_description

    md = read_model_description(str(out))
    with zipfile.ZipFile(out) as z:  # the build facts: documentation/build.json (native), ffrf_fmu.json (python)
        name = "documentation/build.json" if args.runtime == "native" else "resources/ffrf_fmu.json"
        scene = json.loads(z.read(name))["build"].get("scene")
    print(f"wrote {out} (FMI {md.fmiVersion}, {args.runtime} runtime, model identifier {md.coSimulation.modelIdentifier}, "
          f"scene {scene!r})")
    return 0


@command(
    arg("source", metavar="MODEL|FMU", help="model file (.toml; the FMU is built) or a built .fmu"),
    arg("--scene", help="scene to run (default: the first scene of the model)"),
    arg("--model", help="model file, required with an .fmu (scene and standalone reference)"),
    arg("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a model value (repeatable), e.g. --set duration=2"),
    arg("--comm-step", type=float, default=None, help="communication step H [s] (default: the scene's internal step)"),
    arg("--report", default=None, metavar="DIR", help="write DIR/report.json and DIR/*.png (and the built FMU)"),
    arg("--rtol", type=float, default=DEFAULT_RTOL, help=f"relative tolerance per output group (default {DEFAULT_RTOL:g})"),
    arg("--atol", type=float, default=DEFAULT_ATOL,
        help=f"absolute tolerance for groups that stay near zero (default {DEFAULT_ATOL:g})"),
    arg("--fmi", type=int, choices=(2, 3), default=2,
        help="FMI version of the FMU built from a model file (an .fmu given is run as the version it is)"),
)
def validate(args) -> int:
    """Run a scene through the FMU under fmpy and standalone, compare every output, write a report.

    Exit 0 when every group is within tolerance and the FMU reached the stop time, 1 when not,
    2 when the validation could not run."""
    from ..fmu.builder import BuildError
    from ..fmu.run import FmuRunError
    from ..validate import ValidationError
    from ..validate import validate as run_validation

    try:
        rep = run_validation(args.source, scene=args.scene, model=args.model, overrides=args.overrides,
                             comm_step=args.comm_step, report_dir=args.report, rtol=args.rtol, atol=args.atol,
                             fmi=args.fmi)
    except (ValidationError, FmuRunError, ModelError, BuildError, OSError) as e:
        print(f"{PROG} validate: error: {e}", file=sys.stderr)
        return 2
    print(f"FMU {rep['fmu']} / scene {rep['scene']}: H = {rep['comm_step']:g} s, internal step "
          f"{rep['internal_step']:g} s, t_end {rep['fmu_t_end']:g} of {rep['duration']:g} s")
    if not rep["fmu_reached_stop_time"]:
        print("  FMU run stopped early: " + (rep["fmu_log"][-1] if rep["fmu_log"] else "(no message)"))
    if not rep["standalone_completed"]:
        print(f"  standalone run stopped early ({rep['standalone_failure']}): compared up to where it stopped")
    if not rep["fmu_matches_model"]:
        print("  warning: " + rep["warning"])
    for g, d in rep["groups"].items():
        mark = "ok " if d["passed"] else "BAD"
        print(f"  {mark} {g:28s} max|diff| {d['max_abs_diff']:.3e}  rel {d['max_rel_diff']:.3e}")
    samp = rep["input_sampling"]
    worst = max(samp["groups"].items(), key=lambda kv: kv[1]["max_rel_diff"], default=None)
    if worst is not None:
        print(f"  input sampling (the standalone run under the FMU's input rule against the exact inputs at every "
              f"step's end; not part of the verdict): largest {worst[0]} rel {worst[1]['max_rel_diff']:.3e}")
    for part, d in samp["drives"].items():
        force = (f", spring force <= {d['force_error_bound']:.3e} ({d['force_error_bound_rel']:.3e} of {d['group']})"
                 if "force_error_bound_rel" in d else "")
        print(f"    {part}: rate error {d['rate_error']:.3e} <= J H^2/2 = {d['rate_error_bound']:.3e}{force}")
    for k, d in rep["metrics"].items():
        print(f"  metric {k}: FMU {d['fmu']:.6g}, standalone {d['standalone']:.6g}, rel diff {d['rel_diff']:.2e}")
    w = rep["wall_time_s"]
    print(f"  wall time: FMU {w['fmu']:.2f} s, standalone {w['standalone']:.2f} s (backend {rep['backend']['standalone']})")
    print(("PASSED" if rep["passed"] else "FAILED") + f" (rtol {rep['tolerances']['rtol']:g})")
    return 0 if rep["passed"] else 1
