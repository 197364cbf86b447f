"""Facts with one home: the split of a span into steps (runtime/steps.py), the names and layout of a
time-series row and eq. (92) (runtime/outputs.py), a scene's spin (spin.py). Each is tested here
once; the callers are tested through their own results."""
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.model import load_model
from ffrf_fmu.runtime.outputs import ENERGY_FIELDS, OUTPUT_WIDTH, row_columns, tip_from_hub
from ffrf_fmu.runtime.rotation import expm
from ffrf_fmu.runtime.steps import STEP_COUNT_TOLERANCE, communication_grid, divides, whole_steps
from ffrf_fmu.spin import scene_spin

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("span, step, n", [
    (10.0, 1e-3, 10_000),  # whole
    (0.3, 0.1, 3),  # 0.3 / 0.1 = 2.9999999999999996 in floating point: still 3 steps
    (0.009, 0.002, 5),  # 4.5 steps: reduced to 5 of 1.8 ms, never 4 of 2 ms plus a sliver
    (1e-4, 1e-3, 1),  # a span shorter than the step: one step of the span
    (1.0 + 0.5e-6, 0.1, 10),  # 5e-7 of a step over 10 steps: inside the tolerance
    (1.0 + 2e-5, 0.1, 11),  # 2e-4 of a step over 10 steps: outside, one step more
])
def test_whole_steps(span, step, n):
    steps = whole_steps(span, step)
    assert steps.n == n and steps.h == pytest.approx(span / n, rel=1e-15)
    assert steps.n * steps.h == pytest.approx(span, rel=1e-15)  # the last step ends at the span
    assert steps.h <= step * (1 + STEP_COUNT_TOLERANCE)
    assert divides(span, step) == (abs(span / step - n) <= STEP_COUNT_TOLERANCE * span / step)


def test_communication_points_of_a_long_run_split_as_whole_steps():
    """A master's step H = t_{k+1} - t_k at t = 1e4 s differs from k H by round-off at the size of t:
    still n whole internal steps."""
    t0 = 1e4
    H = (t0 + 1e-3) - t0  # 1e-3 up to 1.8e-12 s
    assert H != 1e-3 and whole_steps(H, 1e-4).n == 10 and divides(H, 1e-4)


@pytest.mark.parametrize("span, H, points", [
    (0.3, 0.1, [0.0, 0.1, 0.2, 0.3]),  # 0.3 / 0.1 = 2.9999999999999996: three whole steps, ending on 0.3
    (0.25, 0.1, [0.0, 0.1, 0.2, 0.25]),  # 2.5 steps: a shorter last one
    (0.26, 0.1, [0.0, 0.1, 0.2, 0.26]),  # 2.6 steps: never a point past the span (rounding gave 0.3)
    (0.05, 0.1, [0.0, 0.05]),  # a span shorter than H: one step
])
def test_communication_grid(span, H, points):
    """A master's grid at a fixed H (fmu/run.py): k H, then the span's end, never past it."""
    grid = communication_grid(span, H)
    assert grid == pytest.approx(points, rel=1e-15, abs=1e-15) and grid[-1] == span


@pytest.mark.parametrize("span, step", [(0.0, 1e-3), (1.0, 0.0), (-1.0, 1e-3), (1.0, float("nan"))])
def test_whole_steps_refuses_what_cannot_be_split(span, step):
    with pytest.raises(ValueError, match="cannot be split into steps"):
        whole_steps(span, step)


def test_row_columns_are_the_rows_of_the_body():
    """A row: 30 columns per port (r, R row-major, v, w, f, t, a, dw), the energies, the Newton iterations;
    BodySystem.output_row has exactly that many values. The FMU variables of a port come in the same
    field order as the row's columns."""
    from ffrf_fmu import simulate as sim
    from ffrf_fmu.reduction import reduce_scene_body

    model = load_model(ROOT / "models/haug_beam.toml", ["superelements=1", "modes=2"])
    scene = model.scene("spinup")
    body = reduce_scene_body(model.body, scene).data
    names = row_columns([p.name for p in body.ports])
    assert OUTPUT_WIDTH == 30 and len(names) == 30 * len(body.ports) + len(ENERGY_FIELDS) + 1
    assert names[:4] == ["hub.r[1]", "hub.r[2]", "hub.r[3]", "hub.R[1,1]"] and names[-1] == "solver.newton_iterations"
    system, _ = sim.build_system(body, scene, backend="numpy")
    assert len(system.output_row()) == len(names) == len(sim.column_names(body))
    from ffrf_fmu.fmu.variables import body_variables

    params = {"step": 0.01, "rho_inf": 0.9, "gravity": [0.0] * 3, "terms": "linear", "initial_velocity": [0.0] * 3,
              "initial_angular_velocity": [0.0] * 3, "port_displacements": {}}
    hub = [v.name for v in body_variables(body.ports, body.node_positions, params) if v.name.startswith("hub.")]
    assert hub == names[:OUTPUT_WIDTH]


def test_tip_from_hub_eq92():
    """A rigid motion of hub and tip together (any rotation R, any translation) leaves d = 0; an
    elastic displacement e given in the hub's axes comes back as e, one instant or a series."""
    rng = np.random.default_rng(3)
    X = np.array([8.0, 0.0, 0.0])
    R = np.stack([expm(rng.normal(size=3)) for _ in range(5)])
    x_hub = rng.normal(size=(5, 3))
    e = rng.normal(size=(5, 3)) * 1e-2
    x_tip = x_hub + np.einsum("nij,nj->ni", R, X + e)
    assert np.allclose(tip_from_hub(R, x_hub, x_tip, X), e, atol=1e-14)
    assert np.allclose(tip_from_hub(R[2], x_hub[2], x_tip[2], X), e[2], atol=1e-14)
    rigid = x_hub + np.einsum("nij,nj->ni", R, np.broadcast_to(X, (5, 3)))
    assert np.abs(tip_from_hub(R, x_hub, rigid, X)).max() < 1e-14


def test_scene_spin_is_read_the_same_by_info_the_term_rule_and_the_advisor():
    """B1's spin-up reaches omega = 4 rad/s at T = 15 s (a grid point): the peak is exact; info
    (invariants.scene_spin) and the advisor (indicators.spin_history) read the one history."""
    from ffrf_fmu.invariants import scene_spin as info_spin
    from ffrf_fmu.studies.indicators import spin_history

    model = load_model(ROOT / "models/haug_beam.toml")
    scene = model.scene("spinup")
    s = scene_spin(scene)
    assert s.peak == pytest.approx(4.0, rel=1e-12) and s.port == "hub" and np.allclose(s.axis, [0, 0, 1])
    rate, axis, source = info_spin(scene)
    assert rate == s.peak and np.array_equal(axis, s.axis) and source == s.source
    t, r, acc, axis, source = spin_history(scene)
    assert np.array_equal(r, s.rate) and np.array_equal(t, s.t)
    # the acceleration is the rate's time derivative: central differences on the 2 ms grid are off by
    # h^2/6 max|d3 rate/dt3| = (2e-3)^2/6 (4/15) (2 pi/15)^2 = 3e-8 rad/s^2; 1e-6 leaves round-off room
    assert np.allclose(np.gradient(s.rate, s.t)[1:-1], s.acceleration[1:-1], rtol=0, atol=1e-6)
    assert scene_spin(model.scene("hub_free")) is None and info_spin(model.scene("hub_free")) == (None, None, "none")


def test_the_native_fmu_start_checks_are_the_python_ones():
    """The FMU's C checks of a start state (fmu/native: model.c, initialize.c) carry the tolerances and the
    state names of runtime/start.py and model.py as literals (C has no import); they must be the same
    numbers, or an FMU would accept a start the standalone run refuses (or the reverse)."""
    import re

    from ffrf_fmu.model import INITIAL_STATES
    from ffrf_fmu.runtime.start import GRAVITY_TOL, MOTION_TOL

    native = ROOT / "ffrf_fmu" / "fmu" / "native"
    model_c, initialize_c = (native / "model.c").read_text(), (native / "initialize.c").read_text()

    def define(text, name):
        return float(re.search(rf"#define {name} (\S+)", text).group(1))

    assert define(model_c, "START_GRAVITY_TOL") == GRAVITY_TOL
    assert define(initialize_c, "START_MOTION_TOL") == MOTION_TOL
    states = re.search(r"STATES\[\d+\] = \{([^}]*)\}", model_c).group(1)
    assert tuple(s.strip().strip('"') for s in states.split(",")) == INITIAL_STATES
