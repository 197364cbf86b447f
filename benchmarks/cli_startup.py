"""Start-up of the command line: `ffrf-fmu --help` (as `python -m ffrf_fmu --help`) as a whole process,
median of N runs, beside the bare interpreter (`python -c pass`) on the same machine at the same time,
and which of the package's modules `--help` imports.

    python benchmarks/cli_startup.py [--runs 15]

The target (issue: start-up) is 0.15 s for the whole process. The interpreter's own start (its site
packages' .pth files included) is part of it and not the package's: the difference of the two
medians is what the package costs. The machine load is printed with the figures: on a loaded
machine both grow.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def wall(cmd: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env={**os.environ, "PYTHONPATH": str(ROOT)})
    return time.perf_counter() - start


def imported_modules(args: list[str]) -> list[str]:
    """The ffrf_fmu modules and the heavy third-party packages that `python -m ffrf_fmu ARGS` imports."""
    code = ("import sys, runpy\nsys.argv = ['ffrf-fmu', *sys.argv[1:]]\n"
            "try:\n    runpy.run_module('ffrf_fmu', run_name='__main__')\nexcept SystemExit:\n    pass\n"
            "heavy = ('numpy', 'scipy', 'matplotlib', 'dask', 'fmpy', 'pythonfmu', 'numba')\n"
            "mods = sorted(m for m in sys.modules if m.startswith('ffrf_fmu') or m in heavy)\n"
            "print('\\n'.join(mods), file=sys.stderr)\n")
    out = subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    return out.stderr.split()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args()
    help_cmd = [sys.executable, "-m", "ffrf_fmu", "--help"]
    bare_cmd = [sys.executable, "-c", "pass"]
    wall(help_cmd), wall(bare_cmd)  # warm the file cache
    helps, bares = [], []
    for _ in range(args.runs):  # interleaved: both see the same load
        helps.append(wall(help_cmd))
        bares.append(wall(bare_cmd))
    h, b = statistics.median(helps), statistics.median(bares)
    print(f"load average {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores, {args.runs} runs each")
    print(f"ffrf-fmu --help   median {h:.3f} s  (min {min(helps):.3f}, max {max(helps):.3f})")
    print(f"python -c pass    median {b:.3f} s  (min {min(bares):.3f}, max {max(bares):.3f})")
    print(f"the package's share: {h - b:.3f} s")
    print("imported by --help:", " ".join(imported_modules(["--help"])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
