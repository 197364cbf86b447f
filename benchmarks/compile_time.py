"""First use of the numba kernel from an empty disk cache, per path (issue 10, compile time).

    python benchmarks/compile_time.py [--paths standalone,fmu,step] [--steps 300] [--no-load] [--nested]

Each path runs in a fresh process with an empty kernel cache (FFRF_FMU_CACHE_DIR a new temporary
directory), on B1 (models/haug_beam.toml, scene spinup, 1 superelement x 2 modes: the compiled code
does not depend on the sizes):

- standalone: simulate.run over --steps steps (what `ffrf-fmu simulate` does: `_record` of the initial
  state, the first step through `step` checked against numpy, then the scheduled steps in one call);
- fmu: what an FMU's doSteps do with the body (in this process, no FMI host): the output row at
  initialization, then one run_held per communication step of h with the scene's inputs held at its
  start (the first doStep checked on numpy through `step`, the others in one kernel call each);
- step: BodySystem.step --steps times (runtime/compiled.py CompiledStep.step).

Prints per path: the first-use seconds the body reports (CompiledStep.compile_seconds, wall; and its
CPU), the seconds of each kernel entry point numba compiled (numba's compile events, top level only:
an entry point's callees are nested in it), the seconds numba held its LLVM lock (optimization and
machine code), the process's wall and CPU for the whole path, and the load average before and after.
Unless --no-load, a second fresh process per path runs the same path on the cache the first left: it
should load (0 cache misses) and its first-use seconds are the load time. --nested also lists every
function numba compiled, indented under its caller: seconds with its callees, without them, and its
own seconds under the LLVM lock (where a function's library is optimized and emitted with its callees
linked in, so a deep chain of separately compiled functions optimizes the deepest code many times).

Load average and other processes change the figures several-fold on a shared machine: compare only
runs made side by side (docs/benchmarks.md, compile section).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODEL = HERE.parent / "models" / "haug_beam.toml"

CHILD = r"""
import dataclasses, json, os, sys, time
t_start, c_start = time.perf_counter(), time.process_time()
sys.path.insert(0, {root!r})
import numpy as np
from numba.core import event
from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import build_scene_body
from ffrf_fmu.runtime import held

path, steps = {path!r}, {steps}
model = load_model({model!r}, ["superelements=1", "modes=2"])
scene = model.scene("spinup")
body, _ = build_scene_body(model.body, scene)


class Spans(event.Listener):
    # (name, seconds) of each top-level event of a kind (nested ones are inside their caller's); with
    # `inner`, every compile as (depth, name, seconds, without callees, own LLVM-lock seconds)
    def __init__(self, inner=None):
        self.depth, self.spans, self.stack, self.inner, self.all = 0, [], [], inner, []

    def on_start(self, ev):
        if self.depth == 0:
            self.t0 = time.perf_counter()
        self.depth += 1
        self.stack.append([time.perf_counter(), 0.0, self.inner.total() if self.inner else 0.0, 0.0])

    def on_end(self, ev):
        self.depth -= 1
        d = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        name = getattr(getattr(d, "py_func", None), "__name__", "?")
        t0, child, llvm0, child_llvm = self.stack.pop()
        dt = time.perf_counter() - t0
        llvm = self.inner.total() - llvm0 if self.inner else 0.0
        if self.stack:
            self.stack[-1][1] += dt
            self.stack[-1][3] += llvm
        if self.inner is not None and name != "impl":  # (numba's own overloads: impl)
            self.all.append((self.depth, name, dt, dt - child, llvm - child_llvm))
        if self.depth == 0:
            self.spans.append((name, time.perf_counter() - self.t0))

    def total(self):
        return sum(s for _, s in self.spans) + (time.perf_counter() - self.t0 if self.depth else 0.0)


llvm = Spans()
compiles = Spans(inner=llvm)
t0, c0 = time.perf_counter(), time.process_time()
with event.install_listener("numba:compile", compiles), event.install_listener("numba:llvm_lock", llvm):
    if path == "standalone":
        scene = dataclasses.replace(scene, duration=steps * scene.step)
        result = sim.run(body, scene, progress=False, backend="numba")
        system_c = None
        out = result.summary
        first, first_cpu, compiled = out["compile_time_s"], None, out["kernel_compiled"]
        rows = np.column_stack(list(result.columns.values()))
    else:
        system, inputs = sim.build_system(body, scene, backend="numba")
        h = scene.step
        rows = [system.output_row()]
        if path == "fmu":
            row = np.empty(rows[0].size)
            for k in range(steps):
                t_c = system.t
                system.run_held(h, 1, t_c, held.rows(body.ports, inputs(t_c)), row)
                rows.append(row.copy())
        else:
            for k in range(steps):
                system.step(h, inputs)
                rows.append(system.output_row())
        rows = np.array(rows)
        c = system._compiled
        first, first_cpu, compiled = c.compile_seconds, c.compile_cpu_seconds, c.compiled
print(json.dumps(dict(first=first, first_cpu=first_cpu, compiled=compiled,
                      entry=compiles.spans, nested=compiles.all, llvm=sum(s for _, s in llvm.spans),
                      wall=time.perf_counter() - t0, cpu=time.process_time() - c0,
                      process_wall=time.perf_counter() - t_start, process_cpu=time.process_time() - c_start,
                      finite=bool(np.isfinite(rows).all()), steps=len(rows) - 1)))
"""


def run_path(path: str, steps: int, cache: str) -> dict:
    code = CHILD.format(root=str(HERE.parent), model=str(MODEL), path=path, steps=steps)
    env = {**os.environ, "FFRF_FMU_CACHE_DIR": cache, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    load0 = os.getloadavg()[0]
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{path}: the child failed:\n{out.stderr}")
    res = json.loads(out.stdout.strip().splitlines()[-1])
    res["load"] = (load0, os.getloadavg()[0])
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--paths", default="standalone,fmu,step")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--no-load", action="store_true", help="skip the second process on the cache the first left")
    ap.add_argument("--nested", action="store_true", help="list every compiled function under its caller")
    args = ap.parse_args()
    for path in args.paths.split(","):
        with tempfile.TemporaryDirectory(prefix="ffrf-compile-") as cache:
            runs = [("empty cache", run_path(path, args.steps, cache))]
            if not args.no_load:
                runs.append(("second process", run_path(path, args.steps, cache)))
        for label, r in runs:
            entry = ", ".join(f"{name} {s:.1f} s" for name, s in r["entry"]) or "none"
            cpu = f" / {r['first_cpu']:.1f} s CPU" if r["first_cpu"] is not None else ""
            print(f"{path:10s} {label:14s} first use {r['first']:.2f} s{cpu} ({'compiled' if r['compiled'] else 'loaded'}); "
                  f"compiled: {entry}; LLVM lock {r['llvm']:.1f} s; whole path {r['wall']:.1f} s wall / {r['cpu']:.1f} s CPU; "
                  f"{r['steps']} steps, finite {r['finite']}; load average {r['load'][0]:.2f} -> {r['load'][1]:.2f}", flush=True)
            if args.nested and r["nested"]:
                # numba reports a callee's end before its caller's: print in reverse, callers first
                for depth, name, dt, own, own_llvm in reversed(r["nested"]):
                    print(f"    {'  ' * depth}{name:24s} {dt:6.1f} s, without callees {own:6.1f} s, LLVM lock {own_llvm:5.1f} s")


if __name__ == "__main__":
    main()
