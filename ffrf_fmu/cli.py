"""`ffrf-fmu` command line: one function per subcommand, registered with @command; all of the
package's argparse code is here (build_fmu.py uses `build` through `command_parser`).

A subcommand is `def name(args) -> int` whose docstring is its help; its arguments come from
the decorator. Over 400 lines: one short function per subcommand, each with its argument table
above it, read one at a time; the work itself is in the modules they call. Expected failures (a bad model file, a missing file) print
`ffrf-fmu: error: <message>` on stderr and exit 2, without a traceback.
"""
from __future__ import annotations

import argparse
import json
import sys

# BLAS threads: pinned to one when the package is imported (ffrf_fmu/__init__.py)
from typing import TYPE_CHECKING, Callable, Sequence

# Start-up: a command imports what it uses, inside its function (`ffrf-fmu --help` imports no numpy;
# benchmarks/cli_startup.py). Only the error type every command catches is imported here.
from .checked_toml import ModelError
from .validate import DEFAULT_ATOL, DEFAULT_RTOL  # validate.py imports numpy only when it runs

if TYPE_CHECKING:
    from .model import Model, Scene

PROG = "ffrf-fmu"
_COMMANDS: list[tuple[Callable, tuple]] = []


def arg(*names, **kwargs):
    """One argparse argument, as given to `command`."""
    return names, kwargs


# The model arguments most subcommands share.
MODEL_ARGS = (
    arg("model", help="model file (TOML, see docs/model-format.md)"),
    arg("--scene", help="scene name (default: the first scene in the file)"),
    arg("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a model value, e.g. --set superelements=2 --set step=1e-3 (repeatable)"),
)


def _backend(value: str) -> str:
    """--backend: a backend of runtime/body.py BACKENDS; a retired one is refused naming its replacement."""
    from .runtime.body import check_backend

    try:
        check_backend(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return value


BACKEND_ARG = arg(
    "--backend", type=_backend, default="native", metavar="{native,numpy}",
    help="native: the C runtime (default; compiled on first use in seconds, then cached in ~/.cache/ffrf-fmu), "
         "numpy: the plain reference implementation")


# Where a sweep's runs go (ffrf_fmu/studies/sweep.py, docs/scale.md); chart and study share them.
SWEEP_ARGS = (
    arg("--workers", type=int, metavar="K", help="local worker processes (default: cpu count; 1 runs in this "
        "process; wall times of concurrent runs are measured per process and grow when K exceeds the free cores)"),
    arg("--scheduler", metavar="ADDRESS", help="run on dask.distributed instead of the local pool: local:N starts a "
        "LocalCluster of N workers, anything else is the address of a running scheduler, e.g. tcp://host:8786 "
        "(optional extra `cluster`; docs/scale.md)"),
    arg("--start-method", choices=("spawn", "forkserver"), default="spawn", help="how the local pool starts its "
        "workers (default spawn; both import ffrf_fmu afresh)"),
    arg("--fresh", action="store_true", help="discard the results stored in the output directory and run every "
        "run again (needed after the code changed: a sweep does not mix code versions)"),
)


def _scheduler(args):
    from .studies.sweep import parse_scheduler

    return parse_scheduler(args.scheduler, args.workers, args.start_method)


def command(*arguments):
    """Register the decorated function as a subcommand named after it."""

    def register(fn):
        _COMMANDS.append((fn, arguments))
        return fn

    return register


def _load(args) -> tuple[Model, Scene]:
    from .model import load_model

    model = load_model(args.model, args.overrides)
    return model, model.scene(args.scene)


def _body_for_scene(model: Model, scene: Scene):
    """The body with the scene's causality, built and reduced: a reduction.ReducedBody."""
    from .reduction import reduce_scene_body  # heavy (scipy); only the commands that need it pay

    return reduce_scene_body(model.body, scene)


def _hz(values, n: int = 6) -> str:
    shown = ", ".join(f"{f:.4f}" for f in values[:n])
    return shown + (f", ... ({len(values)} in all)" if len(values) > n else "")


def _damping_report(data):
    """The body's structural damping as each mode of superelement 0's reduced model feels it (its ratio
    c_i / (2 omega_i), runtime/damping.py), or None when undamped."""
    if data.damping is None or data.damping.kind == "none":
        return None
    import numpy as np

    from .runtime.damping import modal_basis, modal_coefficients

    se = data.superelements[0]
    basis = modal_basis(se.K[None], se.M[None])
    w = basis.omega[0]
    return {"kind": data.damping.kind, **data.damping.as_meta(), "mode_frequencies_hz": (w / (2 * np.pi)).tolist(),
            "mode_ratios": (modal_coefficients(data.damping, basis)[0] / (2 * w)).tolist()}


@command(*MODEL_ARGS, arg("--json", action="store_true", help="print a JSON object instead of text"))
def info(args) -> int:
    """Summarize a model: superelements, dofs before/after reduction, modes and frequencies."""
    model, scene = _load(args)
    from .linear import natural_frequencies  # after the model loads: file errors come first

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
    from .invariants import body_inertia_report, scene_spin  # Witteveen's invariants and indicators
    from .model import scene_body

    spin, axis, spin_source = scene_spin(scene)
    inertia = body_inertia_report(scene_body(body, scene), spin, axis,
                                  first_frequency_hz=freqs[0] if freqs else None, reductions=reductions)
    inertia["spin_source"] = spin_source
    # what each term does on this chain's steady spin (the indicator of term_rule.choose_term_set), and
    # the recommendation: the advisor itself at INFO_TOLERANCE (one rule for info and advise)
    from .term_rule import INFO_TOLERANCE, choose_term_set, steady_term_effects

    if body.solid is not None:  # one superelement, no stiffening: the term-set rule alone (the advisor sizes chains)
        inertia["term_effects"] = steady_term_effects(scene_body(body, scene), scene)
        terms, reason = choose_term_set(inertia["term_effects"], INFO_TOLERANCE)
        inertia["recommended"] = {"tolerance": INFO_TOLERANCE, "terms": terms, "superelements": 1,
                                  "stiffening": False, "reason": reason}
    else:
        from .studies.advise import advise

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
    if body.solid is not None:  # what an FE analyst checks beside a reduced solid (solid/quality.py)
        from .solid.quality import quality_report

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
        print(f"  steady spin at {eff['spin_rate']:.3g} rad/s on this chain (stiffening {'on' if eff['stiffening'] else 'off'}): "
              f"each term changes the boundary displacements by (of linear's) "
              + ", ".join(f"{k.removeprefix('full[').removesuffix(']')} {v:.2%}" for k, v in eff["change"].items()
                          if k != "linear"))
    else:
        print(f"  term effects not evaluated: {eff['status']}")
    rec = inertia["recommended"]
    how = "term_rule.choose_term_set" if body.solid is not None else "ffrf-fmu advise"
    print(f"  recommended at tolerance {rec['tolerance']:.0%} ({how}): {rec['superelements']} SE, term set "
          f"{rec['terms']}, stiffening {'on' if rec['stiffening'] else 'off'}: {rec['reason']}")
    return 0


@command(
    *MODEL_ARGS,
    arg("--out", metavar="DIR", required=True, help="directory for modal.csv and the VTK series (BODY.pvd, BODY_*.vtu)"),
    arg("--every", type=int, default=10, metavar="N", help="record every N-th step (default 10)"),
    arg("--no-vtk", action="store_true", help="write the modal coordinates only"),
)
def recover(args) -> int:
    """Run a solid's scene and write its modal coordinates (modal.csv) and deformed mesh (VTK for ParaView)."""
    model, scene = _load(args)
    if args.every < 1:
        raise ModelError(f"--every: expected a positive integer, got {args.every}")
    from pathlib import Path

    from .solid.recovery import run_recorded, write_modal_csv, write_vtk

    rec, red, data = run_recorded(model, scene.name, every=args.every)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_modal_csv(rec, red, out / "modal.csv")
    print(f"{out / 'modal.csv'}: {len(rec.t)} states, {rec.q.shape[1]} elastic coordinates")
    if not args.no_vtk:
        print(f"{write_vtk(rec, red, out, data.name)}: {len(rec.t)} meshes of {red.fe.n_nodes} nodes")
    return 0


@command(
    *MODEL_ARGS,
    arg("--rates", default="0:400:5", metavar="START:STOP:N | W1,W2", help="spin rates [rad/s]"),
    arg("--modes", type=int, default=3, help="frequencies per rate (default 3)"),
    arg("--terms", choices=("linear", "gyroscopic", "full"), help="term set of the reduced body (default: the scene's)"),
    arg("--full", action="store_true", help="also the full FE model linearized about each steady spin (solids)"),
    arg("-o", "--out", metavar="FIG.png", help="draw the diagram"),
)
def campbell(args) -> int:
    """Campbell diagram: a body's frequencies about its steady spin against the spin rate (studies/campbell.py)."""
    import numpy as np

    from .studies.campbell import campbell as diagram, plot

    model, scene = _load(args)
    try:
        if ":" in args.rates:
            a, b, n = args.rates.split(":")
            rates = np.linspace(float(a), float(b), int(n))
        else:
            rates = np.array([float(x) for x in args.rates.split(",")])
    except ValueError:
        raise ModelError(f"--rates: expected START:STOP:N or W1,W2,..., got {args.rates!r}") from None
    try:
        c = diagram(model, rates, n=args.modes, full=args.full, terms=args.terms, scene=scene.name)
    except (ValueError, RuntimeError) as e:  # a scene without a spin drive; a steady spin not found
        raise ModelError(str(e)) from None
    print(f"{c.model}: spin about {list(c.axis)}, terms {c.terms}, stiffening {'on' if c.stiffening else 'off'}")
    for note in c.notes.values():
        print(f"  {note}")
    print(c.table())
    if args.out:
        plot(c, args.out)
        print(f"wrote {args.out}")
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
    from . import simulate as sim

    model, scene = _load(args)
    if args.solver == "reference":
        result = sim.run_reference(model, scene)
    else:
        from .body_cache import scene_body_data  # a body reduced before loads from the cache

        body_data = scene_body_data(model.body, scene)
        try:
            result = sim.run(body_data, scene, origin=model.body.origin, progress=True, backend=args.backend)
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
    *MODEL_ARGS,
    arg("--map", required=True, choices=("spin", "integrator", "cosim"),
        help="spin: final spin rate vs superelements and term set against the nonlinear beam (B3); "
             "integrator: step size vs rho_inf against a converged run; cosim: communication step vs coupling "
             "scheme against the monolithic run (B5: beam + hub drive FMUs, and the beam split in two FMUs)"),
    arg("-o", "--output", default="stability", metavar="DIR", help="output directory for map.csv and map.png "
        "(resumable: runs already in DIR/map.csv are not run again)"),
    arg("--values", metavar="X,Y,...", help="the swept values: spin rates [rad/s] (spin), steps [s] "
        "(integrator, cosim); default: the documented sweep"),
    arg("--duration", type=float, help="run duration [s] (spin, cosim: the spin-up time T scales with it)"),
    arg("--plot-only", action="store_true", help="redraw DIR/map.png from DIR/map.csv, run nothing"),
    *SWEEP_ARGS,
)
def stability(args) -> int:
    """Map where models, integrator or coupling become inaccurate or unstable (docs/stability.md)."""
    from pathlib import Path

    from .studies import stability as st
    from .studies.store import StoreVersionError
    from .studies.sweep import SweepError

    out = Path(args.output)
    values = tuple(float(x) for x in args.values.split(",")) if args.values else None
    if not args.plot_only:
        from .model import load_model

        model = load_model(args.model, args.overrides)
        log = lambda m: print(m, flush=True)  # noqa: E731
        try:
            sweep = st.SweepOptions(_scheduler(args), args.fresh, progress=True, log=log)
            if args.map == "spin":
                scene = model.scene(args.scene or st.SPIN_SCENE).name
                s = st.SpinSettings(overrides=tuple(args.overrides))
                if values:
                    s.omegas = values
                if args.duration:
                    s.T, s.duration = s.T * args.duration / s.duration, args.duration
                st.spin_map(args.model, scene, s, out, sweep)
            elif args.map == "integrator":
                scene = model.scene(args.scene).name
                s = st.IntegratorSettings(**st.INTEGRATOR_DEFAULTS.get(
                    (model.body.name, scene), {"steps": tuple(model.scene(scene).step * k for k in (0.5, 1, 2, 5, 10))}))
                s.steps, s.overrides = tuple(s.steps), (*s.overrides, *args.overrides)
                if values:
                    s.steps = values
                if args.duration:
                    s.duration = args.duration
                st.integrator_map(args.model, scene, s, out, sweep)
            else:
                s = st.CosimSettings(overrides=tuple(args.overrides))
                if values:
                    s.steps = values
                if args.duration:
                    s.T, s.duration = s.T * args.duration / s.duration, args.duration
                st.cosim_map(args.model, s, out, sweep=sweep)
        except (SweepError, StoreVersionError) as e:
            print(f"{PROG}: error: {e}", file=sys.stderr)
            return 2
    rows = st.read_map(out / "map.csv")
    st.PLOTS[args.map](rows, out / "map.png")
    print(f"wrote {out / 'map.csv'} ({len(rows)} runs) and {out / 'map.png'}")
    return 0


@command(
    *MODEL_ARGS,
    arg("--sweep", nargs="+", action="append", metavar="KEY=V1,V2", default=None,
        help="swept values, e.g. --sweep superelements=1,2,4 modes=2,4,6 terms=linear,gyroscopic step=2e-3,1e-2 "
             "(cartesian product; repeat --sweep to add another group; unswept keys keep the model's values)"),
    arg("--fmu", action="store_true", help="also run every configuration through its FMU under fmpy "
        "(communication step = internal step)"),
    arg("--reference-elements", type=int, metavar="N", help="elements of the full-order reference beam "
        "(default: the scene's [reference] elements, else max(16, 4 x superelements of the model))"),
    arg("--reference-step", type=float, metavar="H", help="step of the reference (default: the scene's [reference] "
        "step, else the scene's step)"),
    *SWEEP_ARGS,
    arg("-o", "--output", default="chart", metavar="DIR", help="output directory: chart.csv, chart.png, "
        "chart.json and the result store of every run, the reference's included (runs.jsonl: a rerun skips finished runs)"),
    BACKEND_ARG,
    arg("--cost", choices=("wall", "cpu"), default="wall", help="time on the x axis and for the Pareto front "
        "(default wall; cpu is the load-independent measure on a busy machine)"),
    arg("--plot-only", action="store_true", help="redraw DIR/chart.png from DIR/chart.csv and chart.json, run nothing"),
    arg("--resolve", metavar="TOL", type=lambda text: _fraction(text), help="refine the reference (mesh, step) until the primary metric "
        "moves by less than a tenth of TOL (e.g. 1%%) and measure against the refined one; the refinement table is "
        "printed and kept in chart.json"),
    arg("--peer", choices=("exudyn",), help="also run a full-order peer code on the scene and draw its runs and "
        "Pareto front: exudyn = Exudyn's 3D geometrically exact beam (optional extra `peers`)"),
    arg("--peer-sweep", nargs="+", metavar="KEY=V1,V2", default=None,
        help="the peer's meshes and steps (default elements=2,3,4,6,8,16 step=0.002,0.005,0.01,0.02,0.04)"),
)
def chart(args) -> int:
    """Accuracy against cost: error of each configuration against the full-order reference over its wall time."""
    from pathlib import Path

    from .studies import chart as ch
    from .studies.grid import GridError, parse_values
    from .studies.store import StoreVersionError
    from .studies.sweep import SweepError

    if args.plot_only:
        out = ch.replot(Path(args.output), cost=args.cost)
        print(f"wrote {out}")
        return 0
    try:
        groups = [parse_values(g) for g in args.sweep] if args.sweep else None
        out = ch.chart(args.model, args.scene, groups, overrides=args.overrides, fmu=args.fmu, backend=args.backend,
                       reference_elements=args.reference_elements, reference_step=args.reference_step,
                       out_dir=args.output, cost=args.cost, peer=args.peer,
                       peer_sweep=parse_values(args.peer_sweep, "--peer-sweep") if args.peer_sweep else None,
                       scheduler=_scheduler(args), fresh=args.fresh, resolve=args.resolve)
    except (GridError, SweepError, StoreVersionError) as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
    ref = out["reference"]
    if ref.get("failure"):
        print(f"reference: full-order beam, {ref['n_elements']} elements FAILED ({ref['failure']}): no errors")
    else:
        cost = "cached" if ref["cached"] else f"{ref['wall_time_s']:.1f} s wall"
        print(f"reference: full-order beam, {ref['n_elements']} elements, h = {ref['step']:g} s, {cost}: "
              + ", ".join(f"{k} = {v:.6g}" for k, v in ref["metrics"].items() if isinstance(v, float)))
        if ref.get("warning"):
            print(f"WARNING: {ref['warning']}")
    if out["meta"].get("reference_resolution"):
        from .studies.resolve import Resolution, format_resolution

        print(format_resolution(Resolution.from_dict(out["meta"]["reference_resolution"])))
    print(ch.format_table(out["rows"]))
    print(f"wrote {out['csv']}, {out['png']}, {out['json']}")
    return 0 if all(r["completed"] for r in out["rows"]) else 1


@command(
    *MODEL_ARGS,
    arg("--vary", nargs="+", action="append", metavar="KEY=V1,V2", default=None, required=True,
        help="varied values, e.g. --vary length=6,8,10 EI2=400,566 or --vary "
             "scenes.spinup.drives.hub.rotation.angle.omega=2,4,8 (every combination runs; repeatable)"),
    *SWEEP_ARGS,
    BACKEND_ARG,
    arg("-o", "--output", default="study", metavar="DIR", help="output directory: study.csv, study.png, "
        "study.json and the result store (runs.jsonl: a rerun skips finished runs)"),
)
def study(args) -> int:
    """Parameter study: the scene's metrics against each varied key of the body and scene (plot and table)."""
    from .studies.grid import GridError, parse_values
    from .studies.store import StoreVersionError
    from .studies.study import StudyError, read_table
    from .studies.study import study as run_study
    from .studies.sweep import SweepError

    try:
        vary = {}
        for group in args.vary:
            for k, v in parse_values(group, "--vary").items():
                if k in vary:
                    raise StudyError(f"--vary: key {k!r} given twice")
                vary[k] = v
        out = run_study(args.model, args.scene, vary, overrides=args.overrides, scheduler=_scheduler(args),
                        out_dir=args.output, fresh=args.fresh, backend=args.backend)
    except (GridError, StudyError, SweepError, StoreVersionError) as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
    meta, rows = out["meta"], read_table(out["csv"])
    print(f"{meta['runs']} runs on {meta['scheduler']}: {meta['runs_ran']} ran, {meta['runs_stored']} from the store, "
          f"{meta['runs_retried']} retried, {meta['runs_failed']} failed")
    cols = list(rows[0]) if rows else []
    shown = [c for c in cols if c not in ("failure", "code_version", "attempts", "cpu_time_s")]
    width = {c: max(11, len(c.rsplit(".", 1)[-1])) for c in shown}
    print("  ".join(f"{c.rsplit('.', 1)[-1]:>{width[c]}}" for c in shown))
    for r in rows:
        print("  ".join(f"{r[c]:>{width[c]}.6g}" if isinstance(r[c], float) else f"{str(r[c]):>{width[c]}}"
                        for c in shown)
              + ("" if r["completed"] else f"  FAILED: {r['failure']}"))
    print(f"wrote {out['csv']}, {out['png']}, {out['json']}")
    return 0 if all(r["completed"] for r in rows) else 1


def _fraction(text: str) -> float:
    """'1%' -> 0.01, '0.01' -> 0.01."""
    t = text.strip()
    try:
        return float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction (0.01) or a percentage (1%), got {text!r}") from None


@command(
    *MODEL_ARGS,
    arg("--tolerance", type=_fraction, required=True, metavar="TOL",
        help="relative error allowed on the scene's primary metric, e.g. 1%% or 0.01"),
    arg("--check", action="store_true", help="run the advised configuration and the reference; report the "
        "achieved error and cost"),
    arg("--chart", metavar="chart.csv", help="with --check: compare the cost with the cheapest configuration of "
        "this chart that meets the tolerance"),
    arg("--fmu", action="store_true", help="the body runs as an FMU with communication step = step: budget the "
        "FMU's input extrapolation too (and --check runs the FMU under fmpy)"),
    arg("--reference-elements", type=int, metavar="N", help="elements of the reference beam (with --check; "
        "default: the scene's [reference] elements, else max(16, 4 x superelements))"),
    arg("--reference-step", type=float, metavar="H", help="step of the reference (with --check; default: the scene's "
        "[reference] step, else the scene's step)"),
    arg("-o", "--output", default="chart", metavar="DIR", help="with --check: the result store of its two runs "
        "(a chart's directory: its reference run is not repeated)"),
    BACKEND_ARG,
    arg("--json", action="store_true", help="print a JSON object instead of text"),
    *SWEEP_ARGS,
)
def advise(args) -> int:
    """Pick superelements, modes, term set and step for a scene and a tolerance, with the reasons."""
    from .studies import advise as ad
    from .studies.store import StoreVersionError
    from .studies.sweep import SweepError

    model, scene = _load(args)
    if not 0.0 < args.tolerance < 1.0:
        print(f"{PROG}: error: --tolerance must be between 0 and 100 %, got {args.tolerance:g}", file=sys.stderr)
        return 2
    advice = ad.advise(model, scene.name, args.tolerance, fmu=args.fmu, backend=args.backend)
    out = advice.as_dict()
    if not args.json:
        print(ad.format_advice(advice, model.body.name, scene.name))
    if args.check:
        try:
            from .studies.check import check, format_check

            res = check(args.model, scene.name, advice, overrides=args.overrides,
                        reference_elements=args.reference_elements, reference_step=args.reference_step,
                        out_dir=args.output, chart_csv=args.chart,
                        scheduler=_scheduler(args), fresh=args.fresh, progress=not args.json)
        except (SweepError, StoreVersionError) as e:
            print(f"{PROG}: error: {e}", file=sys.stderr)
            return 2
        out["check"] = res
        if not args.json:
            print(format_check(res, advice.tolerance))
    if args.json:
        json.dump(out, sys.stdout, indent=2, default=float)
        print()
    if args.check and out["check"]["within_tolerance"] is None:
        return 3  # no verdict: the reference does not resolve the metric at a tenth of the tolerance
    return 0 if not args.check or out["check"]["within_tolerance"] else 1


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
    from .fmu.builder import BuildError, build_fmu

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
    from .fmu.builder import BuildError
    from .fmu.run import FmuRunError
    from .validate import ValidationError
    from .validate import validate as run_validation

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
    for k, d in rep["metrics"].items():
        print(f"  metric {k}: FMU {d['fmu']:.6g}, standalone {d['standalone']:.6g}, rel diff {d['rel_diff']:.2e}")
    w = rep["wall_time_s"]
    print(f"  wall time: FMU {w['fmu']:.2f} s, standalone {w['standalone']:.2f} s (backend {rep['backend']['standalone']})")
    print(("PASSED" if rep["passed"] else "FAILED") + f" (rtol {rep['tolerances']['rtol']:g})")
    return 0 if rep["passed"] else 1


@command(
    arg("action", choices=("write", "run"), help="write: an SSP 1.0 package from FMUs; run: a package under an engine"),
    arg("package", metavar="PACKAGE.ssp"),
    arg("--fmu", action="append", default=[], metavar="NAME=FILE", help="write: a component (repeat)"),
    arg("--ports", action="append", default=[], metavar="A.PORT:B.PORT", help="write: join two body ports rigidly (repeat)"),
    arg("--connect", action="append", default=[], metavar="SRC:DST[:GAIN]",
        help="write: a connection of variables or port fields, e.g. drive.hub_frame.R:beam.hub.R (repeat)"),
    arg("--set", dest="params", action="append", default=[], metavar="INSTANCE.VAR=VALUE", help="write: a parameter (repeat)"),
    arg("--step", type=float, help="communication step [s] (write: required; run: overrides the package's)"),
    arg("--stop", type=float, help="stop time [s] (write: required; run: overrides the package's)"),
    arg("--engine", choices=("master", "libcosim", "ecos"), default="master", help="run: the co-simulation engine"),
    arg("--record", default="", metavar="VAR,...", help="run: variables or port fields to record"),
    arg("-o", "--out", metavar="FILE.csv", help="run: write the recorded series"),
)
def system(args) -> int:
    """Write or run an SSP 1.0 system package (ffrf_fmu/master/ssp.py, docs/cosim.md)."""
    from pathlib import Path

    from .master import ssp

    try:
        if args.action == "write":
            if args.step is None or args.stop is None:
                raise ssp.SspError("write needs --step and --stop")
            s = ssp.system_from_arguments(Path(args.package).stem, args.fmu, args.ports, args.connect, args.params,
                                          args.step, args.stop)
            ssp.write_ssp(args.package, s)
            print(f"wrote {args.package}: {len(s.components)} FMUs, {len(s.connections)} connections, "
                  f"{len(s.parameters)} parameters, H = {s.step:g} s, stop {s.stop:g} s")
            return 0
        pkg = ssp.read_ssp(args.package)
        names = [n for r in filter(None, args.record.split(",")) for n in ssp.expand(
            r, list(ssp._model_variables(pkg.components.get(r.split(".", 1)[0], "")) if r.split(".", 1)[0] in pkg.components else []))]
        run = ssp.run_ssp(args.package, args.engine, names, step=args.step, stop=args.stop)
    except ssp.SspError as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
    if args.out:
        ssp.write_csv(args.out, run)
    print(f"{args.engine}: {len(run.t)} steps to t = {run.t[-1] if len(run.t) else 0.0:g} s in {run.wall:.2f} s"
          + (f"; stopped: {run.stopped}" if run.stopped else ""))
    return 1 if run.stopped else 0


@command(
    arg("--elements", default="4,8,16,32", metavar="N1,N2", help="meshes of the reference beam"),
    arg("--steps", default="0.02,0.01,0.005,0.002,0.001", metavar="H1,H2", help="time steps [s]"),
    arg("--quick", action="store_true", help="elements 4,8,16 and steps 0.01,0.002"),
)
def convergence(args) -> int:
    """Convergence of the full-order reference beam on B1 over mesh and step (ffrf_fmu/reference/convergence.py)."""
    from .reference.convergence import convergence_table

    els = [4, 8, 16] if args.quick else [int(x) for x in args.elements.split(",")]
    steps = [0.01, 0.002] if args.quick else [float(x) for x in args.steps.split(",")]
    return convergence_table(els, steps)


def _add_arguments(parser: argparse.ArgumentParser, arguments) -> None:
    for names, kwargs in arguments:
        parser.add_argument(*names, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description="Flexible bodies (beams and solids) as FFRF superelement FMUs.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for fn, arguments in _COMMANDS:
        doc = (fn.__doc__ or "").strip()
        p = sub.add_parser(fn.__name__, help=doc.splitlines()[0] if doc else None, description=doc)
        _add_arguments(p, arguments)
        p.set_defaults(run=fn)
    return parser


def command_parser(name: str, prog: str) -> argparse.ArgumentParser:
    """A stand-alone parser of one subcommand (build_fmu.py is `build` under another name)."""
    fn, arguments = next((fn, a) for fn, a in _COMMANDS if fn.__name__ == name)
    parser = argparse.ArgumentParser(prog=prog, description=(fn.__doc__ or "").strip().splitlines()[0])
    _add_arguments(parser, arguments)
    parser.set_defaults(run=fn)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except (ModelError, OSError) as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
