"""`ffrf-fmu chart`: sweep parsing, error measures, Pareto front, the stored reference, the CSV and
the plot, on short B1 runs (a fraction of a second to a few seconds of simulated time)."""
import csv
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.studies import chart as ch
from ffrf_fmu.studies import grid
from ffrf_fmu.studies.runners import run_reference
from ffrf_fmu.studies.task import make_task

ROOT = Path(__file__).resolve().parent.parent
B1 = str(ROOT / "models" / "haug_beam.toml")


def test_parse_sweep_and_configurations():
    sweep = grid.parse_values(["superelements=1,2,4", "terms=linear,gyroscopic"])
    assert sweep == {"superelements": ["1", "2", "4"], "terms": ["linear", "gyroscopic"]}
    configs = grid.combinations(sweep)
    assert len(configs) == 6 and configs[0] == {"superelements": "1", "terms": "linear"}
    # several groups: the union of their products, in order
    union = grid.combinations([sweep, {"superelements": ["8"], "step": ["1e-2"]}])
    assert len(union) == 7 and union[-1] == {"superelements": "8", "step": "1e-2"}
    for bad in (["superelements"], ["superelements="], ["=1,2"], ["modes=2", "modes=4"]):
        with pytest.raises(grid.GridError):
            grid.parse_values(bad)


def test_label():
    assert ch.label({"superelements": 4, "modes": 6, "terms": "linear", "step": 0.002}) == "4SE/6m/lin/2ms"
    assert ch.label({"superelements": 1, "modes": 2, "terms": "gyroscopic", "step": 0.032},
                    {"elements": 4}) == "1SE/2m/gyr/32ms/elements=4"


def test_pareto_front():
    cost = [1.0, 2.0, 3.0, 4.0, 2.5, math.nan, 0.5]
    err = [0.5, 0.1, 0.2, 0.01, 0.1, 0.0, math.nan]
    # 1 (0.5) -> 2 (0.1) -> 4 (0.01); 3 and 5 are dominated (2.5 ties 2's error at a higher cost);
    # NaN cost or error never belongs to the front
    assert ch.pareto_front(cost, err) == [0, 1, 3]


def test_errors_against_a_synthetic_reference():
    t = np.linspace(0.0, 2.0, 201)
    d_ref = np.column_stack([0.01 * t, 0.5 * np.sin(t), 0 * t])
    ref = {"t": t, "d": d_ref, "metrics": {"m": 2.0}}
    same = ch.errors({"t": t, "d": d_ref, "metrics": {"m": 2.0}}, ref, "m")
    assert same["metric_error_rel"] == 0.0 and same["rms_error_rel"] == 0.0
    # a run on a coarser grid, 1 % too large everywhere: RMS error = 1 % of rms|d| / max|d|
    tc = t[::4]
    run = {"t": tc, "d": 1.01 * d_ref[::4], "metrics": {"m": 2.04}}
    e = ch.errors(run, ref, "m")
    assert e["metric_error_rel"] == pytest.approx(0.02)
    expected = 0.01 * np.sqrt(np.mean(np.sum(d_ref[::4] ** 2, axis=1))) / np.max(np.linalg.norm(d_ref, axis=1))
    assert e["rms_error_rel"] == pytest.approx(expected, rel=1e-9)
    # a run that failed before producing anything has no errors
    assert ch.errors({"failure": "x"}, ref, "m") == {"metric": None, "metric_error_rel": None, "rms_error_rel": None}


def test_chart_end_to_end(tmp_path):
    """Two configurations and the reference over the first 1.5 s of B1, in this process.

    Physics: by t = 1.5 s the hub turns at 0.013 rad/s, sigma = (Omega/omega_1)^2 = 2e-5, so the
    stiffening that separates 1 and 2 superelements is absent and the tip deflection is the linear
    response to the hub's angular acceleration. Both chains then agree with the 8-element
    geometrically exact reference to the spatial discretization of the two models (measured 0.2 %):
    < 1 % for the peak and the trajectory."""
    start = time.perf_counter()
    out = ch.chart(B1, "spinup", {"superelements": ["1", "2"], "modes": ["2"]}, overrides=["duration=1.5"],
                   reference_elements=8, workers=1, out_dir=tmp_path, progress=False)
    elapsed = time.perf_counter() - start
    rows = out["rows"]
    assert [r["label"] for r in rows] == ["1SE/2m/lin/2ms", "2SE/2m/lin/2ms"]
    for r in rows:
        assert r["completed"] and r["failure"] == "" and r["t_end_s"] == pytest.approx(1.5)
        assert r["metric_error_rel"] < 0.01 and r["rms_error_rel"] < 0.01
        assert r["metric"] == pytest.approx(out["reference"]["metrics"]["tip_deflection_max_m"], rel=0.01)
        # the real-time factor is the simulated time over the run's own wall time
        assert r["real_time_factor"] == pytest.approx(r["t_end_s"] / r["wall_time_s"], rel=1e-12)
    # the runs happened one after the other inside the chart call, timed here independently: their
    # wall times (seconds, not another unit) add up to less than the call
    assert 0 < sum(r["wall_time_s"] for r in rows) < elapsed
    # the reference is trusted (its energy error, measured 7e-6, is below the solver's 2 % warning)
    assert out["reference"]["energy_error"] < 0.02 and not any(r["reference_suspect"] for r in rows)
    assert sum(r["pareto"] for r in rows) >= 1
    # the files: CSV (one row per configuration, the documented columns), PNG, JSON with provenance
    back = ch.read_csv(tmp_path / "chart.csv")
    assert len(back) == 2 and back[0]["superelements"] == 1 and back[0]["modes"] == 2
    assert back[1]["metric_error_rel"] == pytest.approx(rows[1]["metric_error_rel"], rel=1e-5)
    header = next(csv.reader(open(tmp_path / "chart.csv")))
    for col in ("superelements", "modes", "terms", "step", "wall_time_s", "real_time_factor", "metric",
                "metric_error_rel", "rms_error_rel", "completed", "failure"):
        assert col in header
    assert (tmp_path / "chart.png").exists()  # the plot's content is not checked here
    assert ch.json.loads((tmp_path / "chart.json").read_text())["reference"]["warning"] == ""
    # the reference is stored: a second chart runs nothing again, and gets the same numbers
    assert not out["reference"]["cached"]
    again = ch.chart(B1, "spinup", {"superelements": ["1", "2"], "modes": ["2"]}, overrides=["duration=1.5"],
                     reference_elements=8, workers=1, out_dir=tmp_path, progress=False, plot=False)
    assert again["reference"]["cached"] and again["meta"]["runs_ran"] == 0 and again["meta"]["runs_stored"] == 3
    assert again["reference"]["metrics"] == out["reference"]["metrics"]
    assert [r["metric_error_rel"] for r in again["rows"]] == [r["metric_error_rel"] for r in rows]
    direct = run_reference(B1, "spinup", ["duration=1.5"], 8, None)
    assert direct["metrics"]["tip_deflection_max_m"] == out["reference"]["metrics"]["tip_deflection_max_m"]
    assert direct["energy_error"] == out["reference"]["energy_error"]
    # another duration is another reference
    assert make_task(B1, ["duration=1.5"], "spinup", "reference", elements=8).key != \
        make_task(B1, [], "spinup", "reference", elements=8).key


def test_suspect_reference_is_marked(tmp_path):
    """A reference too coarse to trust: 4 elements at h = 0.25 s over the first 1.5 s of B1. Its energy
    error (measured 9.7 % of the energy level) is above the reference solver's 2 % warning: the
    chart must say so in every row, in chart.json and on the command line's table, not silence it."""
    out = ch.chart(B1, "spinup", {"superelements": ["1"]}, overrides=["duration=1.5", "modes=2"],
                   reference_elements=4, reference_step=0.25, workers=1, out_dir=tmp_path, progress=False, plot=False)
    assert out["reference"]["energy_error"] > 0.02
    assert "reference suspect: energy error" in out["reference"]["warning"]
    assert all(r["reference_suspect"] for r in out["rows"])
    assert ch.read_csv(tmp_path / "chart.csv")[0]["reference_suspect"] is True
    assert "energy error" in ch.json.loads((tmp_path / "chart.json").read_text())["reference"]["warning"]


def test_failed_run_is_a_row_and_plotted_apart(tmp_path):
    """B1 with two superelements at h = 40 ms and 100 ms: the spin-up time T = 15 s in 375 and 150
    steps. The first completes (its error is the chain's 3.5 % plus the step's 0.5 %); the second fails
    at t = 18.8 s, where Newton's root has a rotation increment beyond pi (an alias). The
    failed run is a row with completed = False, its failure and the time it reached, outside the
    Pareto front, in the plot's strip of failed runs."""
    out = ch.chart(B1, "spinup", {"step": ["0.04", "0.1"]}, overrides=["superelements=2", "modes=2"],
                   reference_elements=8, reference_step=0.01, workers=1, out_dir=tmp_path, progress=False)
    by = {r["step"]: r for r in out["rows"]}
    assert by[0.04]["completed"] and by[0.04]["pareto"]
    assert 0.03 < by[0.04]["metric_error_rel"] < 0.05
    assert not by[0.1]["completed"] and ("Newton" in by[0.1]["failure"] or "exceeds pi" in by[0.1]["failure"])
    assert 5.0 < by[0.1]["t_end_s"] < 20.0 and not by[0.1]["pareto"]
    # its peak so far is no peak of the scene: not compared with the reference's
    assert by[0.1]["metric_error_rel"] is None and by[0.1]["rms_error_rel"] is not None
    assert (tmp_path / "chart.png").exists()
    assert "2SE/2m/lin/100ms (standalone)" in ch.json.loads((tmp_path / "chart.json").read_text())["failures"]


# `python -m ffrf_fmu ARGS` with the process-wide default start method set to forkserver first (the
# Linux default from Python 3.14)
FORKSERVER_MAIN = ("import multiprocessing, runpy, sys; multiprocessing.set_start_method('forkserver'); "
                   "sys.argv[0] = 'ffrf_fmu'; runpy.run_module('ffrf_fmu', run_name='__main__', alter_sys=True)")


def test_pool_start_method_is_explicit_and_not_fork(monkeypatch, tmp_path):
    """The worker pool names its start method (the platform default changes: fork on Linux up to
    3.13, forkserver from 3.14, spawn on macOS and Windows) and it is one whose workers inherit
    nothing from the parent's memory, so a chart runs the same everywhere."""
    seen = {}

    from ffrf_fmu.studies import sweep

    class Recorder(sweep.ProcessPoolExecutor):
        def __init__(self, *args, **kwargs):
            seen["context"] = kwargs.get("mp_context")
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(sweep, "ProcessPoolExecutor", Recorder)
    out = ch.chart(B1, "spinup", {"superelements": ["1"]}, overrides=["duration=0.1", "modes=2"],
                   reference_elements=4, workers=2, out_dir=tmp_path, progress=False, plot=False)
    assert seen["context"] is not None and seen["context"].get_start_method() in ("spawn", "forkserver")
    assert out["rows"][0]["completed"]


def test_cli_chart_with_workers(tmp_path):
    """The subcommand end to end, two worker processes under a forkserver default, a bad sweep exits
    2 with a message."""
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    cmd = [sys.executable, "-c", FORKSERVER_MAIN, "chart", B1, "--scene", "spinup", "--set", "duration=0.4",
           "--reference-elements", "8", "--workers", "2", "-o", str(tmp_path),
           "--sweep", "superelements=1,2", "modes=2"]
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "1SE/2m/lin/2ms" in res.stdout and "2SE/2m/lin/2ms" in res.stdout
    rows = ch.read_csv(tmp_path / "chart.csv")
    assert [r["superelements"] for r in sorted(rows, key=lambda r: r["superelements"])] == [1, 2]
    assert all(r["completed"] and r["metric_error_rel"] < 0.01 for r in rows)  # as in test_chart_end_to_end
    bad = subprocess.run(cmd[:-2] + ["superelements"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "ffrf-fmu: error: --sweep" in bad.stderr and "Traceback" not in bad.stderr
