"""Whole runs on the C runtime (backend "native", runtime/native) against the numpy path, taking the same
Newton decisions.

Each run is stepped on the C runtime one step per call, recording what its Newton decided (the
iterations and the iterations at which it built the iteration matrix: the C body's `refreshed`); the
numpy run then replays those decisions (GeneralizedAlpha.newton_replay) instead of taking its own, so
that a convergence or refresh test that round-off tips (a compiled step flipped one of 301 steps of the
coned beam) cannot make the compared runs differ by more than round-off, and the comparison
is tight: 1e-10 of each kinematic output field's largest value over all ports (r, R, v, w), as
tests/test_backends.py argues for the C runtime's communication steps. The decisions themselves are checked: along the
replayed run the numpy path still evaluates its own rules and logs every decision they would take
otherwise (NewtonReplay.disagreements), so a C Newton policy that differs from runtime/newton.py's
(a threshold, the refresh rule REFRESH_AFTER, the serves verdict) fails the test.
Reaction loads (f, t) are residual rows at the last evaluated iterate, one increment before the accepted
one: their round-off passes through the ill-conditioned iteration matrix (condition ~1e11 on B1), so
they get test_backends.py's 2e-6 of their field's largest value; the energies 1e-9 of the largest. So do
the accelerations a, dw (accel.c against runtime/accelerations.py): they are made of the rates vdot of the
last increment, the dynamic rows' unknowns, whose round-off passes through the same matrix (measured: at
most 3.3e-8 of their field's largest value, tip.a of disk_rotor-full; 1.6e-9 on B1).

The C runs go through all three ways the body steps: a scene's schedule evaluated in C
(BodySystem.run_schedule, one step per call), the inputs given per step (BodySystem.step, as a free
body's run does) and an FMU's point values extrapolated in C (BodySystem.run_extrapolated).
"""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_scene_body
from ffrf_fmu.runtime import input_rule
from ffrf_fmu.runtime.newton import NewtonDecisions, NewtonReplay

COMPLIANT_B5 = [  # B5 (haug_beam hub_free) with the hub shaft as a compliant rotation, its far end driven
    'scenes.hub_free.causality.hub.rotation="compliant"',
    "body.ports.hub.coupling={ rotational_stiffness = [0.0, 0.0, 300.0], rotational_damping = [0.0, 0.0, 0.0] }",
    'scenes.hub_free.drives.hub.rotation={ axis = [0.0, 0.0, 1.0], angle = { kind = "haug_spinup", omega = 4.0, T = 7.5 } }',
    "scenes.hub_free.step=0.01", "scenes.hub_free.duration=3.0",
]
# (model, scene, overrides, how the C run takes its inputs): a few hundred steps into each benchmark
RUNS = {
    "B1": ("models/haug_beam.toml", "spinup", ["superelements=2", "step=0.01", "duration=3.0"], "schedule"),
    "B1-stiffening-gyroscopic": ("models/haug_beam.toml", "spinup", ["superelements=2", "stiffening=true", "terms=gyroscopic",
                                                                      "step=0.01", "duration=2.0"], "schedule"),
    "B2": ("models/spherical_beam.toml", "torque_then_tip", ["duration=3.0"], "schedule"),
    "B4": ("models/free_beam.toml", "tumble", ["terms=gyroscopic", "duration=0.6"], "given"),
    "coned-full-W2-coriolis": ("models/coned_beam.toml", "spinup", ["terms=full", 'full_terms=["inertia_W2", "coriolis"]',
                                                                    "duration=3.0"], "schedule"),
    # the spin-up in 2 s instead of 20: at 4 s of the 20 s spin-up the tip's speed is 1.2 mm/s, and the runs'
    # round-off floor of ~3e-12 m/s (2.2e-9 of it) is not 1e-10 of that
    "disk_rotor-full": ("models/disk_rotor.toml", "spinup", ["terms=full", "duration=4.0", "scenes.spinup.drives.hub.rotation.angle="
                                                             '{ kind = "haug_spinup", omega = 0.9, T = 2.0 }'], "schedule"),
    "B5-compliant": ("models/haug_beam.toml", "hub_free", COMPLIANT_B5, "schedule"),
    # a solid stiffened from its mesh (membrane tensors r = n = 22), spun up to 300 rad/s in 40 ms
    "plate-stiffening-full": ("models/plate.toml", "spin_kick", ["terms=full", "duration=0.06", "scenes.spin_kick.drives.hub."
                                                                 'rotation.angle={ kind = "haug_spinup", omega = 300.0, T = 0.04 }'],
                              "schedule"),
    "B5-compliant-extrapolated": ("models/haug_beam.toml", "hub_free", COMPLIANT_B5, "extrapolated"),
}
KINEMATIC, LOADS = ("r", "R", "v", "w"), ("f", "t", "a", "dw")  # a, dw: from the solved rates (accel.c)
POINT_STEPS = 5  # internal steps per communication step of the extrapolated-input runs


def _scene(name):
    path, scene, overrides, how = RUNS[name]
    model = load_model(path, overrides)
    sc = model.scene(scene)
    body = reduce_scene_body(model.body, sc).data
    return model, sc, body, how


def _decisions(system) -> NewtonDecisions:
    """The Newton decisions of the C body's last step (its `refreshed` bits and iterations)."""
    bits = int(system._compiled.body.get("refreshed"))
    return NewtonDecisions(system.iterations, frozenset(i + 1 for i in range(64) if bits >> i & 1))


def _native_run(model, sc, body, how, n):
    """(rows, times, decisions) of n steps on the C runtime, one step per call."""
    s, inputs = sim.build_system(body, sc, model.body.origin, "native")
    assert s.backend == "native", s.backend_note
    rows, times = np.empty((n + 1, sim.record(s).size)), np.zeros(n + 1)
    rows[0] = sim.record(s)
    schedule = sim.scene_schedule(body, sc)
    decisions = []
    for k in range(n):
        if how == "schedule":
            done, exc = s.run_schedule(sc.step, schedule, rows[k + 1 : k + 2], times[k + 1 : k + 2])
            assert exc is None and done == 1, exc
        elif how == "given":
            s.step(sc.step, inputs)
            rows[k + 1], times[k + 1] = sim.record(s), s.t
        else:  # extrapolated: the point values at t_c, extrapolated over POINT_STEPS steps
            t_c = (k // POINT_STEPS) * POINT_STEPS * sc.step
            s.run_extrapolated(sc.step, 1, t_c, input_rule.point_values(body.ports, inputs(t_c)), rows[k + 1])
            times[k + 1] = s.t
        decisions.append(_decisions(s))
    return rows, times, decisions


def _numpy_run(model, sc, body, how, n, decisions):
    """(rows, times, the decisions its own rules would have taken otherwise) of n steps on the numpy path
    replaying the C run's Newton decisions."""
    s, inputs = sim.build_system(body, sc, model.body.origin, "numpy")
    assert s.backend == "numpy"
    s.newton_replay = NewtonReplay(iter(decisions))
    rows, times = np.empty((n + 1, sim.record(s).size)), np.zeros(n + 1)
    rows[0] = sim.record(s)
    for k in range(n):
        if how == "extrapolated":
            t_c = (k // POINT_STEPS) * POINT_STEPS * sc.step
            s.step(sc.step, input_rule.extrapolate(body.ports, input_rule.point_values(body.ports, inputs(t_c)), t_c))
        else:
            s.step(sc.step, inputs)
        rows[k + 1], times[k + 1] = sim.record(s), s.t
    return rows, times, s.newton_replay.disagreements


@pytest.mark.parametrize("name", list(RUNS))
def test_native_run_matches_numpy_with_the_same_newton_decisions(name):
    model, sc, body, how = _scene(name)
    n, _ = sim.whole_steps(sc.duration, sc.step)
    assert n >= 200
    fast, t_fast, decisions = _native_run(model, sc, body, how, n)
    ref, t_ref, disagreements = _numpy_run(model, sc, body, how, n, decisions)
    # the C run's policy is the numpy path's: its decisions are those the numpy rules take along the replayed
    # run, but for a test that round-off tips (none measured in these runs; a compiled step flipped one of 301 steps of the coned beam, module doc)
    assert len(disagreements) <= 2, disagreements
    # the decisions cover both branches of modified Newton: matrices built and matrices kept
    refreshes = sum(len(d.refreshed) for d in decisions)
    assert 0 < refreshes < sum(d.iterations for d in decisions)
    np.testing.assert_array_equal(t_fast, t_ref)  # one addition of h per step on both
    names = sim.column_names(body)
    np.testing.assert_array_equal(fast[:, names.index("solver.newton_iterations")], ref[:, names.index("solver.newton_iterations")])
    for fld in KINEMATIC + LOADS:
        cols = {p.name: [names.index(v) for v in sim.variable_names(p.name) if v.startswith(f"{p.name}.{fld}[")] for p in body.ports}
        scale = max(np.abs(ref[:, c]).max() for c in cols.values())
        rtol = 1e-10 if fld in KINEMATIC else 2e-6
        for port, c in cols.items():
            assert c, (port, fld)
            err = np.abs(fast[:, c] - ref[:, c]).max()
            assert err <= rtol * max(scale, 1e-300), (port, fld, err / max(scale, 1e-300))
    energy = [names.index(f"energy.{k}") for k in sim.ENERGIES]
    peak = np.abs(ref[:, energy]).max()
    assert np.abs(fast[:, energy] - ref[:, energy]).max() <= 1e-9 * peak


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
    # logged: that accept and, where the step ran on a kept matrix that served, the refresh its own rule then takes at
    # the extra iteration (runtime/newton.py `_newton`: a trusted matrix not accepted serves no more), in that step only
    log = s.newton_replay.disagreements
    assert 1 <= len(log) <= 2 and "accept False replayed, True" in log[0], log
    assert all(entry.split(",")[0] == log[0].split(",")[0] for entry in log) and all("refresh False replayed, True" in e for e in log[1:]), log
    s, inputs = sim.build_system(body, sc, model.body.origin, "numpy")
    s.newton_replay = NewtonReplay(iter([NewtonDecisions(2, frozenset())]))  # the first step has no matrix to keep
    with pytest.raises(ValueError, match="kept a matrix"):
        s.step(sc.step, inputs)


SANITIZED = ("coned-full-W2-coriolis", "B5-compliant-extrapolated")  # `full` with W2 and Coriolis; springs and held inputs


def test_sanitized_runtime_runs_two_scenes(tmp_path):
    """The runtime built with -fsanitize=address,undefined (runtime/native/build.py; the undefined-behaviour
    checks abort, not recover) steps two scenes in a process of its own (libasan preloaded; leak checks off:
    the interpreter's own allocations at exit are no finding): no report, and the same rows, bit for bit,
    as the optimized build's (both -O2 -ffp-contract=off: the instrumentation changes no arithmetic)."""
    from ffrf_fmu.runtime.native import build

    try:
        build.library(sanitize=True)
        preload = build.sanitizer_preload()
    except build.BuildError as e:
        pytest.skip(f"no sanitizer build here: {e}")
    if not os.path.isfile(preload):
        pytest.skip(f"the compiler has no libasan ({preload!r})")
    script = textwrap.dedent(f"""
        import functools, sys
        import numpy as np
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        import test_native_runs as T
        from ffrf_fmu.runtime.native import binding
        binding.native_step = functools.partial(binding.native_step, sanitize=True)  # what BodySystem calls
        for name in {SANITIZED!r}:
            model, sc, body, how = T._scene(name)
            rows, times, decisions = T._native_run(model, sc, body, how, 150)
            assert True in binding._LIB and False not in binding._LIB  # the sanitized library only
            np.save({str(tmp_path)!r} + "/" + name + ".npy", rows)
        print("done")
    """)
    env = dict(os.environ, LD_PRELOAD=preload, ASAN_OPTIONS="detect_leaks=0:abort_on_error=1",
               UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1")
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0 and done.stdout.strip().endswith("done"), done.stderr[-4000:]
    assert "runtime error" not in done.stderr and "Sanitizer" not in done.stderr, done.stderr[-4000:]
    for name in SANITIZED:
        model, sc, body, how = _scene(name)
        rows, _, _ = _native_run(model, sc, body, how, 150)
        np.testing.assert_array_equal(np.load(tmp_path / f"{name}.npy"), rows)
