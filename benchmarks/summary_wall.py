"""The run a user makes: `ffrf-fmu simulate MODEL --summary` of B1 in a fresh process, its summary's
wall_time_s (set-up, steps and recording), setup_time_s, load_time_s (the reduced body from its cache,
before wall_time_s) and metrics_time_s (after it), best of N.

    python benchmarks/summary_wall.py [--repeat 5] [--config "superelements=1 modes=2 stiffening=true step=0.04" ...]
                                      [--checkout DIR ...] [--phases]

Each configuration (default: issue 32's, below) runs once untimed (the C runtime compiled and the body
reduced into the cache when missing, the bytecode written), then `--repeat` times, the configurations
interleaved round by round so that a burst of the machine's load falls on all of them. Python's bytecode
cache is on (PYTHONDONTWRITEBYTECODE dropped, as on a user's machine). Per configuration: steps, the best
(minimum) and median of wall_time_s, setup_time_s, load_time_s and metrics_time_s, and wall_time_s /
steps, the per-step figure as the summary reports it (recording included). Best of N: on a shared machine the noise only adds.
--checkout (repeatable) runs the package of each checkout given (A/B against another commit, interleaved
with this one's runs; its bytecode cached under a temporary prefix, not written into that checkout) and
prints the ratio of its best times over this checkout's, per configuration.
--phases runs the same command with the pieces of its run timed (PHASES: the functions of the run
wrapped in the child process, before the CLI is imported; any checkout), and prints their best of N:
the body from the cache (body_cache.scene_body_data), BodySystem(), of it the C body (NativeStep) and of
that the library's lookup (build.library_path, or build.library where there is none), its load (ctypes.CDLL), the image (body_image) and the array
views (NativeBody.array), the damping's modal basis (damping.body_basis; 0 where not computed),
initialize, the steps (run_schedule, all chunks), the metrics, of them the dominant frequency's grid
(TrendFit.grid_scores), and wall_time_s less the steps (what the summary counts outside the steps).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = str(ROOT / "models" / "haug_beam.toml")
CONFIGS = ("superelements=1 modes=2 stiffening=true step=0.04",
           "superelements=1 modes=2 stiffening=true step=0.01",
           "superelements=1 modes=2 step=0.002",
           "superelements=4 modes=6 step=0.002",
           "superelements=8 modes=2 step=0.002")
USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
KEYS = ("wall_time_s", "setup_time_s", "load_time_s", "metrics_time_s")


# the CLI run of `--phases`: the run's functions wrapped with timers (their sum over the run, into the file
# argv[1]), then `ffrf-fmu ARGS` as `python -m ffrf_fmu ARGS` runs it
PHASES = """
import json, runpy, sys, time
out, sys.argv = sys.argv[1], ["ffrf-fmu", *sys.argv[2:]]
T = {}
def timer(owner, name, key):
    f = getattr(owner, name)
    def timed(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            T[key] = T.get(key, 0.0) + time.perf_counter() - t
    setattr(owner, name, timed)
import ctypes
from ffrf_fmu import body_cache
from ffrf_fmu.runtime import body
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.runtime.native import binding, build
from ffrf_fmu.simulate import frequency, loop
for owner, name, key in ((body_cache, "scene_body_data", "load"), (BodySystem, "__init__", "BodySystem()"),
                         (binding.NativeStep, "__init__", "C body"),
                         (build, "library_path" if hasattr(build, "library_path") else "library", "library lookup"),
                         (ctypes.CDLL, "__init__", "ctypes.CDLL"), (binding, "body_image", "image"),
                         (binding.NativeBody, "array", "array views"), (body, "body_basis", "damping basis"),
                         (BodySystem, "initialize", "initialize"), (BodySystem, "run_schedule", "steps"),
                         (loop, "metrics", "metrics"), (frequency.TrendFit, "grid_scores", "frequency grid")):
    timer(owner, name, key)
try:
    runpy.run_module("ffrf_fmu", run_name="__main__")
except SystemExit:
    pass
with open(out, "w") as fh:
    json.dump(T, fh)
"""
PHASE_KEYS = ("load", "BodySystem()", "C body", "library lookup", "ctypes.CDLL", "image", "array views", "damping basis",
              "initialize", "metrics", "frequency grid", "steps")


def run(config: str, out: Path, checkout: Path = ROOT, pycache: str | None = None, phases: bool = False) -> dict:
    """The summary of one fresh `ffrf-fmu simulate` run; with `phases` (PHASES) its pieces' times under "phases"."""
    sets = [w for kv in config.split() for w in ("--set", kv)]
    env = dict(USER_ENV, PYTHONPATH=str(checkout))
    if pycache:
        env["PYTHONPYCACHEPREFIX"] = pycache
    head = [sys.executable, "-c", PHASES, str(out) + ".phases"] if phases else [sys.executable, "-m", "ffrf_fmu"]
    subprocess.run([*head, "simulate", MODEL, "--scene", "spinup", *sets, "--summary", str(out)],
                   check=True, capture_output=True, env=env, cwd=checkout)
    summary = json.loads(out.read_text())
    if phases:
        summary["phases"] = json.loads(Path(str(out) + ".phases").read_text())
    return summary


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--config", action="append", help="KEY=V words of one configuration (repeatable)")
    ap.add_argument("--checkout", action="append", type=Path, help="a checkout to run besides this one (repeatable)")
    ap.add_argument("--phases", action="store_true", help="time the pieces of each run (PHASES) and print them")
    args = ap.parse_args(argv)
    checkouts = [ROOT] + [c.resolve() for c in args.checkout or []]
    jobs = [(k, c) for k in checkouts for c in args.config or CONFIGS]
    runs: dict[tuple, list[dict]] = {j: [] for j in jobs}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp, "summary.json")
        pycache = {k: None if k == ROOT else str(Path(tmp, f"pycache{i}")) for i, k in enumerate(checkouts)}
        for k, c in jobs:
            run(c, out, k, pycache[k], args.phases)  # untimed
        for r in range(args.repeat):
            for k, c in jobs if r % 2 == 0 else jobs[::-1]:
                runs[k, c].append(run(c, out, k, pycache[k], args.phases))
    print(f"B1 spin-up 20 s, `ffrf-fmu simulate --summary`, fresh process each, best of {args.repeat} "
          f"(median in brackets); load average {os.getloadavg()[0]:.2f}")
    print(f"{'configuration':48s} {'steps':>6s} {'wall_time_s [ms]':>18s} {'setup [ms]':>14s} {'load [ms]':>14s} "
          f"{'metrics [ms]':>14s} {'per step [us]':>14s}")
    for (k, c), rs in runs.items():
        if len(checkouts) > 1:
            c = f"{k.name}: {c}"
        cols = []
        for key in KEYS:
            vals = [s.get(key) for s in rs if s.get(key) is not None]
            cols.append(f"{1e3 * min(vals):7.2f} ({1e3 * statistics.median(vals):6.2f})" if vals else "-")
        steps = rs[0]["steps"]
        per = 1e6 * min(s["wall_time_s"] for s in rs) / steps
        print(f"{c:48s} {steps:6d} {cols[0]:>18s} {cols[1]:>14s} {cols[2]:>14s} {cols[3]:>14s} {per:14.1f}")
    if args.phases:  # a row per piece, a column per configuration (and checkout)
        print(f"pieces of the same runs [ms], best of {args.repeat} (median); outside the steps: wall_time_s - steps")
        for j, (k, c) in enumerate(runs):
            print(f"  [{j}] {k.name + ': ' if len(checkouts) > 1 else ''}{c}")
        print(f"{'piece':20s}" + "".join(f"{f'[{j}]':>20s}" for j in range(len(runs))))
        for key in (*PHASE_KEYS, "outside the steps"):
            cells = []
            for rs in runs.values():
                v = [s["wall_time_s"] - s["phases"].get("steps", 0.0) if key == "outside the steps"
                     else s["phases"].get(key, 0.0) for s in rs]
                cells.append(f"{1e3 * min(v):8.3f} ({1e3 * statistics.median(v):7.3f})")
            print(f"{key:20s}" + "".join(f"{cell:>20s}" for cell in cells))
    for k in checkouts[1:]:  # the baseline ratios, of the same run's best times
        for c in args.config or CONFIGS:
            ratio = {key: min(s[key] for s in runs[k, c]) / min(s[key] for s in runs[ROOT, c])
                     for key in KEYS if all(key in s for s in runs[k, c] + runs[ROOT, c])}
            print(f"{k.name} / {ROOT.name}: {c}: " + ", ".join(f"{key} {v:.3f}" for key, v in ratio.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
