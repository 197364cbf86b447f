"""Newton on B1 (Haug's rotating beam spin-up): iterations and factorizations per step against the
step size and the Jacobian-reuse rules (runtime/newton.py THETA_REFRESH, REFRESH_AFTER).

    python benchmarks/newton_policy.py [--steps 0.002,0.02,0.05] [--configs 1x2,4x2] [--thetas 0.1,0.25,0.5,0.9]
                                       [--refresh-after 2:3] [--duration 20] [--point-steps 1,5,10]

Each run is the whole scene on the numpy backend (the native backend makes the same decisions):
Newton iterations (residual evaluations, each with one solve) per step, factorizations of the
iteration matrix per step, and the failure if Newton gave up. The threshold is the contraction theta
of successive increments beyond which the stored factorization is dropped within a step (modified
Newton keeps it otherwise; theta = 0 would be full Newton); REFRESH_AFTER = lo:hi drops it before a
step that follows one of lo to hi iterations. Iteration counts, not times: they do not depend on the
machine (benchmarks/newton_iterations.py measures times, against a baseline revision).
--point-steps N1,N2,...: the FMU's input rule beside the exact drive: the inputs extrapolated from the
point values at each communication point t_c = k N h (runtime/input_rule.py, BodySystem.run_extrapolated), N internal
steps per communication step; the standalone column, then one per N (the thetas then take the first value
only).
--tolerances T1,T2,...: the Newton tolerance instead (BodySystem tol, default 1e-9): per configuration and
tolerance, the whole scene on the native backend (simulate.run): Newton iterations per step, the maximum tip
deflection and its change against the default tolerance's run.
--policy NAME=VALUE: a constant of runtime/newton.py's policy (KEEP_MISS, KEPT_ACCEPT, ...) for every run of
this process, on both backends (the C runtime reads the policy from the body's image).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from ffrf_fmu import simulate as sim  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.model.scene import reduction_options  # noqa: E402
from ffrf_fmu.reduction import reduce_body  # noqa: E402
from ffrf_fmu.runtime import input_rule  # noqa: E402
from ffrf_fmu.runtime.newton import ModifiedNewton  # noqa: E402
from ffrf_fmu.runtime.ports import StepFailure  # noqa: E402

MODEL = HERE.parent / "models" / "haug_beam.toml"
SETTINGS: list[str] = []  # --set KEY=VALUE (model settings for every run, e.g. stiffening=true)


def run(h: float, n_se: int, modes: int, theta: float, refresh_after: tuple[int, int], duration: float, point_n: int = 0):
    model = load_model(MODEL, [f"superelements={n_se}", f"modes={modes}", f"step={h}", f"duration={duration}", *SETTINGS])
    scene = model.scene("spinup")
    body = reduce_body(model.body, **reduction_options(scene)).data
    system, inputs = sim.build_system(body, scene, backend="numpy")  # (the counters below wrap the numpy path)
    system.THETA_REFRESH = theta  # instance attributes: this body only (the numpy path reads them per step)
    system.REFRESH_AFTER = refresh_after
    factorizations = [0]
    factor = system._factor

    def counting(*args):
        factorizations[0] += 1
        return factor(*args)

    system._factor = counting
    iterations, failure = [], None
    n = round(duration / h)
    step = system.step

    def counting_step(*args):  # BodySystem.run_extrapolated steps through this on the numpy backend
        iterations.append(step(*args))
        return iterations[-1]

    try:
        if point_n:
            system.step = counting_step
            for k in range(n // point_n):
                t_c = k * point_n * h
                system.run_extrapolated(h, point_n, t_c, input_rule.point_values(body.ports, inputs(t_c)))
                system.t = t_c + point_n * h  # the master's clock, as an FMU's doStep
        else:
            for _ in range(n):
                iterations.append(system.step(h, inputs))
    except StepFailure as e:
        failure = str(e)
    k = max(len(iterations), 1)
    return np.mean(iterations) if iterations else float("nan"), factorizations[0] / k, failure


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", default="0.002,0.02,0.05")
    ap.add_argument("--configs", default="1x2,4x2", help="superelements x modes")
    ap.add_argument("--thetas", default="0.1,0.25,0.5,0.9")
    ap.add_argument("--refresh-after", default="2:3")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--point-steps", default="", help="internal steps per communication step of the FMU's input rule")
    ap.add_argument("--tolerances", default="", help="Newton tolerances to compare (native backend)")
    ap.add_argument("--held", help=argparse.SUPPRESS)  # the old spelling, refused below
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a model setting for every run (repeatable), e.g. stiffening=true")
    ap.add_argument("--policy", action="append", default=[], metavar="NAME=VALUE",
                    help="a constant of runtime/newton.py's policy for every run (repeatable), e.g. KEEP_MISS=1e-8")
    args = ap.parse_args(argv)
    SETTINGS[:] = args.set
    for item in args.policy:
        name, _, value = item.partition("=")
        if not (name.isupper() and isinstance(getattr(ModifiedNewton, name, None), float)):
            ap.error(f"--policy {item}: not a numeric constant of runtime/newton.py's ModifiedNewton")
        setattr(ModifiedNewton, name, float(value))  # (the class: the numpy path and the C image read it)
    if args.held is not None:
        ap.error("--held is now --point-steps (internal steps per communication step from the point values; "
                 "'held' names inputs kept constant over a step)")
    if args.point_steps:
        return point_table(args)
    if args.tolerances:
        return tolerance_table(args)
    print(f"B1 spin-up, {args.duration:g} s, REFRESH_AFTER {args.refresh_after}; Newton iterations / factorizations per step")
    print(f"{'h [ms]':>7} {'SE x modes':>10} " + " ".join(f"{'theta ' + t:>17}" for t in args.thetas.split(",")))
    for h in (float(x) for x in args.steps.split(",")):
        for cfg in args.configs.split(","):
            n_se, modes = (int(v) for v in cfg.split("x"))
            cells, notes = [], []
            for theta in (float(t) for t in args.thetas.split(",")):
                it, fac, failure = run(h, n_se, modes, theta, tuple(int(k) for k in args.refresh_after.split(":")), args.duration)
                cells.append(f"{it:8.2f} / {fac:5.2f}{'*' if failure else ' '}")
                if failure:
                    notes.append(f"theta {theta:g}: {failure}")
            print(f"{1e3 * h:7g} {cfg:>10} " + " ".join(cells))
            for note in notes:
                print(f"{'':19}* {note}")
    return 0


def point_table(args) -> int:
    """--point-steps: the standalone run (exact drive), then one column per number of internal steps per
    communication step."""
    ns = [0] + [int(x) for x in args.point_steps.split(",")]
    theta = float(args.thetas.split(",")[0])
    print(f"B1 spin-up, {args.duration:g} s, REFRESH_AFTER {args.refresh_after}, theta {theta:g}; standalone (exact "
          "drive), then the FMU's input rule; Newton iterations / factorizations per internal step")
    print(f"{'h [ms]':>7} {'SE x modes':>10} " + " ".join(f"{f'H = {n} h' if n else 'standalone':>17}" for n in ns))
    for h in (float(x) for x in args.steps.split(",")):
        for cfg in args.configs.split(","):
            n_se, modes = (int(v) for v in cfg.split("x"))
            cells = []
            for n in ns:
                it, fac, failure = run(h, n_se, modes, theta, tuple(int(k) for k in args.refresh_after.split(":")),
                                       args.duration, n)
                cells.append(f"{it:7.3f} / {fac:6.3f}{'*' if failure else ' '}")
            print(f"{1e3 * h:7g} {cfg:>10} " + " ".join(cells))
    return 0


def tolerance_table(args) -> int:
    """--tolerances: simulate.run (native) per tolerance, the scene's BodySystem built with that tol."""
    import functools

    from ffrf_fmu.runtime.body import BodySystem
    from ffrf_fmu.simulate import loop

    default = 1e-9  # BodySystem's tol
    tols = sorted({float(x) for x in args.tolerances.split(",")} | {default})
    print(f"B1 spin-up, {args.duration:g} s, native; per tolerance: Newton iterations per step, max tip deflection [m], "
          f"its change against tol = {default:g} (relative)")
    for h in (float(x) for x in args.steps.split(",")):
        for cfg in args.configs.split(","):
            n_se, modes = (int(v) for v in cfg.split("x"))
            model = load_model(MODEL, [f"superelements={n_se}", f"modes={modes}", f"step={h}", f"duration={args.duration}",
                                       *SETTINGS])
            scene = model.scene("spinup")
            body = reduce_body(model.body, **reduction_options(scene)).data
            out = {}
            for tol in tols:
                loop.BodySystem = functools.partial(BodySystem, tol=tol)
                try:
                    res = sim.run(body, scene, origin=model.body.origin, progress=False, backend="native")
                finally:
                    loop.BodySystem = BodySystem
                out[tol] = res.summary
            ref = out[default]["metrics"]["tip_deflection_max_m"]
            for tol in tols:
                s = out[tol]
                tip = s["metrics"].get("tip_deflection_max_m")
                fail = f"  FAILED: {s['failure']}" if s["failure"] else ""
                print(f"{1e3 * h:7g} ms {cfg:>5} tol {tol:7.0e}: {s['newton_iterations_mean']:6.3f} it/step  "
                      f"tip {tip:.12f}  {(tip - ref) / ref:+.1e}{fail}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
