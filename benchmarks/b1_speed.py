"""B1 (Haug's rotating beam) standalone with 1, 2 and 4 superelements: speed and accuracy table.

    python benchmarks/b1_speed.py [--duration 20] [--profile]

Prints wall time, steps per second, real-time factor (simulated / wall seconds), Newton
iterations per step, the B1 metrics against the paper's Table 1, and each configuration's wall
time as a ratio to the 1-superelement run of the same invocation (the baseline), so the figures
compare across machines. --profile adds a cProfile summary of the 4-superelement run.
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
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args(argv)
    rows = []
    for n in (1, 2, 4):
        model = load_model(MODEL, [f"superelements={n}", f"duration={args.duration}"])
        if args.profile and n == 4:
            prof = cProfile.Profile()
            r = prof.runcall(sim.run_scene, model, "spinup")
        else:
            r = sim.run_scene(model, "spinup")
        s = r.summary
        rows.append((n, s))
    base = rows[0][1]["wall_time_s"]
    print(f"B1 spin-up, {args.duration:g} s simulated, h = 2 ms, rho_inf = 0.8, terms linear, 6 modes/SE")
    print(f"{'SE':>3} {'wall [s]':>9} {'steps/s':>8} {'RT factor':>9} {'vs 1 SE':>8} {'Newton/step':>11} "
          f"{'max defl [m]':>12} {'paper':>7} {'diff':>7} {'axial [m]':>10}")
    for n, s in rows:
        m = s["metrics"]
        d = m["tip_deflection_max_m"]
        print(f"{n:>3} {s['wall_time_s']:9.2f} {s['steps'] / s['wall_time_s']:8.0f} {s['real_time_factor']:9.2f} "
              f"{s['wall_time_s'] / base:8.2f} {s['newton_iterations_mean']:11.2f} {d:12.4f} {PAPER[n]:7.4f} "
              f"{100 * (d / PAPER[n] - 1):+6.2f}% {m['tip_axial_at_max_m']:10.4f}")
    if args.profile:
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(15)
        print(out.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
