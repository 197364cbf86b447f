"""The stability maps' marginal class (ffrf_fmu/studies/stability/margin.py): a point whose verdict could
flip is re-run perturbed and at the neighbour step; it is `marginal` when a re-run's verdict differs."""
import numpy as np

from ffrf_fmu.studies.stability import margin

GRID = (0.05, 0.1, 0.2, 0.5)


def _chaotic_failure(step: float, perturbation: float, duration: float = 20.0) -> float:
    """A synthetic run that fails when a chaotic iterate (the logistic map at r = 4, whose
    perturbations grow by 2x per iterate: 1e-9 reaches O(1) in ~30 iterates) passes 0.999: the time it
    fails, or `duration` when it runs through. Stands for a late Newton failure that depends on the
    last bits of the state."""
    x = 0.3 * (1.0 + perturbation)
    n = int(round(duration / step))
    for k in range(n):
        x = 4.0 * x * (1.0 - x)
        if k > 0.9 * n and x > 0.999:
            return (k + 1) * step
    return duration


def _point(step, perturbation=0.0):
    t = _chaotic_failure(step, perturbation)
    return margin.Point(unstable=t < 20.0, t_end=t, duration=20.0)


def test_a_late_failure_that_moves_under_a_1e_9_perturbation_is_marginal():
    # the synthetic run at h = 0.2 s: 100 iterates; a 1e-9 perturbation grows to O(1) in ~30, so the
    # perturbed run's late path is another one
    steps = [h for h in (0.1, 0.2, 0.05, 0.04, 0.025) if _point(h).unstable]
    assert steps, "no synthetic run fails late: the case tests nothing"
    h = steps[0]
    p = _point(h)
    assert margin.could_flip(p)
    rerun = lambda step, eps: _point(step, eps).unstable
    reruns = [rerun(h, eps) for eps in (1e-9, 2e-9, 3e-9, 5e-9)]
    assert not all(reruns), "the perturbed runs all fail as well: the synthetic case is not chaotic"
    # classify re-runs at margin.PERTURBATION: whatever its outcome, it equals verdict() of the re-runs
    got = margin.classify(p, h, (h, 2 * h), rerun)
    expected = margin.verdict(True, [rerun(h, margin.PERTURBATION), rerun(2 * h, 0.0)])
    assert got == expected
    # a re-run that runs through makes the failed point marginal
    assert margin.classify(p, h, GRID, lambda step, eps: False) == margin.MARGINAL


def test_an_early_failure_is_unstable_without_reruns():
    p = margin.Point(unstable=True, t_end=3.0, duration=20.0, failure="StepFailure: Newton")
    assert not margin.could_flip(p)
    called = []
    assert margin.classify(p, 0.2, GRID, lambda h, e: called.append(h) or False) == margin.UNSTABLE
    assert called == []  # robust: never re-run


def test_a_late_failure_that_holds_under_perturbation_and_at_the_larger_step_stays_unstable():
    p = margin.Point(unstable=True, t_end=19.2, duration=20.0)
    asked = []

    def rerun(h, eps):
        asked.append((h, eps))
        return True  # every re-run fails too

    assert margin.classify(p, 0.2, GRID, rerun) == margin.UNSTABLE
    # own step perturbed, and the larger neighbour (a monotone map fails there too)
    assert asked == [(0.2, margin.PERTURBATION), (0.5, 0.0)]


def test_a_stable_point_near_its_bound_is_checked_at_the_smaller_step():
    # energy growth at 0.8 of its bound: within the factor 2, could flip
    p = margin.Point(unstable=False, t_end=20.0, duration=20.0, bound_ratios=(0.8, 0.1))
    assert margin.could_flip(p)
    asked = []
    assert margin.classify(p, 0.1, GRID, lambda h, e: asked.append((h, e)) or h < 0.1) == margin.MARGINAL
    assert asked == [(0.1, margin.PERTURBATION), (0.05, 0.0)]
    # far from every bound: not re-run
    far = margin.Point(unstable=False, t_end=20.0, duration=20.0, bound_ratios=(0.01, 0.2))
    assert not margin.could_flip(far)


def test_neighbour_steps_of_the_grid():
    assert margin.neighbour_steps(0.2, GRID) == [0.1, 0.5]
    assert margin.neighbour_steps(0.05, GRID) == [0.1]
    assert margin.neighbour_steps(0.3, GRID) == []
    assert np.isclose(margin.PERTURBATION, 1e-9)


def test_spin_map_reruns_a_completed_point_near_L_and_keeps_its_verdict(monkeypatch):
    """The spin map's candidate rule (spin.spin_verdict): a completed run whose peak deflection is 0.95 L
    (the shipped map's 1 SE linear at 8 rad/s: 7.567 m of 8 m) is re-run perturbed and at the slower
    neighbour spin; an early failure (at 40 % of the run) and a run far below L are not re-run."""
    from ffrf_fmu.studies.stability import spin

    calls = []

    class Run:
        unstable = False

    monkeypatch.setattr(spin, "spin_model_run", lambda path, scene, w, n, terms, s, eps: calls.append((w, eps)) or Run())
    s = spin.SpinSettings(omegas=(4.0, 6.0, 8.0, 10.0), duration=10.0)
    row = {"omega": 8.0, "superelements": 1, "terms": "linear", "unstable": False, "t_end": 10.0, "max_deflection": 7.567}
    assert spin.spin_verdict("m.toml", "s", row, s, 8.0) == margin.STABLE
    assert calls == [(8.0, margin.PERTURBATION), (6.0, 0.0)]
    Run.unstable = True  # the re-runs fail: the point is marginal
    assert spin.spin_verdict("m.toml", "s", row, s, 8.0) == margin.MARGINAL
    calls.clear()
    early = {**row, "unstable": True, "t_end": 4.0, "max_deflection": 8.0004}
    far = {**row, "max_deflection": 1.0}
    assert spin.spin_verdict("m.toml", "s", early, s, 8.0) == margin.UNSTABLE
    assert spin.spin_verdict("m.toml", "s", far, s, 8.0) == margin.STABLE and calls == []


def test_cosim_compare_gives_the_bound_ratio_of_a_completed_run():
    """cosim.compare's `bound_ratio` (the margin check's input): a completed run's largest value over
    bound of the instability tests; a run that follows its reference is far below 1, one whose torque
    reaches 8x the monolithic peak (bound 10x) is within the factor 2 of margin.py, and a stopped run has
    none (its time decides)."""
    from ffrf_fmu.studies.stability.case import CosimRun
    from ffrf_fmu.studies.stability.cosim import TORQUE_BLOWUP, compare

    t = np.linspace(0.0, 10.0, 1001)
    ref = CosimRun(t, 0.1 * np.sin(t), np.ones_like(t), np.sin(t), "", 1.0)
    same = compare(ref, ref, 8.0, 1.0)
    # the largest ratio is the torque's, 1 / TORQUE_BLOWUP (deflection 0.1 m of L = 8 m: 0.0125; no growth: 0)
    assert same["verdict"] == "stable" and abs(same["bound_ratio"] - 1.0 / TORQUE_BLOWUP) < 1e-6
    assert not margin.could_flip(margin.Point(False, 10.0, 10.0, bound_ratios=(same["bound_ratio"],)))
    big = CosimRun(t, ref.deflection, ref.speed, 0.8 * TORQUE_BLOWUP * np.sin(t), "", 1.0)
    r = compare(big, ref, 8.0, 1.0)
    assert not r["unstable"] and margin.could_flip(margin.Point(False, 10.0, 10.0, bound_ratios=(r["bound_ratio"],)))
    stopped = CosimRun(t[:500], ref.deflection[:500], ref.speed[:500], ref.torque[:500], "beam: doStep failed", 1.0)
    assert np.isnan(compare(stopped, ref, 8.0, 1.0)["bound_ratio"])
