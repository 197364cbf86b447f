"""Newton of the integrator on B1 (runtime/integrator.py `_step`, runtime/newton.py `_newton`): iterations per step at
B1's 20 ms step, the accuracy they buy, and a 50 ms step.

An iteration is one residual evaluation followed by one solve; the counts here are the calls of
`_residual_at` themselves (wrapped), so they hold whatever `step` reports. Counts, not times.
"""
from __future__ import annotations

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime import input_rule

HAUG = "models/haug_beam.toml"
# B1's max tip deflection with the solver of commit 585668d (benchmarks/newton_iterations.py --baseline,
# 1 SE x 2 modes, 20 ms; 4 SE x 6 modes, 50 ms): the regression anchor of the iteration counts below
BASELINE_20MS_1x2, BASELINE_50MS_4x6 = 0.602011240, 0.540429819


def _b1(h, n_se, modes, duration=20.0, tol=None):
    """Step B1's spin-up on numpy; returns (evaluations per step, reported iterations per step,
    max transverse tip deflection in the hub frame, steps completed)."""
    model = load_model(HAUG, [f"superelements={n_se}", f"modes={modes}", f"step={h}", f"duration={duration}"])
    body = reduce_body(model.body).data
    system, inputs = sim.build_system(body, model.scene("spinup"), backend="numpy")
    if tol is not None:
        system.tol = tol
    evaluations = [0]
    residual_at = system._residual_at

    def counted(*args, **kwargs):
        evaluations[0] += 1
        return residual_at(*args, **kwargs)

    system._residual_at = counted
    X = system.xN[-1] - system.xN[0]
    n, reported, deflection = round(duration / h), 0, 0.0
    for _ in range(n):
        reported += system.step(h, inputs)
        d = system.RN[0].T @ (system.xN[-1] - system.xN[0]) - X  # eq. (92), hub frame
        deflection = max(deflection, float(np.hypot(d[1], d[2])))
    return evaluations[0] / n, reported / n, deflection, n


@pytest.mark.parametrize("n_se, modes", [(1, 2), (4, 6)])
def test_b1_20ms_takes_at_most_two_iterations_per_step(n_se, modes):
    """At most 2 Newton iterations per step on average on B1 at h = 20 ms (measured 2.00 for both; the
    solver of 585668d took 3.94 and 3.95 evaluations: 2.94 and 2.95 solves and one evaluation of the
    accepted iterate).
    The co-rotated predictor misses by 1e-7..1e-6 of each field's scale, the iteration matrix built at
    the predictor takes it to the tolerance in one increment, the second increment confirms it.
    Two is also the floor (an increment and its confirmation), so the measured 2.00 can only move up on
    another CPU: the bound 2.2 lets one step in five take a third iteration, as at 50 ms below."""
    evals, reported, _, _ = _b1(0.02, n_se, modes)
    assert evals == pytest.approx(reported, abs=1e-12)  # the reported count is the evaluations
    assert evals <= 2.2


def test_b1_20ms_deflection_is_the_tightly_converged_one():
    """The fewer iterations cost no accuracy: B1's max tip deflection at h = 20 ms equals the run with
    the Newton tolerance 100x tighter (1e-11) to 1e-10 relative (measured: identical, 0.602011238154 m)
    and the value of the solver of 585668d (0.602011240 m) to 1e-8 (measured -2.9e-9, the baseline's
    own Newton error)."""
    _, _, d, _ = _b1(0.02, 1, 2)
    _, _, d_tight, _ = _b1(0.02, 1, 2, tol=1e-11)
    assert d == pytest.approx(d_tight, rel=1e-10)
    assert d == pytest.approx(BASELINE_20MS_1x2, rel=1e-8)


def test_b1_50ms_runs_through():
    """h = 50 ms on B1 (4 SE, 6 modes, the 20 s spin-up; the chart of docs/accuracy.md section 2 saw
    Newton give up there) completes in 2 iterations per step (585668d's solver: 5.52 evaluations),
    with 585668d's deflection to 1e-6 (measured +8.7e-8) and within 1 % of the 2 ms run (0.536620 m;
    measured +0.71 %: the step's own error)."""
    evals, _, d, n = _b1(0.05, 4, 6)
    # n: the step count of 20 s at 50 ms, fixed by the scene. evals measured 2.00: the bound 2.2 lets one
    # step in ten take a third iteration where another CPU's round-off puts an increment just above the
    # tolerance, and still fails the old solver's 5.52 by far
    assert n == 400 and evals <= 2.2
    assert d == pytest.approx(BASELINE_50MS_4x6, rel=1e-6)
    assert d == pytest.approx(0.536620, rel=1e-2)


def test_extrapolated_inputs_keep_the_iteration_matrix():
    """An FMU's communication steps (runtime/input_rule.py's input rule, BodySystem.run_extrapolated) of 5 internal
    steps on B1 (4 SE x 6 modes, h = 2 ms, H = 10 ms): the extrapolation from the point values jumps back onto the drive
    at every communication point and sets the elastic modes vibrating, whose accelerations (1e4-1e6
    tolerances) the predictor cannot follow, so every internal step takes 2 iterations; but the matrix
    serves, and REFRESH_AFTER keeps it (KEEP_CONTRACTION). Measured: 1.99 iterations and 0.022
    factorizations per internal step over this second (before: 0.99, a new matrix at every step)."""
    model = load_model(HAUG, ["superelements=4", "modes=6", "step=0.002"])
    body = reduce_body(model.body).data
    system, inputs = sim.build_system(body, model.scene("spinup"), backend="numpy")
    counts = {"evaluations": 0, "factorizations": 0}
    residual_at, factor = system._residual_at, system._factor

    def counted_residual(*args, **kwargs):
        counts["evaluations"] += 1
        return residual_at(*args, **kwargs)

    def counted_factor(*args):
        counts["factorizations"] += 1
        return factor(*args)

    system._residual_at, system._factor = counted_residual, counted_factor
    n, h, steps = 5, 0.002, 0
    for k in range(100):
        t_c = k * n * h
        system.run_extrapolated(h, n, t_c, input_rule.point_values(body.ports, inputs(t_c)))
        system.t = t_c + n * h  # the master's clock (fmu/core.py)
        steps += n
    # measured 2.00 (docs/stability.md): a bound, not an exact count; held under .ci/run's round-off check
    # (runtime with -ffp-contract=fast, numpy without AVX2), where a third iteration in some step would show
    assert counts["evaluations"] / steps <= 2.2  # one step in ten may take a third iteration (as above)
    assert counts["factorizations"] / steps <= 0.05
