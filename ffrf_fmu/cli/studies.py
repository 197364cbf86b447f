"""`ffrf-fmu` studies over many runs: campbell, stability, chart, study, advise and the reference's
convergence table."""
from __future__ import annotations

import argparse
import json
import sys

from ..checked_toml import ModelError
from .common import BACKEND_ARG, MODEL_ARGS, PROG, SWEEP_ARGS, _load, _scheduler, arg, command


def reference_args(when: str, output_help: str) -> tuple:
    """--reference-elements, --reference-step: the full-order reference beam of a chart or of advise --check;
    -o DIR, the result store its run is kept in (default `chart` for both, so that advise --check reuses a
    chart's reference run), and --backend."""
    return (arg("--reference-elements", type=int, metavar="N", help=f"elements of the full-order reference beam ({when}"
                "default: the scene's [reference] elements, else max(16, 4 x superelements of the model))"),
            arg("--reference-step", type=float, metavar="H", help=f"step of the reference ({when}default: the "
                "scene's [reference] step, else the scene's step)"),
            arg("-o", "--output", default="chart", metavar="DIR", help=output_help),
            BACKEND_ARG)


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

    from ..studies.campbell import campbell as diagram, plot

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

    from ..studies import stability as st
    from ..studies.store import StoreVersionError
    from ..studies.sweep import SweepError

    out = Path(args.output)
    values = tuple(float(x) for x in args.values.split(",")) if args.values else None
    if not args.plot_only:
        from ..model import load_model

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
    *SWEEP_ARGS,
    *reference_args("", "output directory: chart.csv, chart.png, chart.json and the result store of every run, "
                    "the reference's included (runs.jsonl: a rerun skips finished runs)"),
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

    from ..studies import chart as ch
    from ..studies.grid import GridError, parse_values
    from ..studies.store import StoreVersionError
    from ..studies.sweep import SweepError

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
        from ..studies.resolve import Resolution, format_resolution

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
    from ..studies.grid import GridError, parse_values
    from ..studies.store import StoreVersionError
    from ..studies.study import StudyError, read_table
    from ..studies.study import study as run_study
    from ..studies.sweep import SweepError

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
    *reference_args("with --check; ", "with --check: the result store of its two runs (a chart's directory: its "
                    "reference run is not repeated)"),
    arg("--json", action="store_true", help="print a JSON object instead of text"),
    arg("--cutoffs", metavar="N1,N2,...", help="with --check, where the reference is the scene's own converged modes (a "
        "solid or shell body, a rotating unbalance: studies/modal_advice.py): the mode counts to converge over "
        "(default: the advised count x 1, 1.5, 2, 3, 4)"),
    arg("--system", choices=("crank",), help="advise the body in the system its partner FMUs make, against that "
        "system's monolithic reference: crank, the conrod in the crank drive (models/conrod_crank.toml; "
        "studies/crank_advice.py)"),
    arg("--duration", type=float, metavar="T", help="with --system: the system run's duration [s] (default: the "
        "drive's 7.5 ms)"),
    *SWEEP_ARGS,
)
def advise(args) -> int:
    """Pick superelements, modes, term set and step for a scene and a tolerance, with the reasons."""
    from ..studies import advise as ad
    from ..studies.store import StoreVersionError
    from ..studies.sweep import SweepError

    model, scene = _load(args)
    if not 0.0 < args.tolerance < 1.0:
        print(f"{PROG}: error: --tolerance must be between 0 and 100 %, got {args.tolerance:g}", file=sys.stderr)
        return 2
    from ..studies import modal_advice as ma

    if args.system:
        from ..studies import crank_advice

        return crank_advice.advise_command(args)
    if ma.needs_modal_reference(model, scene):
        return ma.advise_command(args, model, scene)
    advice = ad.advise(model, scene.name, args.tolerance, fmu=args.fmu, backend=args.backend)
    out = advice.as_dict()
    if not args.json:
        print(ad.format_advice(advice, model.body.name, scene.name))
    if args.check:
        try:
            from ..studies.check import check, format_check

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
    return ma.exit_code(out["check"] if args.check else None)


@command(
    arg("--elements", default="4,8,16,32", metavar="N1,N2", help="meshes of the reference beam"),
    arg("--steps", default="0.02,0.01,0.005,0.002,0.001", metavar="H1,H2", help="time steps [s]"),
    arg("--quick", action="store_true", help="elements 4,8,16 and steps 0.01,0.002"),
)
def convergence(args) -> int:
    """Convergence of the full-order reference beam on B1 over mesh and step (ffrf_fmu/reference/convergence.py)."""
    from ..reference.convergence import convergence_table

    els = [4, 8, 16] if args.quick else [int(x) for x in args.elements.split(",")]
    steps = [0.01, 0.002] if args.quick else [float(x) for x in args.steps.split(",")]
    return convergence_table(els, steps)
