"""Whole processes, as a user runs them: `ffrf-fmu simulate` of B1 against a Python process that builds
and solves Exudyn's 3D beam of B1 (the peer of benchmarks/peers.py), and the CLI's start-up.

    python benchmarks/cli_process.py [--repeat 7] [--ours-set superelements=1 ...] [--peer 4,0.04]

Ours: `python -m ffrf_fmu simulate models/haug_beam.toml` with 1 stiffened superelement at 40 ms (the
configuration of our B1 front near 0.5 % error), summary and CSV off. Peer: Exudyn's
ObjectBeamGeometricallyExact with 4 elements at 40 ms (ffrf_fmu/peers/exudyn_beam.py `simulate`;
needs the `peers` extra). The two run alternately, `--repeat` times each after one untimed run of each
(it compiles the C runtime and caches the reduced body when they are missing, and warms the disk
cache), each process timed from start to exit (wall, and the children's CPU from os.wait4); the table
gives min and median and the ratio ours/peer of the medians and of the pairs. The first, cold run of
ours (an empty cache directory: the C runtime compiled, the body reduced) is timed apart. Python's
bytecode cache is on for every process, as on a user's machine (PYTHONDONTWRITEBYTECODE, where the
environment sets it, is dropped): the untimed runs write it.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = str(ROOT / "models" / "haug_beam.toml")
PEER = """
from ffrf_fmu.model import load_model
from ffrf_fmu.peers.exudyn_beam import simulate
model = load_model({model!r})
scene = model.scene("spinup")
result = simulate(model.body, scene, {n}, {h})
"""


USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd, env=None) -> tuple[float, float, int]:
    """(wall, CPU of the process, exit code) of one whole process."""
    env = USER_ENV if env is None else env
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    return wall, usage.ru_utime + usage.ru_stime, os.waitstatus_to_exitcode(status)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--ours-set", nargs="*", default=["superelements=1", "stiffening=true", "step=0.04"])
    ap.add_argument("--peer", default="4,0.04", help="Exudyn's elements,step")
    args = ap.parse_args(argv)
    n, h = args.peer.split(",")
    ours = [sys.executable, "-m", "ffrf_fmu", "simulate", MODEL] + [w for s in args.ours_set for w in ("--set", s)]
    peer = [sys.executable, "-c", PEER.format(model=MODEL, n=int(n), h=float(h))]
    helpcmd = [sys.executable, "-m", "ffrf_fmu", "--help"]
    with tempfile.TemporaryDirectory() as cache:
        cold = timed(ours, {**USER_ENV, "FFRF_FMU_CACHE_DIR": cache})
    runs = {"ours": [], "peer": [], "help": []}
    for cmd in (ours, peer, helpcmd):
        if timed(cmd)[2] != 0:
            print(f"failed: {' '.join(cmd)}", file=sys.stderr)
            return 1
    for k in range(args.repeat):
        order = [("ours", ours), ("peer", peer), ("help", helpcmd)]
        for name, cmd in order if k % 2 == 0 else order[::-1]:
            runs[name].append(timed(cmd)[:2])
    print(f"whole processes, {args.repeat} runs each, alternating; load average {os.getloadavg()[0]:.2f}")
    print(f"  ours cold (empty cache: the C runtime compiles, the body is reduced): {cold[0]:.3f} s wall")
    for name, label in (("ours", f"ffrf-fmu simulate B1 {' '.join(args.ours_set)}"),
                        ("peer", f"Exudyn B1 {n} elements, h = {h} s"), ("help", "ffrf-fmu --help")):
        wall = [w for w, _ in runs[name]]
        cpu = [c for _, c in runs[name]]
        print(f"  {label:55s} wall min {min(wall):.3f} median {statistics.median(wall):.3f} s, "
              f"CPU median {statistics.median(cpu):.3f} s")
    pairs = [a[0] / b[0] for a, b in zip(runs["ours"], runs["peer"])]
    print(f"  ours / peer: median of walls {statistics.median(w for w, _ in runs['ours']) / statistics.median(w for w, _ in runs['peer']):.2f}, "
          f"pairs min {min(pairs):.2f} median {statistics.median(pairs):.2f} max {max(pairs):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
