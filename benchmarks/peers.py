#!/usr/bin/env python3
"""Benchmark: our superelement chains against Exudyn's full-order 3D beam on B1, in ONE run.

    python benchmarks/peers.py [--quick] [--backend numba|numpy] [-o DIR] [--set KEY=V ...] [--sweep KEY=V1,V2 ...]
                               [--peer-sweep ...]

B1 (models/haug_beam.toml, scene spinup: Haug's rotating beam, 20 s, rho_inf 0.8). Runs, one
after another in this process (one core; BLAS and Exudyn pinned to one thread):
- ours over superelements x modes x steps (OURS, or `--sweep` groups): the linear chain and the
  chain with geometric stiffening (`stiffening=true`), with `--backend` (default numba; it falls
  back to numpy, with a note, for what its kernel lacks; the table says which ran). `--set` applies
  to every run;
- Exudyn's ObjectBeamGeometricallyExact (ffrf_fmu/peers/exudyn_beam.py: the same section, the
  same spin-up prescribed at the hub, generalized-alpha with the same rho_inf) over elements
  {2, 3, 4, 6, 8, 16} x steps {2, 5, 10, 20, 40} ms;
- the converged reference: the in-house full-order beam (ffrf_fmu/reference) with
  --reference-elements (default 64) at 2 ms, kept in DIR's result store as `ffrf-fmu chart` keeps it.

Prints and writes (DIR/peers.md, DIR/peers.json, DIR/chart.csv, DIR/chart.png):
- every run's error of the maximum transverse tip deflection against the reference, its wall and
  CPU time (time stepping only) and Newton iterations;
- the agreement of Exudyn's converged value with the reference: Exudyn at --check-elements
  (default 16 and 32) at 2 ms and their Richardson extrapolation (the element converges as 1/n^2)
  against the reference's 64 elements;
- the ratio of the two Pareto fronts at equal error: Exudyn's cost / ours, both fronts
  interpolated in log-log (chart.front_cost_at), at 0.2 %, 1 %, 5 % and between, for wall and CPU
  time. Above 1, ours is cheaper.

Without exudyn (the optional extra `peers`: pip install -e ".[peers]") it says so and exits 0.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # one core against one core
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ffrf_fmu.studies import chart as ch  # noqa: E402
from ffrf_fmu.studies.grid import parse_values  # noqa: E402
from ffrf_fmu.studies.runners import run_configuration  # noqa: E402
from ffrf_fmu.peers import available  # noqa: E402

STEPS = ["0.002", "0.005", "0.01", "0.02", "0.04"]
OURS = [  # superelements x modes x steps: the linear chain (its chain error falls as 1/N^2, 12 SE ~0.1 %) ...
    {"superelements": ["1", "2", "3", "4", "6", "8"], "modes": ["2", "6"], "step": STEPS},
    {"superelements": ["12"], "modes": ["2"], "step": STEPS},
    # ... and with geometric stiffening inside each superelement (docs/equations.md; few SE suffice)
    {"superelements": ["1", "2", "3", "4"], "modes": ["2"], "step": STEPS, "stiffening": ["true"]},
]
QUICK_OURS = [{"superelements": ["2", "4"], "modes": ["2"], "step": ["0.04"]}]
QUICK_PEER = {"elements": ["4", "8"], "step": ["0.04"]}
LEVELS = (0.002, 0.005, 0.01, 0.02, 0.05)  # error levels of the front ratio (issue 10: 0.2 % to 5 %)
METRIC = "tip_deflection_max_m"  # B1's primary metric (models/haug_beam.toml [scenes.spinup.metrics])


def warm_up(model_path, scene, overrides, backend) -> None:
    """A short run of each code first (not timed): the numba kernel is compiled or loaded from its disk
    cache, Exudyn and the modules imported, so no configuration pays that in its time."""
    from ffrf_fmu.peers.exudyn_beam import run_configuration as run_peer

    run_configuration(model_path, scene, list(overrides) + ["duration=0.04"], {}, "standalone", backend)
    run_peer(model_path, scene, list(overrides) + ["duration=0.04"], {"elements": 2, "step": 0.02})


def front(rows, runner, cost_key):
    sel = [r for r in rows if r["runner"] == runner and r["completed"] and r["metric_error_rel"] is not None
           and r[cost_key]]
    idx = ch.pareto_front([r[cost_key] for r in sel], [r["metric_error_rel"] for r in sel])
    return [sel[i] for i in idx]


def front_ratios(rows, peer, levels=LEVELS) -> list[dict]:
    """Per error level and cost measure: our front's cost, the peer front's, and peer / ours."""
    out = []
    for level in levels:
        row = {"error": level}
        for cost, key in ch.COSTS.items():
            costs = {}
            for who in ("standalone", peer):
                f = front(rows, who, key)
                costs[who] = ch.front_cost_at([r[key] for r in f], [r["metric_error_rel"] for r in f], level)
            row[f"ours_{cost}_s"], row[f"peer_{cost}_s"] = costs["standalone"], costs[peer]
            row[f"ratio_{cost}"] = (costs[peer] / costs["standalone"]) if None not in costs.values() else None
        out.append(row)
    return out


def convergence_check(model_path, scene, overrides, elements, rows, reference) -> dict:
    """Exudyn at 2 ms with `elements` (taken from the sweep's rows when there, else run) and the
    Richardson extrapolation of the two finest (1/n^2) against the reference's maximum deflection."""
    from ffrf_fmu.peers.exudyn_beam import run_configuration

    metric = METRIC
    values = {}
    for n in elements:
        hit = [r for r in rows if r["runner"] == "exudyn" and r.get("elements") == n and abs(r["step"] - 0.002) < 1e-12
               and r["completed"]]
        if hit:
            values[n] = {"metric": hit[0]["metric"], "wall_time_s": hit[0]["wall_time_s"], "from": "sweep"}
        else:
            run = run_configuration(model_path, scene, overrides, {"elements": n, "step": 0.002})
            if not run["completed"]:
                values[n] = {"failure": run["failure"]}
                continue
            values[n] = {"metric": run["metrics"][metric], "wall_time_s": run["wall_time_s"], "from": "run"}
    ref = reference["metrics"][metric]
    out = {"reference": ref, "reference_elements": reference["n_elements"], "exudyn": values}
    done = sorted(n for n in values if "metric" in values[n])
    for n in done:
        values[n]["difference_rel"] = (values[n]["metric"] - ref) / ref
    if len(done) >= 2:
        n1, n2 = done[-2], done[-1]
        m1, m2 = values[n1]["metric"], values[n2]["metric"]
        ext = m2 + (m2 - m1) / ((n2 / n1) ** 2 - 1)
        out["exudyn_extrapolated"] = {"from_elements": [n1, n2], "metric": ext, "difference_rel": (ext - ref) / ref}
    return out


def _f(v, fmt, none="–"):
    return format(v, fmt) if v is not None and not (isinstance(v, float) and math.isnan(v)) else none


def markdown(rows, ratios, check, meta) -> str:
    lines = ["| code | configuration | wall [s] | CPU [s] | Newton it./step | max deflection [m] | error | front | backend |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (r["runner"] != "exudyn", r["label"])):
        who = "Exudyn" if r["runner"] == "exudyn" else "ours"
        status = "" if r["completed"] else f" (failed at t = {_f(r['t_end_s'], '.3g')} s)"
        lines.append(f"| {who} | {r['label']}{status} | {_f(r['wall_time_s'], '.2f')} | {_f(r['cpu_time_s'], '.2f')} | "
                     f"{_f(r.get('newton_iterations_mean'), '.2f')} | {_f(r['metric'], '.5f')} | "
                     f"{_f(r['metric_error_rel'], '.3%')} | {'*' if r.get('pareto') else ''} | "
                     f"{r.get('backend') or ('C++' if r['runner'] == 'exudyn' else '')} |")
    lines += ["", "| error | ours: wall / CPU [s] | Exudyn: wall / CPU [s] | Exudyn / ours (wall) | Exudyn / ours (CPU) |",
              "|---|---|---|---|---|"]
    for q in ratios:
        lines.append(f"| {q['error']:.1%} | {_f(q['ours_wall_s'], '.3g')} / {_f(q['ours_cpu_s'], '.3g')} | "
                     f"{_f(q['peer_wall_s'], '.3g')} / {_f(q['peer_cpu_s'], '.3g')} | "
                     f"{_f(q['ratio_wall'], '.2f', 'not reached')} | {_f(q['ratio_cpu'], '.2f', 'not reached')} |")
    if check:
        lines += ["", f"Converged value: reference ({check['reference_elements']} elements, 2 ms) "
                  f"{check['reference']:.6f} m; Exudyn at 2 ms: "
                  + ", ".join(f"{n} el. {v['metric']:.6f} m ({v['difference_rel']:+.4%})" if "metric" in v
                              else f"{n} el. failed" for n, v in check["exudyn"].items())]
        if "exudyn_extrapolated" in check:
            e = check["exudyn_extrapolated"]
            lines[-1] += (f"; Richardson extrapolation of {e['from_elements'][0]} and {e['from_elements'][1]} el. "
                          f"{e['metric']:.6f} m ({e['difference_rel']:+.4%}).")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "models" / "haug_beam.toml"))
    ap.add_argument("--scene", default="spinup")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=V",
                    help="override for every run (ours and the peer's model/scene), e.g. terms=linear")
    ap.add_argument("--sweep", nargs="+", action="append", metavar="KEY=V1,V2", help="our sweep (default OURS)")
    ap.add_argument("--peer-sweep", nargs="+", metavar="KEY=V1,V2", help="Exudyn's (default chart.PEER_SWEEP)")
    ap.add_argument("--reference-elements", type=int, default=64)
    ap.add_argument("--check-elements", default="16,32", help="Exudyn meshes at 2 ms for the convergence check")
    ap.add_argument("--backend", choices=("numba", "numpy"), default="numba",
                    help="our runtime backend (numba falls back to numpy, with a note, for what its kernel lacks)")
    ap.add_argument("--quick", action="store_true", help="a small subset (smoke test): 2 of ours, 2 of Exudyn's, "
                    "16-element reference, no convergence check")
    ap.add_argument("-o", "--output", default="bench_peers", metavar="DIR")
    args = ap.parse_args(argv)

    ok, why = available("exudyn")
    if not ok:
        print(f"peers: skipped: {why}")
        return 0
    ours = [parse_values(g) for g in args.sweep] if args.sweep else (QUICK_OURS if args.quick else OURS)
    peer_sweep = parse_values(args.peer_sweep) if args.peer_sweep else (QUICK_PEER if args.quick else ch.PEER_SWEEP)
    n_ref = 16 if args.quick else args.reference_elements
    warm_up(args.model, args.scene, args.overrides, args.backend)
    t0 = time.perf_counter()
    out = ch.chart(args.model, args.scene, ours, overrides=args.overrides, reference_elements=n_ref,
                   workers=1, out_dir=args.output, peer="exudyn", peer_sweep=peer_sweep, backend=args.backend,
                   progress=False)
    rows, ref = out["rows"], out["reference"]
    if ref.get("failure"):
        print(f"peers: the reference failed ({ref['failure']}): no errors")
        return 1
    check = None if args.quick else convergence_check(
        args.model, args.scene, args.overrides, [int(n) for n in args.check_elements.split(",")], rows, ref)
    ratios = front_ratios(rows, "exudyn")
    meta = {**out["meta"], "exudyn": why, "total_wall_time_s": time.perf_counter() - t0}
    text = markdown(rows, ratios, check, meta)
    Path(args.output, "peers.md").write_text(text + "\n", encoding="utf-8")
    Path(args.output, "peers.json").write_text(json.dumps({"meta": meta, "rows": rows, "front_ratio": ratios,
                                                            "convergence_check": check}, indent=2, default=float)
                                               + "\n", encoding="utf-8")
    print(f"B1 peers: exudyn {why}; reference {ref['n_elements']} elements, h = {ref['step']:g} s: "
          f"max deflection {ref['metrics'][METRIC]:.6f} m; load average "
          f"{', '.join(f'{x:.2f}' for x in meta['load_average'] or [])}")
    print(text)
    print(f"wrote {args.output}/peers.md, peers.json, chart.csv, chart.png ({meta['total_wall_time_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
