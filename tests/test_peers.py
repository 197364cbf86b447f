"""The Exudyn peer (ffrf_fmu/peers/exudyn_beam.py) reproduces the reference on B1, the peers
benchmark stays harmless without it, and its timing (best of N fresh, interleaved runs) and front
ratio over the error span do what benchmarks/peers.py says (with fake runs: no timed test)."""
import dataclasses
import importlib.util
from pathlib import Path

import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.studies.chart import front_cost_at
from ffrf_fmu.studies.runners import body_data
from ffrf_fmu.model import load_model, scene_body

ROOT = Path(__file__).resolve().parent.parent
# the converged maximum transverse tip deflection of B1 from the in-house reference (ffrf_fmu/reference):
# 64 elements, h = 2 ms (docs/accuracy.md section 3; its Richardson extrapolation from 32 and 64 elements
# is 0.531879, so it is itself within 3e-5 of converged)
B1_CONVERGED = 0.531864


def _bench():
    spec = importlib.util.spec_from_file_location("peers_bench", ROOT / "benchmarks" / "peers.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def _b1(duration):
    model = load_model(ROOT / "models" / "haug_beam.toml", [f"duration={duration}"])
    sc = model.scene("spinup")
    return model, sc, scene_body(model.body, sc)


def test_exudyn_b1_reproduces_the_reference_max_deflection():
    """Exudyn's 3D geometrically exact beam with the B1 section and spin-up: the maximum transverse tip
    deflection (eq. 92, simulate.metrics) converges from below with the mesh, as the reference does, and
    the Richardson extrapolation of 8 and 16 elements (1/n^2) lands within 0.1 % of the reference's
    converged 0.531864 m. Measured: 0.529946, 0.531500 -> 0.532018 (+0.029 %). The budget: Exudyn's step
    error at h = 10 ms, +0.027 % against 2 ms (measured, O(h^2)); the reference's own mesh error, 3e-5;
    Newton tolerances, below 1e-5 (exudyn_beam.NEWTON_REL_TOL study). 0.1 % is 3x that, while a wrong
    section, inertia or drive moves the peak by far more. 8 s of the 20 s scene: the peak is at 6.76 s."""
    pytest.importorskip("exudyn", reason="exudyn is the optional extra `peers` (pip install -e \".[peers]\")")
    from ffrf_fmu.peers import exudyn_beam as xb

    model, sc, body = _b1(8.0)
    bd = body_data(model, sc)
    peak = {}
    for n in (8, 16):
        res = xb.simulate(body, sc, n, 0.01)
        assert res.completed, res.failure
        m = sim.metrics(sim.SimulationResult(res.t, xb.columns(res), {}, bd), sc)
        assert 6.0 < m["t_at_max_s"] < 7.5  # the peak of the spin-up, inside the run
        peak[n] = m["tip_deflection_max_m"]
    assert peak[8] < peak[16] < B1_CONVERGED
    extrapolated = peak[16] + (peak[16] - peak[8]) / 3.0
    assert extrapolated == pytest.approx(B1_CONVERGED, rel=1e-3)


def test_exudyn_peer_refuses_what_it_cannot_model():
    pytest.importorskip("exudyn", reason="exudyn is the optional extra `peers` (pip install -e \".[peers]\")")
    from ffrf_fmu.peers import exudyn_beam as xb

    _, sc, body = _b1(1.0)
    with pytest.raises(ValueError, match="superelements"):  # 3 elements put no node at 4 superelements' ports
        xb.build(dataclasses.replace(body, ports=body.ports + (dataclasses.replace(body.ports[0], name="mid", node=2),)),
                 sc, 3)
    with pytest.raises(NotImplementedError, match="gravity"):
        xb.build(body, dataclasses.replace(sc, gravity=(0.0, 0.0, -9.81)), 4)
    with pytest.raises(ValueError, match="GA2"):
        xb.build(dataclasses.replace(body, section=dataclasses.replace(body.section, GA2=None)), sc, 4)


def test_front_cost_interpolates_in_log_log():
    # front (1 s, 10 %), (4 s, 1 %), (16 s, 0.1 %): 3.16 % lies half-way in log error -> 2 s (log-half of 1..4)
    cost, err = [1.0, 4.0, 16.0], [0.1, 0.01, 0.001]
    assert front_cost_at(cost, err, 10 ** -1.5) == pytest.approx(2.0)
    assert front_cost_at(cost, err, 0.2) == 1.0  # the cheapest point already meets it
    assert front_cost_at(cost, err, 1e-4) is None  # not reached


def test_peers_benchmark_without_exudyn_says_so_and_exits_0(monkeypatch, capsys):
    bench = _bench()
    monkeypatch.setattr(bench, "available", lambda name: (False, "exudyn is not installed (test)"))
    assert bench.main(["--quick", "-o", "unused"]) == 0
    assert "skipped: exudyn is not installed" in capsys.readouterr().out


def _row(label, runner, error, wall, metric=0.5):
    return {"label": label, "runner": runner, "completed": True, "metric": metric, "metric_error_rel": error,
            "wall_time_s": wall, "cpu_time_s": wall, "t_end_s": 20.0, "real_time_factor": 20.0 / wall}


def test_best_of_n_times_fresh_runs_interleaved_and_keeps_their_minimum():
    """Every timing is a fresh run through `execute` (not the time the chart's row carries, which a rerun
    takes from the result store), rounds alternate ours and the peer's runs and every other round runs
    backwards, and each configuration keeps the minimum wall and CPU time of its runs, with the spread."""
    bench = _bench()
    # as the chart gave them: times of a stored run (0.001 s), which must not count as a timing
    rows = [_row("o1", "standalone", 0.01, 0.001), _row("o2", "standalone", 0.003, 0.001),
            _row("x1", "exudyn", 0.01, 0.001)]
    tasks = ["task-o1", "task-o2", "task-x1"]
    walls = {"task-o1": [0.30, 0.20, 0.25], "task-o2": [0.9, 1.1, 1.0], "task-x1": [0.5, 0.7, 0.6]}
    cpus = {"task-o1": [0.29, 0.21, 0.19], "task-o2": [0.8, 1.0, 0.9], "task-x1": [0.5, 0.6, 0.45]}
    calls = []

    def execute(task):
        k = sum(c == task for c in calls)
        calls.append(task)
        return {"wall_time_s": walls[task][k], "cpu_time_s": cpus[task][k], "completed": True,
                "metrics": {bench.METRIC: 0.5}}

    order = bench.interleaved([0, 1], [2])
    assert order == [0, 2, 1]  # the peer's one run in the middle of ours
    runs = bench.timing_rounds(order, tasks, 3, execute)
    assert calls == ["task-o1", "task-x1", "task-o2", "task-o2", "task-x1", "task-o1",
                     "task-o1", "task-x1", "task-o2"]
    best = bench.timed(rows, runs)
    assert [r["wall_time_s"] for r in best] == [0.20, 0.9, 0.5]
    assert [r["cpu_time_s"] for r in best] == [0.19, 0.8, 0.45]  # each its own minimum
    assert best[0]["wall_spread"] == pytest.approx(1.5) and best[2]["cpu_spread"] == pytest.approx(0.6 / 0.45)
    assert all(r["timing_runs"] == 3 for r in best)
    assert best[1]["real_time_factor"] == pytest.approx(20.0 / 0.9)
    assert rows[0]["wall_time_s"] == 0.001  # the chart's rows are left as they were
    second = bench.timed(rows, runs, bench.round_of(1))
    assert [r["wall_time_s"] for r in second] == [0.20, 1.1, 0.7]
    worst = bench.timed(rows, runs, bench.pessimistic("exudyn"))
    assert [r["wall_time_s"] for r in worst] == [0.30, 1.1, 0.5]  # ours slowest, the peer's best
    assert bench.disagreements(rows, runs) == []


def test_a_timing_run_that_differs_from_the_accuracy_pass_is_reported():
    bench = _bench()
    rows = [_row("o1", "standalone", 0.01, 0.1, metric=0.5)]
    results = iter([{"completed": True, "metrics": {bench.METRIC: 0.5}, "wall_time_s": 0.1, "cpu_time_s": 0.1},
                    {"completed": True, "metrics": {bench.METRIC: 0.5001}, "wall_time_s": 0.1, "cpu_time_s": 0.1},
                    {"completed": False, "metrics": {}, "wall_time_s": 0.01, "cpu_time_s": 0.01}])
    runs = bench.timing_rounds([0], ["t"], 3, lambda task: next(results))
    wrong = bench.disagreements(rows, runs)
    assert len(wrong) == 2 and "run 2 gave 0.5001" in wrong[0] and "run 3 failed" in wrong[1]
    assert bench.best_of(runs[0])["wall_time_s"] == 0.1  # the failed run's time is no timing


def test_lowest_front_ratio_over_the_span_finds_a_dip_between_the_levels():
    """The fronts are piecewise linear in log-log, so their ratio is lowest at a level or at a vertex of
    either front: a peer vertex at 0.7 % (between the 0.5 % and 1 % levels) is where the peer is cheapest
    against ours, and the verdict must see it."""
    bench = _bench()
    rows = [_row("o1", "standalone", 0.05, 0.1), _row("o2", "standalone", 0.002, 1.0),
            _row("x1", "exudyn", 0.05, 0.5), _row("x2", "exudyn", 0.007, 0.6), _row("x3", "exudyn", 0.002, 5.0)]
    at_levels = [q["ratio_wall"] for q in bench.front_ratios(rows, "exudyn")]
    low = bench.lowest_ratio(rows, "exudyn", "wall")
    assert low["error"] == 0.007 and low["ratio"] < min(at_levels)
    ours = bench.ch.front_cost_at([0.1, 1.0], [0.05, 0.002], 0.007)
    assert low["ratio"] == pytest.approx(0.6 / ours)
    v = bench.verdict(rows, [rows], rows, "exudyn", target=low["ratio"] * 1.01)
    assert min(at_levels) > low["ratio"] * 1.01 and not v["met"]  # every listed level passes, the span does not


def test_equal_errors_make_no_front_vertex_and_runs_only_ratio_does_not_interpolate():
    """Two of our runs with the same error to 1e-7 (1 SE with 2 and 6 modes): the dearer one is no vertex of
    the front (else it bends the interpolated front between its neighbours); the runs-only ratio takes the
    cheapest run reaching the level."""
    bench = _bench()
    rows = [_row("2m", "standalone", 0.137, 0.028), _row("6m", "standalone", 0.137 * (1 - 1e-7), 0.034),
            _row("stiff", "standalone", 0.005, 0.035), _row("x", "exudyn", 0.05, 0.1), _row("y", "exudyn", 0.002, 1.0)]
    assert [r["label"] for r in bench.front(rows, "standalone", "wall_time_s")] == ["2m", "stiff"]
    q = bench.front_ratios(rows, "exudyn", [0.05])[0]
    ours = bench.ch.front_cost_at([0.028, 0.035], [0.137, 0.005], 0.05)  # between 2m and the stiffened run
    assert q["ours_wall_s"] == pytest.approx(ours) and q["ratio_wall"] == pytest.approx(0.1 / ours)
    assert q["ratio_wall_runs"] == pytest.approx(0.1 / 0.035)  # the cheapest run reaching 5 %
    assert bench.timed(rows, {})[1]["pareto"] is False


def test_level_table_takes_each_codes_cheapest_run_at_or_below_the_level():
    """Per level, the cheapest run of each code whose error is at or below it (a cheaper run above the
    level does not count), and the peer's cheapest at or below our run's own error beside it."""
    bench = _bench()
    rows = [_row("o1", "standalone", 0.004, 0.03), _row("o2", "standalone", 0.0015, 0.07),
            _row("o3", "standalone", 0.03, 0.01), _row("x1", "exudyn", 0.011, 0.1),
            _row("x2", "exudyn", 0.0024, 0.17), _row("x3", "exudyn", 0.0006, 0.35)]
    by = {q["error"]: q for q in bench.level_table(rows, "exudyn", (0.002, 0.005, 0.01, 0.05))}
    assert by[0.002]["ours"]["label"] == "o2" and by[0.002]["peer"]["label"] == "x3"
    assert by[0.005]["ours"]["label"] == "o1" and by[0.005]["peer"]["label"] == "x2"
    assert by[0.005]["ratio"] == pytest.approx(0.17 / 0.03)
    assert by[0.005]["peer_at_ours"]["label"] == "x2"  # 0.24 % <= our 0.4 %
    assert by[0.01]["peer"]["label"] == "x2"  # x1's 1.1 % is above the level
    assert by[0.01]["peer_at_ours"]["label"] == "x2" and by[0.01]["ratio_at_ours"] == pytest.approx(0.17 / 0.03)
    assert by[0.05]["ours"]["label"] == "o3" and by[0.05]["peer"]["label"] == "x1"
    assert by[0.05]["peer_at_ours"]["label"] == "x1"  # at or below our 3 %: x1 (1.1 %), the cheapest
