"""Newton on B1 (Haug's rotating beam spin-up), before and after: residual evaluations, Jacobians and
factorizations per step, CPU time, and the maximum tip deflection, for a baseline revision of the
runtime and the working tree, in one run.

    python benchmarks/newton_iterations.py [--baseline 585668d] [--steps 0.002,0.01,0.02,0.04,0.05]
                                           [--configs 1x2,4x6] [--refresh-after 2:3] [--duration 20]
                                           [--repeats 3]

The baseline is exported with `git archive` into a temporary directory; every run is a subprocess
that imports either tree, so both run the same scene with their own integrator. Counts come from a
numpy-backend run with the integrator's `_residual_at` and `_factor` wrapped (the native backend
makes the same decisions, tests/test_backends.py): an evaluation is one residual (with or without
the Jacobian), so it is the honest count of Newton iterations whatever either tree calls an
iteration (the baseline evaluated the accepted iterate once more after its last solve). Time is
the CPU time of a native-backend `simulate.run` of the reduced body (steps and per-step recording;
the kernel loaded by a short run before), the best of --repeats runs, one BLAS thread: CPU time,
because on the shared 2-core machine wall times swing by 2x. --refresh-after runs the working
tree once per value lo:hi of `GeneralizedAlpha.REFRESH_AFTER` (the Jacobian is rebuilt at the
predictor when the last step took lo to hi iterations; 3:99, 2:99 are the rules "after 3 or more",
"after 2 or more"). Ratios are working tree / baseline, measured in this run.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def worker(tree: str, h: float, cfg: str, refresh_after: tuple[int, int] | None, duration: float, repeats: int) -> dict:
    """One configuration in one tree (run in a subprocess whose sys.path starts with the tree)."""
    import dataclasses
    import warnings

    sys.path.insert(0, tree)
    from ffrf_fmu import simulate as sim
    from ffrf_fmu.model import load_model
    from ffrf_fmu.reduction import reduce_body, reduction_options
    from ffrf_fmu.runtime.integrator import GeneralizedAlpha

    if refresh_after is not None:
        GeneralizedAlpha.REFRESH_AFTER = refresh_after
    n_se, modes = cfg.split("x")
    model = load_model(str(Path(tree) / "models" / "haug_beam.toml"),
                       [f"superelements={n_se}", f"modes={modes}", f"step={h}", f"duration={duration}"])
    scene = model.scene("spinup")
    try:  # the scene's causality on the ports: model.scene_body now, simulate.effective_ports in older trees
        from ffrf_fmu.model import scene_body
        scened = scene_body(model.body, scene)
    except ImportError:
        scened = dataclasses.replace(model.body, ports=sim.effective_ports(model, scene))
    body = reduce_body(scened, **reduction_options(scene)).data
    counts = {"evaluations": 0, "jacobians": 0, "factorizations": 0}
    residual_at, factor = GeneralizedAlpha._residual_at, GeneralizedAlpha._factor

    def counted_residual(self, yd, jacobian=False, beta=None):
        counts["evaluations"] += 1
        counts["jacobians"] += bool(jacobian)
        return residual_at(self, yd, jacobian, beta)

    def counted_factor(self, *args):
        counts["factorizations"] += 1
        return factor(self, *args)

    def run(sc, backend):
        return sim.run(body, sc, origin=model.body.origin, progress=False, backend=backend)

    GeneralizedAlpha._residual_at, GeneralizedAlpha._factor = counted_residual, counted_factor
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = run(scene, "numpy")
        GeneralizedAlpha._residual_at, GeneralizedAlpha._factor = residual_at, factor
        # the kernel compiles or loads from its disk cache at the first call of a process: a short run first
        run(dataclasses.replace(scene, duration=3 * h), "native")
        cpus, walls, fast = [], [], None
        for _ in range(repeats):
            c0 = time.process_time()
            fast = run(scene, "native")
            cpus.append(time.process_time() - c0)
            walls.append(fast.summary["wall_time_s"])
    s, steps = ref.summary, max(ref.summary["steps"], 1)
    return {
        "evaluations": counts["evaluations"] / steps, "jacobians": counts["jacobians"] / steps,
        "factorizations": counts["factorizations"] / steps, "reported": s["newton_iterations_mean"],
        "failure": s["failure"], "t_end": s["t_end"], "tip": s["metrics"].get("tip_deflection_max_m"),
        "wall_native": min(walls), "cpu_native": min(cpus), "backend": fast.summary["backend"], "failure_native": fast.summary["failure"],
        "tip_native": fast.summary["metrics"].get("tip_deflection_max_m"),
    }


def run_worker(tree, h, cfg, refresh_after, duration, repeats) -> dict:
    cmd = [sys.executable, __file__, "--worker", tree, str(h), cfg, str(refresh_after), str(duration), str(repeats)]
    out = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": tree})
    if out.returncode != 0:
        raise RuntimeError(f"worker failed ({tree}, {h}, {cfg}):\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def export(rev: str, into: str) -> str:
    """The runtime and models of revision rev, as files under `into`."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "ffrf_fmu", "models"], capture_output=True, check=True)
    path = Path(into) / "baseline.tar"
    path.write_bytes(archive.stdout)
    with tarfile.open(path) as tar:
        tar.extractall(into, filter="data")
    return into


def main(argv=None) -> int:
    if argv is None and len(sys.argv) > 1 and sys.argv[1] == "--worker":
        tree, h, cfg, ra, duration, repeats = sys.argv[2:8]
        rule = None if ra == "None" else tuple(int(k) for k in ra.split(":"))
        print(json.dumps(worker(tree, float(h), cfg, rule, float(duration), int(repeats))))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="585668d", help="git revision of the baseline runtime (default: the solver before the co-rotated predictor)")
    ap.add_argument("--steps", default="0.002,0.01,0.02,0.04,0.05")
    ap.add_argument("--configs", default="1x2,4x6", help="superelements x modes")
    ap.add_argument("--refresh-after", default="2:3", help="rules lo:hi of REFRESH_AFTER for the working tree")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    policies = args.refresh_after.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        base = export(args.baseline, tmp)
        print(f"B1 spin-up {args.duration:g} s; per step: residual evaluations / Jacobians / factorizations (numpy "
              f"counts); native CPU [s] (best of {args.repeats}); max tip deflection [m]; ratios working tree / "
              f"baseline {args.baseline}")
        for h in (float(x) for x in args.steps.split(",")):
            for cfg in args.configs.split(","):
                b = run_worker(base, h, cfg, None, args.duration, args.repeats)
                rows = [("baseline", b)] + [(f"REFRESH_AFTER={ra}", run_worker(str(ROOT), h, cfg, ra, args.duration,
                                                                               args.repeats)) for ra in policies]
                for name, r in rows:
                    fail = f"  FAILED at t = {r['t_end']:.2f} s: {r['failure']}" if r["failure"] else ""
                    ratio = "" if r is b else (f"  evals x{r['evaluations'] / b['evaluations']:.2f}  CPU "
                                               f"x{r['cpu_native'] / b['cpu_native']:.2f}  tip {(r['tip'] - b['tip']) / b['tip']:+.1e}"
                                               if not (r["failure"] or b["failure"]) else "")
                    print(f"{1e3 * h:5g} ms {cfg:>4} {name:>16}: {r['evaluations']:5.2f} / {r['jacobians']:4.2f} / "
                          f"{r['factorizations']:4.2f}  CPU {r['cpu_native']:6.3f}  tip {r['tip']:.9f}{ratio}{fail}",
                          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
