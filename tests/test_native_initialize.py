"""BodySystem.initialize on the C runtime: one call of ffrf_body_initialize (runtime/native/initial.c) with the
inputs read in Python (those at t0 and those of the micro-step at t0 + 1 us), against the numpy path's steps
(runtime/initial_conditions.py, the oracle): the same state for a motion-driven spin-up started mid-drive, a
compliant hub, a free body with an initial rotation and a displaced port (the relaxation), and a load at t0;
and the same failure."""
import re
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.model import load_model, scene_body
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.runtime.ports import StepFailure
from ffrf_fmu.simulate import scene_inputs

MODELS = Path(__file__).resolve().parent.parent / "models"

CASES = {  # model, overrides, scene, t0, initialize's keywords
    "spinup mid-drive": ("haug_beam.toml", ["superelements=2", "modes=3"], "spinup", 3.7, {}),
    "compliant hub": ("haug_beam.toml", ['body.ports.hub.translation="compliant"', 'body.ports.hub.rotation="compliant"',
                                         "body.ports.hub.coupling={ step = 0.002 }", "superelements=2"], "spinup", 2.1,
                      {}),
    "tumble, displaced": ("free_beam.toml", [], "tumble", 0.0,
                          {"angular_velocity": (0.3, 0.5, 2.0), "velocity": (0.1, 0.0, -0.2), "origin": (0.5, 0.0, 0.0),
                           "port_displacements": {"b": np.array([0.0, 0.05, 0.02])}}),
}


def _pair(model, overrides, scene):
    m = load_model(MODELS / model, overrides)
    sc = m.scene(scene)
    data = reduce_body(scene_body(m.body, sc)).data
    make = lambda backend: BodySystem(data, terms=sc.terms, rho_inf=sc.rho_inf, gravity=sc.gravity,  # noqa: E731
                                      backend=backend)
    return make("native"), make("numpy"), scene_inputs(data, sc), make


@pytest.mark.parametrize("case", sorted(CASES))
def test_native_initialize_is_the_numpy_paths(case):
    """Every state field, the port loads and the power at t0 within 1e-9 of the field's scale (the C runtime's
    equations against the oracle's: 1e-12 per block, the micro-step's rates divided by its 1 us)."""
    model, overrides, scene, t0, kw = CASES[case]
    native, oracle, inputs, make = _pair(model, overrides, scene)
    assert native.backend == "native"
    for s in (native, oracle):
        s.initialize(t0, inputs, **kw)
    for k in (*BodySystem._STATE_FIELDS, "_spring_loads"):
        a, b = np.asarray(getattr(native, k)), np.asarray(getattr(oracle, k))
        assert np.abs(a - b).max() <= 1e-9 * max(np.abs(b).max(), 1.0), k
    assert native.t == oracle.t == t0 and native.work == oracle.work == 0.0 and native._lu is None
    assert native.power == pytest.approx(oracle.power, rel=1e-9, abs=1e-9)
    assert native._springs is not None and len(native._springs) == len(oracle._springs)
    # it steps on from there as the numpy path does, and starts again from the reference state after a step
    h = 0.002
    for s in (native, oracle):
        s.step(h, inputs)
    assert np.abs(native.xN - oracle.xN).max() < 1e-10
    fresh = make("native")
    for s in (native, oracle, fresh):
        s.initialize(t0 + h, inputs, **kw)
    for k in BodySystem._STATE_FIELDS:
        a, b = np.asarray(getattr(native, k)), np.asarray(getattr(oracle, k))
        assert np.abs(a - b).max() <= 1e-9 * max(np.abs(b).max(), 1.0), k
        assert np.array_equal(a, getattr(fresh, k)), k  # the same bits as a body initialized as created


def test_native_relaxation_fails_as_the_numpy_path():
    """Both ends of a free beam displaced (each held along its u only, free across it): no static shape found in
    30 iterations; both backends raise the same StepFailure, up to the last correction (a Newton that does not
    converge leaves different last corrections from round-off)."""
    native, oracle, inputs, _ = _pair("free_beam.toml", [], "tumble")
    disp = {"b": np.array([0.0, 0.05, 0.0]), "a": np.array([0.0, 0.0, 0.03])}
    words = []
    for s in (native, oracle):
        with pytest.raises(StepFailure) as e:
            s.initialize(0.0, inputs, port_displacements=disp)
        words.append(re.sub(r"last correction [^)]*", "", str(e.value)))
    assert words[0] == words[1] and "no static equilibrium" in words[0] and "['a', 'b']" in words[0]
