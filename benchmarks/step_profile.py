"""Cost of one integrator step of the body (B1, Haug's rotating beam, 1, 2 and 4 superelements).

    python benchmarks/step_profile.py [--steps 200] [--repeats 7] [--warmup 250] [--no-profile]

Prints, per configuration, microseconds per residual evaluation (stage + residual at given rates,
the body of a Newton iteration), per step (runtime.BodySystem.step, scene inputs included), per
step with the per-step recording of simulate.run (outputs and energies), per simulated second
(h = 2 ms: 500 steps) and Newton iterations per step; then a cProfile top-15 of the 4-superelement
steps. Each figure is the best of --repeats runs of --steps steps from the same saved state (the
machine is shared and noisy: the minimum is the reproducible figure). The state is taken after
--warmup steps of the spin-up, so the iteration matrix exists and the beam rotates.

If benchmarks/_baseline_system.py exists (a frozen copy of an earlier runtime/system.py, kept only
while optimizing), the same figures are measured for it in the same run and reported as ratios.
"""
from __future__ import annotations

import argparse
import cProfile
import importlib
import io
import pstats
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from ffrf_fmu import simulate as sim  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.reduction import build_body  # noqa: E402
from ffrf_fmu.runtime.system import BodySystem  # noqa: E402

MODEL = HERE.parent / "models" / "haug_beam.toml"


def implementations():
    """(label, BodySystem class, record function) of the current code and, if present, the baseline."""
    out = [("current", BodySystem, sim.record)]
    if (HERE / "_baseline_system.py").exists():
        base = importlib.import_module("_baseline_system")
        out.append(("baseline", base.BodySystem, base.record))
    return out


def build(cls, body, scene, warmup):
    system = cls(body, terms=scene.terms, rho_inf=scene.rho_inf, gravity=scene.gravity)
    inputs = sim.scene_inputs(body, scene)
    system.initialize(0.0, inputs)
    for _ in range(warmup):
        system.step(scene.step, inputs)
    return system, inputs


def residual_call(system, h, inputs):
    """A no-argument callable evaluating one residual at the current rates, as the Newton loop does."""
    am, af, gamma = system.coefficients
    values = inputs(system.t + h)
    yd = system.yd.copy()
    if hasattr(system, "_prepare_step"):  # current code: per-step constants, then stage + residual
        system._prepare_step(h, values, am, af, gamma)
        return lambda: system._residual_at(yd)
    prescribed = system._read_inputs(system.t + h, values)
    loads = prescribed[3:5]
    return lambda: system._residual(yd, system._stage(yd, h, am, af, gamma, prescribed)[0], loads)[0]


def best_time(fn, n, repeats, setup=None):
    best = float("inf")
    for _ in range(repeats):
        if setup is not None:
            setup()
        t0 = time.perf_counter()
        fn(n)
        best = min(best, time.perf_counter() - t0)
    return best / n


def measure(cls, record, body, scene, args):
    system, inputs = build(cls, body, scene, args.warmup)
    h = scene.step
    saved = system.get_state()
    restore = lambda: system.set_state(saved)  # noqa: E731

    res = residual_call(system, h, inputs)

    def residuals(n):
        for _ in range(n):
            res()

    def steps(n):
        it = 0
        for _ in range(n):
            it += system.step(h, inputs)
        steps.iterations = it / n

    def steps_recorded(n):
        for _ in range(n):
            system.step(h, inputs)
            record(system)

    restore()
    t_res = best_time(residuals, 10 * args.steps, args.repeats, restore)
    t_step = best_time(steps, args.steps, args.repeats, restore)
    t_rec = best_time(steps_recorded, args.steps, args.repeats, restore)
    return {"residual": t_res, "step": t_step, "step+record": t_rec, "iterations": steps.iterations}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--warmup", type=int, default=250)
    ap.add_argument("--no-profile", action="store_true")
    args = ap.parse_args(argv)
    impls = implementations()
    print(f"B1 spin-up, h = 2 ms; best of {args.repeats} x {args.steps} steps after {args.warmup} warm-up steps")
    print(f"{'SE':>3} {'code':>9} {'us/residual':>11} {'us/step':>8} {'us/step+rec':>11} {'ms/sim s':>9} "
          f"{'Newton/step':>11}  ratios baseline/current (residual, step, step+rec)")
    for n in (1, 2, 4):
        model = load_model(MODEL, [f"superelements={n}"])
        scene = model.scene("spinup")
        body, _ = build_body(model.body)
        rows = {label: measure(cls, rec, body, scene, args) for label, cls, rec in impls}
        for label, r in rows.items():
            ratio = ""
            if label == "current" and "baseline" in rows:
                b = rows["baseline"]
                ratio = "  " + ", ".join(f"{b[k] / r[k]:.1f}x" for k in ("residual", "step", "step+record"))
            print(f"{n:>3} {label:>9} {1e6 * r['residual']:11.1f} {1e6 * r['step']:8.1f} {1e6 * r['step+record']:11.1f} "
                  f"{1e3 * r['step+record'] / scene.step:9.1f} {r['iterations']:11.2f}{ratio}")
    if not args.no_profile:
        model = load_model(MODEL, ["superelements=4"])
        scene = model.scene("spinup")
        body, _ = build_body(model.body)
        system, inputs = build(BodySystem, body, scene, args.warmup)
        prof = cProfile.Profile()
        prof.enable()
        for _ in range(5 * args.steps):
            system.step(scene.step, inputs)
            sim.record(system)
        prof.disable()
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(15)
        print(f"\ncProfile, current code, 4 SE, {5 * args.steps} steps with recording (tottime):")
        print(out.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
