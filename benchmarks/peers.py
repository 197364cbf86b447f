#!/usr/bin/env python3
"""Benchmark: our superelement chains against Exudyn's full-order 3D beam on B1, in ONE run.

    python benchmarks/peers.py [--quick] [--repeat N] [--backend native|numpy] [-o DIR] [--set KEY=V ...]
                               [--sweep KEY=V1,V2 ...] [--peer-sweep ...] [--fresh-process | --in-process]

B1 (models/haug_beam.toml, scene spinup: Haug's rotating beam, 20 s, rho_inf 0.8). Runs, one
after another in this process (one core; BLAS and Exudyn pinned to one thread):
- ours over superelements x modes x steps (OURS, or `--sweep` groups): the linear chain and the
  chain with geometric stiffening (`stiffening=true`), with `--backend` (default native; it falls
  back to numpy, with a note, for what its kernel lacks; the table says which ran). `--set` applies
  to every run;
- Exudyn's ObjectBeamGeometricallyExact (ffrf_fmu/peers/exudyn_beam.py: the same section, the
  same spin-up prescribed at the hub, generalized-alpha with the same rho_inf) over elements
  {2, 3, 4, 6, 8, 16} x steps {2, 5, 10, 20, 40} ms;
- the converged reference: the in-house full-order beam (ffrf_fmu/reference) with
  --reference-elements (default 64) at 2 ms, kept in DIR's result store as `ffrf-fmu chart` keeps it.

Two passes over the configurations:
- the accuracy pass: `ffrf-fmu chart`'s sweep (studies/chart.py) with DIR's result store; it gives
  each run's error, which is deterministic (a rerun takes it from the store);
- the timing rounds (--repeat N, default 3): every configuration that completed runs N more times,
  each a fresh run (never the store: a stored result's time is a time of another run, perhaps another
  day's load) as a user runs it (`cli_timing`): ours a subprocess `ffrf-fmu simulate MODEL --set ...
  --summary FILE` whose summary gives the time (wall_time_s: set-up, steps and recording) and the
  metric, Exudyn's a new Python process whose solver's wall time counts (SolveDynamic, no model
  set-up); with --fresh-process both codes' runs in a new Python process each (task.execute: ours the
  time stepping of simulate.run), with --in-process in this one. Round r visits ours and Exudyn's configurations
  interleaved (spread evenly over the round, `interleaved`) and every other round in reverse order,
  so that a burst of load from the other jobs on the machine falls on both codes' runs, not on one
  side. Each configuration keeps the minimum wall and the minimum CPU time of its N runs
  (`best_of`): on a shared machine the noise only ever adds time (waiting for a core, cache
  eviction), so the minimum is the estimate closest to the run's own cost and the least disturbed
  by load; a mean or median carries the load of the moment. Every timing run's metric must equal
  the accuracy pass's (the run is deterministic); a difference is reported and the script exits 1.

Prints and writes (DIR/peers.md, DIR/peers.json, DIR/chart.csv, DIR/chart.png; the chart's times
and Pareto fronts are the best-of-N ones):
- every run's error of the maximum transverse tip deflection against the reference, its wall and
  CPU time (time stepping only; the minimum of N runs, with the spread max/min of the N) and
  Newton iterations;
- the agreement of Exudyn's converged value with the reference: Exudyn at --check-elements
  (default 16 and 32) at 2 ms and their Richardson extrapolation (the element converges as 1/n^2)
  against the reference's 64 elements;
- the ratio of the two Pareto fronts at equal error: Exudyn's cost / ours, both fronts
  interpolated in log-log (chart.front_cost_at), at 0.2 %, 0.5 %, 1 %, 2 %, 5 % and its lowest
  value over the whole span 0.2-5 % (`lowest_ratio`), for wall and CPU time. Above 1, ours is
  cheaper. With its noise: the ratio of the best-of-N fronts, the lowest and highest of the N
  ratios of one round's times each (both fronts from round r), and the pessimistic bound
  (Exudyn's best-of-N front over our front of each configuration's slowest run). Without the
  interpolation ("runs only"): the ratio of the cheapest runs of each code that reach the error.
  On the fronts, errors within SAME_ERROR_REL count as equal (the dearer point is dominated);
- the verdict on the target: Exudyn / ours >= TARGET (10) on wall time over 0.2-5 %;
- the level table (`level_table`): per error level, our cheapest configuration (best-of-N wall time)
  whose error is at or below the level and Exudyn's cheapest at or below it, their errors, times and
  ratio, and beside it Exudyn's cheapest at or below our configuration's own error; by default, the
  whole processes of each level's two configurations (`whole_processes`: `ffrf-fmu simulate` against a
  Python script that loads the model and runs Exudyn, benchmarks/cli_process.py's), best of N,
  interleaved.

Without exudyn (the optional extra `peers`: pip install -e ".[peers]") it says so and exits 0.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # one core against one core
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
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
LEVELS = (0.002, 0.005, 0.01, 0.02, 0.05)  # error levels of the front ratio (0.2 % to 5 %)
SPAN = (LEVELS[0], LEVELS[-1])  # the target holds at every error level in this span ...
TARGET = 10.0  # ... with Exudyn's wall time / ours at least this
REPEAT = 3  # timing runs per configuration (module doc: the minimum of them is kept)
METRIC = "tip_deflection_max_m"  # B1's primary metric (models/haug_beam.toml [scenes.spinup.metrics])
SAME_METRIC_REL = 1e-9  # a timing run's metric against the accuracy pass's: the runs are deterministic
# errors this close count as the same on the fronts (chart.pareto_front): 1 SE with 2 and 6 modes at 40 ms
# differ by 1.3e-7 of their 13.7 % error, far below what the reference resolves (3e-5 of the metric), and
# the dearer one must not be a front vertex that bends the interpolated front between 0.5 % and 13.7 %
SAME_ERROR_REL = 1e-6


def warm_up(model_path, scene, overrides, backend) -> None:
    """A short run of each code first (not timed): the C runtime is compiled or loaded from its disk
    cache, Exudyn and the modules imported, so no configuration pays that in its time."""
    from ffrf_fmu.peers.exudyn_beam import run_configuration as run_peer

    run_configuration(model_path, scene, list(overrides) + ["duration=0.04"], {}, "standalone", backend)
    run_peer(model_path, scene, list(overrides) + ["duration=0.04"], {"elements": 2, "step": 0.02})


def front(rows, runner, cost_key):
    sel = [r for r in rows if r["runner"] == runner and r["completed"] and r["metric_error_rel"] is not None
           and r[cost_key]]
    idx = ch.pareto_front([r[cost_key] for r in sel], [r["metric_error_rel"] for r in sel], SAME_ERROR_REL)
    return [sel[i] for i in idx]


def run_cost_at(f, cost_key, level) -> float | None:
    """The cost of the cheapest run of front f that reaches the error level (no interpolation: the
    front as a staircase of the configurations run), None when none does."""
    costs = [r[cost_key] for r in f if r["metric_error_rel"] <= level]
    return min(costs) if costs else None


def front_ratios(rows, peer, levels=LEVELS) -> list[dict]:
    """Per error level and cost measure: our front's cost, the peer front's, and peer / ours (None
    where a front does not reach the level), the fronts interpolated in log-log (chart.front_cost_at);
    ratio_<cost>_runs: the same of the cheapest runs reaching the level (`run_cost_at`)."""
    out = []
    for level in levels:
        row = {"error": level}
        for cost, key in ch.COSTS.items():
            costs, runs = {}, {}
            for who in ("standalone", peer):
                f = front(rows, who, key)
                costs[who] = ch.front_cost_at([r[key] for r in f], [r["metric_error_rel"] for r in f], level)
                runs[who] = run_cost_at(f, key, level)
            row[f"ours_{cost}_s"], row[f"peer_{cost}_s"] = costs["standalone"], costs[peer]
            row[f"ratio_{cost}"] = (costs[peer] / costs["standalone"]) if None not in costs.values() else None
            row[f"ratio_{cost}_runs"] = (runs[peer] / runs["standalone"]) if None not in runs.values() else None
        out.append(row)
    return out


def span_levels(rows, peer, span=SPAN) -> list[float]:
    """The error levels at which the ratio of the two fronts can be lowest over `span`: its ends and
    every vertex of either front inside it. Both fronts are piecewise linear in log-log
    (chart.front_cost_at), so the log of their ratio is piecewise linear between these levels and
    takes its extremes at them; as staircases (run_cost_at) they step only at these levels."""
    errs = set(span)
    for who in ("standalone", peer):
        for key in ch.COSTS.values():
            errs |= {r["metric_error_rel"] for r in front(rows, who, key) if span[0] < r["metric_error_rel"] < span[1]}
    return sorted(errs)


def lowest_ratio(rows, peer, cost: str, span=SPAN, runs: bool = False) -> dict:
    """{"ratio", "error"}: the lowest peer / ours ratio (cost "wall" or "cpu"; of the interpolated
    fronts, or with `runs` of the cheapest runs) over the whole span and the error level where it
    is; ratio None (at the first such level) when a front misses part of the span."""
    name = f"ratio_{cost}_runs" if runs else f"ratio_{cost}"
    pts = [(q[name], q["error"]) for q in front_ratios(rows, peer, span_levels(rows, peer, span))]
    missing = [e for v, e in pts if v is None]
    if missing:
        return {"ratio": None, "error": missing[0]}
    v, e = min(pts)
    return {"ratio": v, "error": e}


# ------------------------------------------------------------------------------ timing: best of N
def interleaved(a: list, b: list) -> list:
    """a and b merged, each spread evenly over the result (a[i] at (i + 1/2) / len(a) of the way,
    b[j] likewise), so that neither list's items bunch in one part of a timing round."""
    keyed = [((i + 0.5) / len(a), 0, i, x) for i, x in enumerate(a)] + \
            [((j + 0.5) / len(b), 1, j, x) for j, x in enumerate(b)]
    return [k[-1] for k in sorted(keyed, key=lambda k: k[:3])]


def timing_rounds(order: list[int], tasks, repeat: int, execute, log=None) -> dict[int, list[dict]]:
    """{row index: its `repeat` timing runs}, each {"wall_time_s", "cpu_time_s", "completed", "metric"}.
    Round r runs tasks[j] for j in `order` (every other round in reverse), each through `execute`
    (task.execute: a fresh run in this process; the result store is not asked)."""
    runs: dict[int, list[dict]] = {j: [] for j in order}
    for r in range(repeat):
        t0 = time.perf_counter()
        for j in order if r % 2 == 0 else order[::-1]:
            res = execute(tasks[j])
            runs[j].append({"wall_time_s": res.get("wall_time_s"), "cpu_time_s": res.get("cpu_time_s"),
                            "completed": bool(res.get("completed")),
                            "metric": (res.get("metrics") or {}).get(METRIC)})
        if log:
            log(f"timing round {r + 1}/{repeat}: {len(order)} runs, {time.perf_counter() - t0:.0f} s, "
                f"load average {_load()}")
    return runs


def fresh_process(execute):
    """execute(task) in a new Python process (spawned: it imports everything afresh), so that a timing run
    pays what a CLI run pays in its first calls (loading the C runtime, Exudyn's set-up) inside its time."""
    import multiprocessing

    def run(task):
        with multiprocessing.get_context("spawn").Pool(1) as pool:
            return pool.apply(execute, (task,))

    return run


USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}  # bytecode cached, as installed


def cli_command(model_path, task, summary=None) -> list[str]:
    """`ffrf-fmu simulate` of our run `task` (its scene, overrides and backend) as `python -m ffrf_fmu`,
    with --summary FILE when given."""
    sets = [w for o in task.overrides for w in ("--set", o)]
    tail = ["--summary", str(summary)] if summary else []
    return [sys.executable, "-m", "ffrf_fmu", "simulate", str(model_path), "--scene", task.scene, *sets,
            "--backend", task.backend, *tail]


def cli_run(model_path):
    """execute(task) of our runs as a user makes them: `cli_command` in a subprocess (this checkout's
    package, bytecode cached), the summary's wall_time_s, cpu_time_s, completion and metrics."""
    def run(task) -> dict:
        with tempfile.TemporaryDirectory(prefix="ffrf_peers_") as tmp:
            out = Path(tmp, "summary.json")
            p = subprocess.run(cli_command(model_path, task, out), capture_output=True, text=True, cwd=ROOT,
                               env=dict(USER_ENV, PYTHONPATH=str(ROOT)))
            if not out.is_file():
                return {"completed": False, "failure": f"exit {p.returncode}: {p.stderr.strip()[-400:]}"}
            s = json.loads(out.read_text())
        return {"wall_time_s": s["wall_time_s"], "cpu_time_s": s["cpu_time_s"], "completed": bool(s["completed"]),
                "failure": s["failure"], "metrics": s["metrics"]}

    return run


def cli_timing(model_path, execute):
    """The timing runs by default: ours through `cli_run`, the peer's through `fresh_process(execute)`."""
    ours, peer = cli_run(model_path), fresh_process(execute)
    return lambda task: ours(task) if task.runner == "standalone" else peer(task)


def _completed(runs: list[dict]) -> list[dict]:
    """The timing runs that completed with both times."""
    return [r for r in runs if r["completed"] and r["wall_time_s"] and r["cpu_time_s"]]


def best_of(runs: list[dict]) -> dict:
    """The minimum wall and CPU time of a configuration's completed timing runs (module doc: the
    estimate least disturbed by the machine's load), with the spread max / min of each and their
    count. Times None when no run completed."""
    ok = _completed(runs)
    out = {"timing_runs": len(ok)}
    for cost in ch.COSTS.values():
        vals = [r[cost] for r in ok]
        out[cost] = min(vals) if vals else None
        out[cost.replace("_time_s", "_spread")] = max(vals) / min(vals) if vals else None
    return out


def timed(rows, runs: dict[int, list[dict]], pick=None) -> list[dict]:
    """The rows with the times pick(row, its runs) takes (default: best_of the runs); rows not timed
    keep theirs, with timing_runs 0; real-time factor and Pareto fronts (on wall time) recomputed."""
    out = []
    for j, row in enumerate(rows):
        row = dict(row)
        if j in runs:
            row |= pick(row, runs[j]) if pick else best_of(runs[j])
            row["real_time_factor"] = (row["t_end_s"] / row["wall_time_s"]) if row["wall_time_s"] and \
                row["t_end_s"] is not None else None
        else:
            row.setdefault("timing_runs", 0)
        out.append(row)
    ch.mark_pareto(out, "wall", same_error_rel=SAME_ERROR_REL)
    return out


def round_of(r: int):
    """`timed`'s pick of round r's times alone."""
    return lambda row, runs: {k: runs[r][k] if runs[r]["completed"] else None for k in ch.COSTS.values()}


def slowest_of(runs: list[dict]) -> dict:
    """The slowest completed run's wall and CPU time (each its maximum)."""
    ok = _completed(runs)
    return {k: max(r[k] for r in ok) if ok else None for k in ch.COSTS.values()}


def pessimistic(peer: str):
    """`timed`'s pick of the pessimistic bound on peer / ours: the peer's best-of-N times, our slowest."""
    return lambda row, runs: best_of(runs) if row["runner"] == peer else slowest_of(runs)


def disagreements(rows, runs: dict[int, list[dict]]) -> list[str]:
    """Timing runs whose outcome differs from the accuracy pass's run of the same configuration
    (failed, or another metric than to SAME_METRIC_REL): the runs are deterministic, so any is a bug."""
    out = []
    for j, rs in runs.items():
        m = rows[j]["metric"]
        for k, r in enumerate(rs):
            if not r["completed"]:
                out.append(f"{rows[j]['label']}: timing run {k + 1} failed")
            elif r["metric"] is None or m is None or abs(r["metric"] - m) > SAME_METRIC_REL * abs(m):
                out.append(f"{rows[j]['label']}: timing run {k + 1} gave {r['metric']!r}, the accuracy pass {m!r}")
    return out


def ratio_table(best, rounds, worst, peer, levels=LEVELS) -> list[dict]:
    """front_ratios of the best-of-N rows per level, with per cost measure the lowest and highest
    ratio over the rounds (each round's times alone: ratio_<cost>_rounds) and the pessimistic
    ratio (ratio_<cost>_pessimistic: Exudyn best-of-N over our slowest runs)."""
    out = front_ratios(best, peer, levels)
    per_round = [front_ratios(rr, peer, levels) for rr in rounds]
    bound = front_ratios(worst, peer, levels)
    for i, q in enumerate(out):
        for cost in ch.COSTS:
            vals = [pr[i][f"ratio_{cost}"] for pr in per_round]
            q[f"ratio_{cost}_rounds"] = [min(vals), max(vals)] if vals and None not in vals else None
            q[f"ratio_{cost}_pessimistic"] = bound[i][f"ratio_{cost}"]
    return out


def verdict(best, rounds, worst, peer, target=TARGET, span=SPAN) -> dict:
    """The target, Exudyn / ours >= target on wall time at every error level in span, on the
    best-of-N times ("met"), on each round's times alone ("met_every_round"), on the pessimistic
    bound ("met_pessimistic") and, best-of-N, on the cheapest runs without interpolation
    ("met_runs_only"), with the lowest ratios over the span (`lowest_ratio`) it rests on."""
    low = {cost: {"best_of_n": lowest_ratio(best, peer, cost, span),
                  "rounds": [lowest_ratio(rr, peer, cost, span) for rr in rounds],
                  "pessimistic": lowest_ratio(worst, peer, cost, span),
                  "runs_only": lowest_ratio(best, peer, cost, span, runs=True)} for cost in ch.COSTS}

    def ok(x):
        return x["ratio"] is not None and x["ratio"] >= target

    w = low["wall"]
    return {"target": target, "span": list(span), "met": ok(w["best_of_n"]),
            "met_every_round": bool(w["rounds"]) and all(ok(x) for x in w["rounds"]),
            "met_pessimistic": ok(w["pessimistic"]), "met_runs_only": ok(w["runs_only"]), "lowest": low}


def _cheapest(rows, runner, level):
    """The row of `runner` with the least wall time among those whose error is at most `level`, or None."""
    ok = [r for r in rows if r["runner"] == runner and r["completed"] and r["metric_error_rel"] is not None
          and r["wall_time_s"] and r["metric_error_rel"] <= level]
    return min(ok, key=lambda r: r["wall_time_s"]) if ok else None


def level_table(rows, peer, levels=LEVELS) -> list[dict]:
    """Per error level: "ours", our cheapest row at or below the level; "peer", the peer's cheapest at or
    below it, and "ratio" its wall time over ours; "peer_at_ours", the peer's cheapest at or below our
    row's own error, and "ratio_at_ours" (None where a code reaches no such error)."""
    out = []
    for level in levels:
        ours = _cheapest(rows, "standalone", level)
        theirs = _cheapest(rows, peer, level)
        strict = _cheapest(rows, peer, ours["metric_error_rel"]) if ours else None
        out.append({"error": level, "ours": ours, "peer": theirs, "peer_at_ours": strict,
                    "ratio": theirs["wall_time_s"] / ours["wall_time_s"] if ours and theirs else None,
                    "ratio_at_ours": strict["wall_time_s"] / ours["wall_time_s"] if ours and strict else None})
    return out


def whole_processes(model_path, levels, tasks, rows, repeat: int) -> list[dict]:
    """Per distinct pair (ours, the peer's) of `levels` (level_table): the whole process of ours
    (`cli_command` without a summary) and of a Python script that loads the model and runs the peer's
    configuration (benchmarks/cli_process.py PEER), each timed from start to exit, `repeat` times after
    one untimed run, the two alternating; the minimum of each and the ratio peer / ours."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from cli_process import PEER, timed as timed_process

    env = dict(USER_ENV, PYTHONPATH=str(ROOT))
    pairs = {}
    for q in levels:
        if q["ours"] and q["peer"]:
            pairs.setdefault((q["ours"]["label"], q["peer"]["label"]), (q["ours"], q["peer"]))
    index = {r["label"]: j for j, r in enumerate(rows)}
    out = []
    for (a, b), (ours, theirs) in pairs.items():
        cmds = {"ours": cli_command(model_path, tasks[index[a]]),
                "peer": [sys.executable, "-c", PEER.format(model=str(model_path), n=int(theirs["elements"]),
                                                           h=float(theirs["step"]))]}
        walls = {"ours": [], "peer": []}
        for k in range(repeat + 1):
            for who in ("ours", "peer") if k % 2 == 0 else ("peer", "ours"):
                wall, _, code = timed_process(cmds[who], env)
                if code != 0:
                    raise RuntimeError(f"whole process failed (exit {code}): {' '.join(cmds[who])}")
                if k:
                    walls[who].append(wall)
        out.append({"ours": a, "peer": b, "ours_s": min(walls["ours"]), "peer_s": min(walls["peer"]),
                    "ratio": min(walls["peer"]) / min(walls["ours"]), "command": " ".join(cmds["ours"][1:])})
    return out


def _load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


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


def _range(v, fmt=".2f") -> str:
    return f"{v[0]:{fmt}}-{v[1]:{fmt}}" if v else "not reached"


def markdown(rows, ratios, check, meta, judged=None) -> str:
    n = meta.get("repeat")
    lines = [f"| code | configuration | wall [s] | CPU [s] | wall max/min (of {n}) | Newton it./step | "
             "max deflection [m] | error | front | backend |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (r["runner"] != "exudyn", r["label"])):
        who = "Exudyn" if r["runner"] == "exudyn" else "ours"
        status = "" if r["completed"] else f" (failed at t = {_f(r['t_end_s'], '.3g')} s)"
        lines.append(f"| {who} | {r['label']}{status} | {_f(r['wall_time_s'], '.3f')} | {_f(r['cpu_time_s'], '.3f')} | "
                     f"{_f(r.get('wall_spread'), '.2f')} | "
                     f"{_f(r.get('newton_iterations_mean'), '.2f')} | {_f(r['metric'], '.5f')} | "
                     f"{_f(r['metric_error_rel'], '.3%')} | {'*' if r.get('pareto') else ''} | "
                     f"{r.get('backend') or ('C++' if r['runner'] == 'exudyn' else '')} |")
    lines += ["", f"Front ratio Exudyn / ours at equal error (times: best of {n} runs per configuration; "
              f"rounds: the lowest-highest ratio of the {n} rounds' times alone; pessimistic: Exudyn's best over "
              "our slowest run per configuration; runs only: no interpolation, the cheapest run of each code that "
              "reaches the error):", "",
              "| error | ours: wall / CPU [s] | Exudyn: wall / CPU [s] | wall ratio | wall, rounds | wall, pessimistic "
              "| wall, runs only | CPU ratio | CPU, rounds | CPU, pessimistic |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for q in ratios:
        lines.append(f"| {q['error']:.1%} | {_f(q['ours_wall_s'], '.3g')} / {_f(q['ours_cpu_s'], '.3g')} | "
                     f"{_f(q['peer_wall_s'], '.3g')} / {_f(q['peer_cpu_s'], '.3g')} | "
                     f"{_f(q['ratio_wall'], '.2f', 'not reached')} | {_range(q.get('ratio_wall_rounds'))} | "
                     f"{_f(q.get('ratio_wall_pessimistic'), '.2f', 'not reached')} | "
                     f"{_f(q.get('ratio_wall_runs'), '.2f', 'not reached')} | "
                     f"{_f(q['ratio_cpu'], '.2f', 'not reached')} | {_range(q.get('ratio_cpu_rounds'))} | "
                     f"{_f(q.get('ratio_cpu_pessimistic'), '.2f', 'not reached')} |")
    if judged:
        lines += ["", verdict_text(judged, n)]
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


def level_markdown(levels, whole, meta) -> str:
    """The level table (level_table) and the whole processes (whole_processes) as markdown."""
    n = meta.get("repeat")

    def cell(r):
        return (f"{r['label']}, {r['metric_error_rel']:.3%}, {1e3 * r['wall_time_s']:.1f} ms (CPU "
                f"{1e3 * r['cpu_time_s']:.1f})") if r else "not reached"

    def ratio(a, b):
        return f"{b['wall_time_s'] / a['wall_time_s']:.2f} (CPU {b['cpu_time_s'] / a['cpu_time_s']:.2f})" if a and b else "–"

    ours_time = "summary wall_time_s of `ffrf-fmu simulate`" if meta.get("cli") else "wall time of the run"
    lines = [f"Per level, the cheapest configuration of each code at or below it (best of {n}; ours: {ours_time}, "
             "Exudyn: its solver's wall time):", "",
             "| level | ours: configuration, error, wall (CPU) | Exudyn: configuration, error, wall (CPU) | Exudyn / ours "
             "| Exudyn at or below our error | Exudyn / ours there |", "|---|---|---|---|---|---|"]
    for q in levels:
        lines.append(f"| {q['error']:.1%} | {cell(q['ours'])} | {cell(q['peer'])} | {ratio(q['ours'], q['peer'])} | "
                     f"{cell(q['peer_at_ours'])} | {ratio(q['ours'], q['peer_at_ours'])} |")
    if whole:
        lines += ["", f"Whole processes (start to exit, best of {n}, alternating): ours `ffrf-fmu simulate` with the "
                  "configuration, Exudyn a Python script that loads the model file and runs its configuration:", "",
                  "| ours | Exudyn | ours [s] | Exudyn [s] | Exudyn / ours |", "|---|---|---|---|---|"]
        for w in whole:
            lines.append(f"| {w['ours']} | {w['peer']} | {w['ours_s']:.3f} | {w['peer_s']:.3f} | {w['ratio']:.2f} |")
    return "\n".join(lines)


def verdict_text(v: dict, n) -> str:
    def low(x):
        return f"{x['ratio']:.2f} at {x['error']:.3%}" if x["ratio"] is not None else f"not reached at {x['error']:.3%}"

    w, c = v["lowest"]["wall"], v["lowest"]["cpu"]
    lo, hi = v["span"]
    head = (f"Target Exudyn / ours >= {v['target']:g} on wall time at every error level from {lo:.1%} to {hi:.0%}: "
            f"**{'met' if v['met'] else 'not met'}** on the best-of-{n} times (lowest ratio over the span "
            f"{low(w['best_of_n'])}); ")
    per_round = [x["ratio"] for x in w["rounds"]]
    below = sum(r is None or r < v["target"] for r in per_round)
    spread = f"{min(per_round):.2f}-{max(per_round):.2f}" if None not in per_round else "some not reached"
    return (head + f"{'met' if v['met_every_round'] else 'not met'} in every round's times alone (missed in {below} "
            f"of {len(per_round)} rounds; their lowest ratios {spread}); "
            f"{'met' if v['met_pessimistic'] else 'not met'} on the pessimistic bound "
            f"({low(w['pessimistic'])}); {'met' if v['met_runs_only'] else 'not met'} on the runs only, without "
            f"interpolation ({low(w['runs_only'])}). CPU time: lowest {low(c['best_of_n'])} (best of {n}).")


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
    ap.add_argument("--backend", choices=("native", "numpy"), default="native",
                    help="our runtime backend (native falls back to numpy, with a note, where the C runtime cannot be compiled)")
    ap.add_argument("--repeat", type=int, default=REPEAT, metavar="N",
                    help=f"timing runs per configuration, interleaved; each keeps the minimum (default {REPEAT})")
    how = ap.add_mutually_exclusive_group()
    how.add_argument("--fresh-process", action="store_true",
                     help="each timing run in a new Python process (as a CLI run pays its first calls), not in this one")
    how.add_argument("--in-process", action="store_true",
                     help="each timing run in this process (task.execute); default: ours as `ffrf-fmu simulate "
                          "--summary` subprocesses (the summary's wall_time_s), Exudyn's in a new process each (its "
                          "solver's wall time), then the whole processes of each level's pair")
    ap.add_argument("--quick", action="store_true", help="a small subset (smoke test): 2 of ours, 2 of Exudyn's, "
                    "16-element reference, no convergence check")
    ap.add_argument("-o", "--output", default="bench_peers", metavar="DIR")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error(f"--repeat {args.repeat}: expected at least 1 timing run per configuration")

    ok, why = available("exudyn")
    if not ok:
        print(f"peers: skipped: {why}")
        return 0
    from ffrf_fmu.studies.task import execute

    ours = [parse_values(g) for g in args.sweep] if args.sweep else (QUICK_OURS if args.quick else OURS)
    peer_sweep = parse_values(args.peer_sweep) if args.peer_sweep else (QUICK_PEER if args.quick else ch.PEER_SWEEP)
    n_ref = 16 if args.quick else args.reference_elements
    load_start = _load()
    warm_up(args.model, args.scene, args.overrides, args.backend)
    t0 = time.perf_counter()
    out = ch.chart(args.model, args.scene, ours, overrides=args.overrides, reference_elements=n_ref,
                   workers=1, out_dir=args.output, peer="exudyn", peer_sweep=peer_sweep, backend=args.backend,
                   progress=False)
    rows, ref, tasks = out["rows"], out["reference"], out["tasks"]
    if ref.get("failure"):
        print(f"peers: the reference failed ({ref['failure']}): no errors")
        return 1
    t_accuracy = time.perf_counter() - t0
    print(f"accuracy pass: {len(rows)} configurations and the reference ({out['meta']['runs_ran']} runs done now, "
          f"{out['meta']['runs_stored']} taken from {args.output}'s store), {t_accuracy:.0f} s", flush=True)
    timed_rows = [j for j, r in enumerate(rows) if r["completed"] and r["metric_error_rel"] is not None]
    order = interleaved([j for j in timed_rows if rows[j]["runner"] != "exudyn"],
                        [j for j in timed_rows if rows[j]["runner"] == "exudyn"])
    cli = not (args.fresh_process or args.in_process)
    how = execute if args.in_process else fresh_process(execute) if args.fresh_process else cli_timing(args.model, execute)
    runs = timing_rounds(order, tasks, args.repeat, how, log=lambda m: print(m, flush=True))
    best = timed(rows, runs)
    rounds = [timed(rows, runs, round_of(r)) for r in range(args.repeat)]
    worst = timed(rows, runs, pessimistic("exudyn"))
    wrong = disagreements(rows, runs)
    ch.write_csv(Path(args.output, "chart.csv"), best)
    ch.replot(args.output, same_error_rel=SAME_ERROR_REL)  # the chart of the best-of-N times
    check = None if args.quick else convergence_check(
        args.model, args.scene, args.overrides, [int(n) for n in args.check_elements.split(",")], best, ref)
    ratios = ratio_table(best, rounds, worst, "exudyn")
    judged = verdict(best, rounds, worst, "exudyn")
    levels = level_table(best, "exudyn")
    load_timing = _load()
    whole = whole_processes(args.model, levels, tasks, best, args.repeat) if cli else []
    meta = {**out["meta"], "exudyn": why, "repeat": args.repeat, "fresh_process": args.fresh_process, "cli": cli,
            "load_average_start": load_start, "load_average_after_timing": load_timing, "load_average_end": _load(),
            "accuracy_pass_s": t_accuracy, "total_wall_time_s": time.perf_counter() - t0, "timing_disagreements": wrong}
    text = markdown(best, ratios, check, meta, judged) + "\n\n" + level_markdown(levels, whole, meta)
    Path(args.output, "peers.md").write_text(text + "\n", encoding="utf-8")
    Path(args.output, "peers.json").write_text(json.dumps(
        {"meta": meta, "rows": best, "front_ratio": ratios, "verdict": judged, "convergence_check": check,
         "levels": levels, "whole_processes": whole,
         "timing_runs": {rows[j]["label"]: rs for j, rs in runs.items()}}, indent=2, default=float) + "\n",
        encoding="utf-8")
    print(f"B1 peers: exudyn {why}; reference {ref['n_elements']} elements, h = {ref['step']:g} s: "
          f"max deflection {ref['metrics'][METRIC]:.6f} m; load average at the start {load_start}, at the end "
          f"{meta['load_average_end']}; best of {args.repeat} timing runs per configuration")
    print(text)
    for w in wrong:
        print(f"peers: TIMING RUN DISAGREES: {w}")
    print(f"wrote {args.output}/peers.md, peers.json, chart.csv, chart.png ({meta['total_wall_time_s']:.0f} s)")
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
