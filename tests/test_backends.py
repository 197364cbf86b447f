"""The C runtime (backend native, runtime/native) against the numpy reference backend where an FMU
uses it (communication steps from point values), state and snapshot round trips, and the fallback when
the C runtime cannot be compiled. Whole runs of every bundled benchmark, with the numpy run replaying
the C run's Newton decisions, are tests/test_native_runs.py.

Tolerances: 1e-10 of each output field's largest value (over all ports) for the kinematic outputs
(r, R, v, w); reaction loads are residual rows at the last evaluated Newton iterate, one increment
before the accepted one (runtime/newton.py `_newton`), differences of elastic forces of order
K_bar q through the ill-conditioned iteration matrix (condition ~1e11 on B1), so their round-off is up
to ~1e-6 of their own size: 2e-6 for them. The extrapolated-input runs are chosen so that no convergence test
sits at its threshold (there round-off can flip an iteration count).
"""
from __future__ import annotations

import logging

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_body, reduce_scene_body
from ffrf_fmu.runtime import input_rule
from ffrf_fmu.runtime.outputs import FIELD_COLUMNS, OUTPUT_WIDTH
from ffrf_fmu.runtime.body import BodySystem

EXTRAPOLATED_RUNS = {  # 1 s of each scene in communication steps of 5 internal steps
    "B1": ("models/haug_beam.toml", "spinup", ["superelements=2", "step=0.01", "duration=3.0"]),
    "B1-compliant": ("models/haug_beam.toml", "spinup", [
        'body.ports.hub.translation="compliant"', 'body.ports.hub.rotation="compliant"', "superelements=2",
        'body.ports.hub.coupling={ stiffness = [1e5, 2e5, 3e5], damping = [400.0, 500.0, 600.0], '
        'rotational_stiffness = [1e4, 2e4, 3e4], rotational_damping = [40.0, 50.0, 60.0] }', "step=0.01", "duration=2.0"]),
    "B1-full-stiffening-W2": ("models/haug_beam.toml", "spinup", ["superelements=2", "terms=full", 'full_terms=["inertia_W2"]',
                                                                  "stiffening=true", "step=0.01", "duration=3.0"]),
}
KINEMATIC, LOADS = ("r", "R", "v", "w"), ("f", "t")



@pytest.mark.parametrize("name", list(EXTRAPOLATED_RUNS))
def test_extrapolated_inputs_in_the_runtime_match_the_numpy_twin(name):
    """An FMU's communication step in ONE call of the C runtime (BodySystem.run_extrapolated on native: the inputs
    extrapolated from the point values inside it, advance.c ffrf_extrapolated_inputs) against one step call per
    internal step with their numpy twin runtime/input_rule.extrapolate (numpy backend): 1e-10 of the kinematic
    outputs, 2e-6 of the loads and the accelerations (both set by the Newton tolerance: module docstring), equal iterations; 5 internal steps per
    communication step, so that the extrapolation spans several steps, over 1 s of the scene. The
    factorization of the last step is handed back to the body (the next call starts from it), built at
    the same step as numpy's (the first CM frame it was built at, to 1e-10: a step apart they differ by
    ~1e-5) and with the same verdict whether it serves the next step (integrator `_newton`)."""
    path, scene, overrides = EXTRAPOLATED_RUNS[name]
    model = load_model(path, overrides)
    sc = model.scene(scene)
    body = reduce_scene_body(model.body, sc).data
    n, h = 5, sc.step
    runs, lus = {}, {}
    for backend in ("numpy", "native"):
        s, inputs = sim.build_system(body, sc, model.body.origin, backend)
        rows, worst = [], []
        for k in range(int(round(1.0 / (n * h)))):
            t_c = k * n * h
            row = np.empty(sim.record(s).size)
            worst.append(s.run_extrapolated(h, n, t_c, input_rule.point_values(body.ports, inputs(t_c)), row))
            s.t = t_c + n * h  # the master's clock (fmu/core.py)
            rows.append(row)
        assert s.backend == backend
        if backend == "native":
            assert s._lu[0] is s._compiled._lu_out
        runs[backend] = (np.array(rows), worst)
        lus[backend] = s._lu
    (ref, w_ref), (fast, w_fast) = runs["numpy"], runs["native"]
    assert w_fast == w_ref
    np.testing.assert_allclose(lus["native"][3], lus["numpy"][3], rtol=0, atol=1e-10)
    assert lus["native"][4] == lus["numpy"][4]
    np.testing.assert_array_equal(fast[:, -1], ref[:, -1])
    P, W = len(body.ports), OUTPUT_WIDTH
    for field, cols in FIELD_COLUMNS.items():
        a = ref[:, : W * P].reshape(len(ref), P, W)[:, :, cols]
        b = fast[:, : W * P].reshape(len(fast), P, W)[:, :, cols]
        rtol = 1e-10 if field in KINEMATIC else 2e-6
        assert np.abs(a - b).max() <= rtol * max(np.abs(a).max(), 1e-300), field
    peak = np.abs(ref[:, W * P : W * P + 4]).max()
    assert np.abs(fast[:, W * P : W * P + 4] - ref[:, W * P : W * P + 4]).max() <= 1e-9 * peak


def test_state_round_trips_between_bodies():
    """A state saved by one body (its factorization included) continues bit-for-bit the same way in
    another body restored from it; a numpy body given that state, whose factorization is the C
    runtime's (runtime/factorization.py), builds its own matrix and continues to round-off."""
    model = load_model("models/haug_beam.toml", ["superelements=2"])
    sc = model.scene("spinup")
    body = reduce_body(model.body).data
    s, inputs = sim.build_system(body, sc, backend="native")
    for _ in range(50):
        s.step(sc.step, inputs)
    state = s.get_state()
    assert state[4] == 2.0  # the factorization is part of the state, marked as the C runtime's
    other = BodySystem(body, terms=sc.terms, rho_inf=sc.rho_inf, gravity=sc.gravity, backend="native")
    other.set_state(state)
    plain = BodySystem(body, terms=sc.terms, rho_inf=sc.rho_inf, gravity=sc.gravity, backend="numpy")
    plain.set_state(state)
    for _ in range(20):
        s.step(sc.step, inputs)
        other.step(sc.step, inputs)
        plain.step(sc.step, inputs)
    np.testing.assert_array_equal(other.get_state(), s.get_state())
    # within the Newton tolerance of the rates (the matrices differ): tol / beta absolute (integrator `_newton`)
    am, af, gamma = plain.coefficients
    assert np.abs(plain.yd - s.yd).max() <= plain.tol / (sc.step * gamma * af / am)


def test_a_missing_compiler_falls_back_to_numpy_with_a_note(monkeypatch, caplog):
    """Where the C runtime cannot be compiled (no compiler, a failing build), the body runs on the numpy
    path and says why, in backend_note and the log."""
    from ffrf_fmu.runtime.native import binding, build

    def no_compiler(sanitize=False):
        raise build.BuildError("no C compiler: none of cc, gcc, clang on the PATH")

    monkeypatch.setattr(binding, "load", no_compiler)
    model = load_model("models/haug_beam.toml", ["superelements=1"])
    body = reduce_body(model.body).data
    with caplog.at_level(logging.WARNING, logger="ffrf_fmu"):
        s = BodySystem(body, backend="native")
    assert s.backend == "numpy" and "no C compiler" in s.backend_note
    assert "running on numpy" in caplog.text


def test_the_retired_numba_backend_is_refused_naming_its_replacement():
    model = load_model("models/haug_beam.toml", ["superelements=1"])
    body = reduce_body(model.body).data
    with pytest.raises(ValueError, match="replaced by the C runtime: use backend 'native'"):
        BodySystem(body, backend="numba")


@pytest.mark.parametrize("backend", ["numpy", "native"])
def test_snapshot_restore_repeats_the_steps_bit_for_bit(backend):
    """BodySystem.restore(snapshot()) (an FMU's rollback) returns to the snapshot's state with its
    factorization, which the snapshot shares instead of copying: the steps after it repeat bit for bit,
    also when steps in between refreshed the factorization (a refresh makes new arrays)."""
    model = load_model("models/haug_beam.toml", ["superelements=2", "step=0.01"])
    sc = model.scene("spinup")
    body = reduce_body(model.body).data
    s, inputs = sim.build_system(body, sc, backend=backend)
    while s.t < 3.0:
        s.step(sc.step, inputs)
    snap = s.snapshot()
    first = []
    for _ in range(40):
        s.step(sc.step, inputs)
        first.append(s.get_state())
    assert s._lu[0] is not snap[1][0]  # refreshed in between
    s.restore(snap)
    for k in range(40):
        s.step(sc.step, inputs)
        np.testing.assert_array_equal(s.get_state(), first[k])
