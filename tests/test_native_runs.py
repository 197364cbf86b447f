"""The Newton replay of runtime/integrator.py (GeneralizedAlpha.newton_replay): a run takes another run's
Newton decisions (iterations, matrix builds) and logs where its own rules would have decided otherwise.
The C runtime's whole runs are compared with the numpy path through it (the C runtime lands with its
tests here)."""
from __future__ import annotations

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import build_scene_body
from ffrf_fmu.runtime.integrator import NewtonDecisions, NewtonReplay


def _scene(name):
    path, scene, overrides = {"B1": ("models/haug_beam.toml", "spinup", ["superelements=2", "step=0.01", "duration=3.0"])}[name]
    model = load_model(path, overrides)
    sc = model.scene(scene)
    body, _ = build_scene_body(model.body, sc)
    return model, sc, body, None


def test_replay_reproduces_a_runs_own_decisions_bit_for_bit():
    """The replay hook itself: the numpy path's own decisions (its matrix builds seen as Jacobian
    evaluations), replayed, give the very same run with no disagreement logged; one step accepted an
    iteration later is taken and logged (and only that); a replay that keeps a matrix the run does not
    have is refused."""
    model, sc, body, _ = _scene("B1")
    runs = []
    for replay in (None, "own"):
        s, inputs = sim.build_system(body, sc, model.body.origin, "numpy")
        if replay is not None:
            s.newton_replay = NewtonReplay(iter(runs[0][1]))
        jac, evaluate = [], s._residual_at
        s._residual_at = lambda yd, jacobian=False, beta=None: (jac.append(jacobian), evaluate(yd, jacobian, beta))[1]
        rows, decisions = [], []
        for _ in range(100):
            jac.clear()
            it = s.step(sc.step, inputs)
            decisions.append(NewtonDecisions(it, frozenset(i + 1 for i, j in enumerate(jac) if j)))
            rows.append(sim.record(s))
        runs.append((np.array(rows), decisions))
    assert runs[0][1] == runs[1][1] and s.newton_replay.disagreements == []
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    # other decisions are taken, and logged where they differ from the run's own rules
    s, inputs = sim.build_system(body, sc, model.body.origin, "numpy")
    other = [NewtonDecisions(d.iterations + 1, d.refreshed) if k == 50 else d for k, d in enumerate(runs[0][1])]
    s.newton_replay = NewtonReplay(iter(other))
    its = [s.step(sc.step, inputs) for _ in range(60)]
    assert its == [d.iterations for d in other[:60]]
    assert len(s.newton_replay.disagreements) == 1 and "accept False replayed, True" in s.newton_replay.disagreements[0]
    s, inputs = sim.build_system(body, sc, model.body.origin, "numpy")
    s.newton_replay = NewtonReplay(iter([NewtonDecisions(2, frozenset())]))  # the first step has no matrix to keep
    with pytest.raises(ValueError, match="kept a matrix"):
        s.step(sc.step, inputs)

