"""B1 (Haug's rotating beam) standalone with 1, 2 and 4 superelements: speed and accuracy table.

    python benchmarks/b1_speed.py [--duration 20] [--modes 6] [--backend native|numpy|both] [--profile]

Prints wall time, steps per second, real-time factor (simulated / wall seconds), Newton
iterations per step, the B1 metrics against the paper's Table 1, and each configuration's wall
time as a ratio to the 1-superelement run of the same invocation (the baseline), so the figures
compare across machines. --backend both (the default) runs every configuration on both backends
and adds the numpy/native wall-time ratio; a short native run before the table loads (or compiles) the
C runtime, so no timed run pays it; the CPU time column (this process's CPU seconds) is steadier than
wall time on a shared machine.
--profile adds a cProfile summary of the 4-superelement run.
"""
from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
from pathlib import Path

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model

MODEL = Path(__file__).resolve().parents[1] / "models" / "haug_beam.toml"
PAPER = {1: 0.6015, 2: 0.5520, 4: 0.5386}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--modes", type=int, default=6)
    ap.add_argument("--backend", choices=("native", "numpy", "both"), default="both")
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args(argv)
    backends = ("numpy", "native") if args.backend == "both" else (args.backend,)
    rows = []
    if "native" in backends:  # compile or load the C runtime before the timed runs
        sim.run_scene(load_model(MODEL, ["duration=0.02", f"modes={args.modes}"]), "spinup", backend="native")
    for n in (1, 2, 4):
        model = load_model(MODEL, [f"superelements={n}", f"duration={args.duration}", f"modes={args.modes}"])
        for backend in backends:
            if args.profile and n == 4:
                prof = cProfile.Profile()
                r = prof.runcall(sim.run_scene, model, "spinup", backend=backend)
            else:
                r = sim.run_scene(model, "spinup", backend=backend)
            rows.append((n, backend, r.summary))
    base = rows[0][2]["wall_time_s"]
    print(f"B1 spin-up, {args.duration:g} s simulated, h = 2 ms, rho_inf = 0.8, terms linear, {args.modes} modes/SE")
    print(f"{'SE':>3} {'backend':>7} {'wall [s]':>9} {'CPU [s]':>8} {'steps/s':>8} {'RT factor':>9} {'vs first':>8} {'numpy/this':>10} "
          f"{'Newton/step':>11} {'max defl [m]':>12} {'paper':>7} {'diff':>7} {'axial [m]':>10}")
    walls = {(n, b): s["wall_time_s"] for n, b, s in rows}
    for n, backend, s in rows:
        m = s["metrics"]
        d = m["tip_deflection_max_m"]
        ratio = walls.get((n, "numpy"), float("nan")) / s["wall_time_s"]
        print(f"{n:>3} {backend:>7} {s['wall_time_s']:9.2f} {s['cpu_time_s']:8.2f} {s['steps'] / s['wall_time_s']:8.0f} {s['real_time_factor']:9.2f} "
              f"{s['wall_time_s'] / base:8.2f} {ratio:10.1f} {s['newton_iterations_mean']:11.2f} {d:12.4f} {PAPER[n]:7.4f} "
              f"{100 * (d / PAPER[n] - 1):+6.2f}% {m['tip_axial_at_max_m']:10.4f}")
    if args.profile:
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(15)
        print(out.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
