"""Cost of one integrator step of the body (B1, Haug's rotating beam), numpy and native backends.

    python benchmarks/step_profile.py [--phases 0.5,5,15] [--steps 40] [--repeats 10]
                                      [--configs 1x2,4x2,4x6] [--blas-threads 1|default]
                                      [--no-profile] [--no-compile-time]

Configurations are superelements x modes per superelement (h = 2 ms, the scene's term set). Both
backends run in the same process on the same states; the numpy backend is the baseline of the
ratios (numpy time / native time). --no-compile-time skips the first-compile measurement (two fresh
processes: one with an empty kernel cache, which compiles, one with the cache it left, which loads).

The spin-up changes character over its 20 s (about 2 Newton iterations per step early on, the
iteration matrix rebuilt at nearly every step around t = 4 s, 4 iterations per step after the
spin-up), so steps are timed in windows starting at several phase times: the current code runs
the scene once and saves its state (without the iteration matrix, so every implementation starts
the window by building its own) at each phase time.

Prints, per configuration: microseconds per residual evaluation (stage + residual at given rates,
the body of a Newton iteration), per step in each window (BodySystem.step, scene inputs included)
and their mean, the mean per step with the per-step recording of simulate.run (outputs, energies),
milliseconds per simulated second (h = 2 ms: 500 steps of that mean, recording included) and the
Newton iterations per step; then a cProfile top-15 of the current code (4 superelements, the
middle window). Each call is timed alone, --repeats times from the same state, and keeps its best
time: on a shared machine the minimum of a short call is the reproducible figure.

BLAS runs on one thread unless --blas-threads default: the target is one core, and a multi-threaded
OpenBLAS makes the LU of the iteration matrix (n ~ 170) hundreds of times slower when the other
core is busy.

The row `native-run` is simulate.run's path on the native backend: the window's steps in ONE call of the C runtime
(BodySystem.run_schedule), the scene's inputs evaluated and every step recorded inside the C runtime;
its step and step+record columns are the same figure (per step, recording included): the CPU time of
the whole window (best of the repeats), since a call of many milliseconds is interrupted on a busy
machine where the single short calls of the other rows are timed clean.

If benchmarks/_baseline_system.py exists (a frozen copy of an earlier runtime, kept only while
optimizing), the same figures are measured for it in the same run.
"""
from __future__ import annotations

import os
import sys

if "--blas-threads" not in sys.argv or sys.argv[sys.argv.index("--blas-threads") + 1] != "default":
    threads = sys.argv[sys.argv.index("--blas-threads") + 1] if "--blas-threads" in sys.argv else "1"
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = threads  # before numpy is imported

import argparse  # noqa: E402
import cProfile  # noqa: E402
import importlib  # noqa: E402
import io  # noqa: E402
import pstats  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from ffrf_fmu import simulate as sim  # noqa: E402
from ffrf_fmu.model import load_model  # noqa: E402
from ffrf_fmu.reduction import reduce_body  # noqa: E402
from ffrf_fmu.runtime.body import BodySystem  # noqa: E402

MODEL = HERE.parent / "models" / "haug_beam.toml"


def implementations():
    """(label, system factory, record function): both backends and, if present, a frozen baseline."""
    make = lambda backend: lambda body, sc: BodySystem(  # noqa: E731
        body, terms=sc.terms, rho_inf=sc.rho_inf, gravity=sc.gravity, backend=backend)
    out = [("numpy", make("numpy"), sim.record), ("native", make("native"), sim.record)]
    if (HERE / "_baseline_system.py").exists():
        base = importlib.import_module("_baseline_system")
        out.append(("baseline", lambda body, sc: base.BodySystem(
            body, terms=sc.terms, rho_inf=sc.rho_inf, gravity=sc.gravity), base.record))
    return out


COMPILE_SNIPPET = """
import sys, time
sys.path.insert(0, {root!r})
from ffrf_fmu.runtime.native import build
t0 = time.perf_counter()
build.library()
print(time.perf_counter() - t0)
"""


def compile_times() -> tuple[float, float]:
    """Seconds of the C runtime's first use in a fresh process with an empty cache (it compiles) and in a
    second fresh process with the cache the first one left (it finds the library)."""
    import subprocess
    import tempfile

    code = COMPILE_SNIPPET.format(root=str(HERE.parent))
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "FFRF_FMU_CACHE_DIR": cache}
        runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
                for _ in range(2)]
    return tuple(float(r.stdout.split()[0]) for r in runs)


def phase_states(body, scene, phases):
    """States of the current code at the phase times, without the iteration matrix."""
    system, inputs = sim.build_system(body, scene)
    n_plain = 5 + sum(getattr(system, k).size for k in system._STATE_FIELDS)
    states = []
    for t_phase in phases:
        while system.t < t_phase - 0.5 * scene.step:
            system.step(scene.step, inputs)
        state = system.get_state()[:n_plain].copy()
        state[4] = 0.0  # no factorization
        states.append(state)
    return states


def best_per_call(call, n, repeats, setup=None):
    """Seconds per call: each of n consecutive calls is timed alone, each call index keeps its best over
    the repeats (which all start from the same state), and the mean of those is returned. Timing single
    calls rather than blocks keeps the figure clean on a shared machine, where a block of many
    milliseconds is almost always interrupted by other processes."""
    best = [float("inf")] * n
    clock = time.perf_counter
    for _ in range(repeats):
        if setup is not None:
            setup()
        for k in range(n):
            t0 = clock()
            call()
            dt = clock() - t0
            if dt < best[k]:
                best[k] = dt
    return sum(best) / n


def best_cpu(call, repeats, setup) -> float:
    """CPU seconds of one call, the best over the repeats (each after setup): for a call of many
    milliseconds, which a busy machine interrupts, the process's CPU time is the clean figure."""
    best = float("inf")
    for _ in range(repeats):
        setup()
        c0 = time.process_time()
        call()
        best = min(best, time.process_time() - c0)
    return best


def residual_call(system, h, inputs):
    """A no-argument callable evaluating one residual at the current rates, as the Newton loop does."""
    am, af, gamma = system.coefficients
    values = inputs(system.t + h)
    yd = system.yd.copy()
    if hasattr(system, "_prepare_step"):  # current code: per-step constants, then stage + residual
        system._prepare_step(system.t + h, h, values, am, af, gamma)
        return lambda: system._residual_at(yd)
    prescribed = system._read_inputs(system.t + h, values)
    loads = prescribed[3:5]
    return lambda: system._residual(yd, system._stage(yd, h, am, af, gamma, prescribed)[0], loads)[0]


def measure(make, record, body, scene, states, args):
    system = make(body, scene)
    inputs = sim.scene_inputs(body, scene)
    h = scene.step
    out = {"step": [], "step+record": [], "iterations": []}
    for i, state in enumerate(states):
        restore = lambda: system.set_state(state)  # noqa: E731
        restore()
        system.step(h, inputs)  # a first step builds the iteration matrix; the window starts after it
        state = system.get_state()
        restore()
        if i == 0 and getattr(system, "backend", "numpy") == "numpy":  # the native residual is inside the C runtime
            out["residual"] = best_per_call(residual_call(system, h, inputs), 5, 20 * args.repeats)
            restore()
        iterations = []
        step = lambda: iterations.append(system.step(h, inputs))  # noqa: E731
        out["step"].append(best_per_call(step, args.steps, args.repeats, restore))
        out["iterations"].append(np.mean(iterations))
        out["step+record"].append(
            best_per_call(lambda: (system.step(h, inputs), record(system)), args.steps, args.repeats, restore)
        )
        if getattr(system, "backend", "numpy") == "native":  # the many-step call of simulate.run
            schedule = sim.scene_schedule(body, scene)
            rows, times = np.empty((args.steps, len(sim.column_names(body)))), np.empty(args.steps)
            out.setdefault("run", []).append(best_cpu(lambda: system.run_schedule(h, schedule, rows, times), args.repeats,
                                                      restore) / args.steps)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--phases", default="0.5,5,15", help="window start times [s] in the 20 s spin-up")
    ap.add_argument("--steps", type=int, default=40, help="steps per window")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--configs", default="1x2,4x2,4x6", help="superelements x modes, comma separated")
    ap.add_argument("--blas-threads", default="1", help="BLAS threads, or 'default' to leave them alone")
    ap.add_argument("--no-profile", action="store_true")
    ap.add_argument("--no-compile-time", action="store_true")
    args = ap.parse_args(argv)
    phases = [float(x) for x in args.phases.split(",")]
    configs = [tuple(int(v) for v in c.split("x")) for c in args.configs.split(",")]
    impls = implementations()
    if not args.no_compile_time:
        first, cached = compile_times()
        print(f"C runtime: first use {first:.1f} s (empty cache: compiles), {cached:.3f} s with the cache")
    print(f"B1 spin-up, h = 2 ms, BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS', 'default')}; windows of "
          f"{args.steps} steps at t = {', '.join(f'{p:g}' for p in phases)} s; best of {args.repeats} per step")
    head = " ".join(f"{f't={p:g}':>7}" for p in phases)
    print(f"{'SE x modes':>10} {'backend':>8} {'us/resid':>8}  us/step: {head} {'mean':>7} {'+record':>8} "
          f"{'ms/sim s':>8} {'Newton/step':>14}  numpy/this: step, step+record")
    mid = None
    for n, modes in configs:
        model = load_model(MODEL, [f"superelements={n}", f"modes={modes}"])
        scene = model.scene("spinup")
        body = reduce_body(model.body).data
        states = phase_states(body, scene, phases)
        if mid is None or (n, modes) == max(configs):
            mid = (body, scene, states[len(states) // 2], f"{n} SE x {modes} modes")
        rows = {label: measure(make, rec, body, scene, states, args) for label, make, rec in impls}
        base = rows["numpy"]
        if "run" in rows["native"]:  # simulate.run's path: chunks of steps in one call, inputs and recording inside
            rows["native-run"] = {**rows["native"], "step": rows["native"]["run"], "step+record": rows["native"]["run"]}
            rows["native-run"].pop("residual", None)
        for label, r in rows.items():
            step, rec = np.mean(r["step"]), np.mean(r["step+record"])
            ratio = f"  {np.mean(base['step']) / step:.1f}x, {np.mean(base['step+record']) / rec:.1f}x"
            steps = " ".join(f"{1e6 * x:7.0f}" for x in r["step"])
            resid = f"{1e6 * r['residual']:8.1f}" if "residual" in r else f"{'-':>8}"
            print(f"{f'{n} x {modes}':>10} {label:>8} {resid}           {steps} {1e6 * step:7.0f} {1e6 * rec:8.0f} "
                  f"{1e3 * rec / scene.step:8.0f} {' '.join(f'{x:.2f}' for x in r['iterations']):>14}{ratio}")
    if not args.no_profile:
        body, scene, state, label = mid
        system = BodySystem(body, terms=scene.terms, rho_inf=scene.rho_inf, gravity=scene.gravity, backend="native")
        system.set_state(state)
        system.step(scene.step, sim.scene_inputs(body, scene))  # the runtime loaded before profiling
        inputs = sim.scene_inputs(body, scene)
        system.set_state(state)
        prof = cProfile.Profile()
        prof.enable()
        for _ in range(5 * args.steps):
            system.step(scene.step, inputs)
            sim.record(system)
        prof.disable()
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(15)
        t_mid = phases[len(phases) // 2]
        print(f"\ncProfile, native backend, {label}, {5 * args.steps} steps with recording from t = {t_mid:g} s (tottime):")
        print(out.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
