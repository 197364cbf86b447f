"""Initial states ([scenes.NAME.initial] state, ffrf_fmu/initial_state.py): a scene starts at the static
equilibrium under gravity and its loads, or at the steady spin of its rotation drive, instead of the
undeformed body released into a transient."""
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.model import ModelError, load_model

SCENES = """
[scenes.sag]
duration = 1.0
step = 0.01
rho_inf = 0.8
gravity = [0.0, 0.0, -9.81]
[scenes.sag.metrics]
kind = "tip_deflection"
[scenes.sag.initial]
state = "static"
[[scenes.sag.loads]]
port = "tip"
force = [0.0, 0.0, -0.05]
[scenes.spin]
duration = 1.0
step = 0.005
rho_inf = 0.8
stiffening = true
gravity = [0.0, 0.0, 0.0]
[scenes.spin.metrics]
kind = "tip_deflection"
[scenes.spin.initial]
state = "steady_spin"
[scenes.spin.drives.hub.rotation]
axis = [0.0, 0.0, 1.0]
angle = { kind = "ramp", rate = 4.0, t_start = -1.0 }
"""


@pytest.fixture
def model(tmp_path, beam_toml):
    path = tmp_path / "b.toml"
    path.write_text(beam_toml(SCENES, superelements=2, elements=8))
    return str(path)


def _tip(model, scene, *overrides):
    from ffrf_fmu.simulate import elastic_tip, run_scene

    r = run_scene(model, scene, list(overrides), backend="numpy")
    return elastic_tip(r, "hub", "tip")


def test_static_start_stays_at_rest_and_matches_the_linear_chain(model):
    """Gravity along -Z and a 0.05 N tip load, started "static": the tip does not move over the run (to
    1e-10 m: the integrator starts in equilibrium); from rest the same scene swings by about twice its
    deflection. The tip load alone deflects it as the chain's linear statics (linear.static_displacements)
    to 1e-3 (its 0.2 % of L leaves a small geometric nonlinearity)."""
    from ffrf_fmu.linear import static_displacements
    from ffrf_fmu.reduction import reduce_scene_body

    d = _tip(model, "sag")
    assert np.ptp(d, axis=0).max() < 1e-10
    m = load_model(model)
    sc = m.scene("sag")
    data = reduce_scene_body(m.body, sc).data
    d_load = _tip(model, "sag", "scenes.sag.gravity=[0, 0, 0]")
    u = static_displacements(data, {data.port("tip").node: np.array([0, 0, -0.05, 0, 0, 0])})
    assert d_load[0, 2] == pytest.approx(u[-1, 2], rel=1e-3)
    swing = np.ptp(_tip(model, "sag", "scenes.sag.initial.state=rest")[:, 2])
    assert swing > 1.5 * abs(d[0, 2])


def test_steady_spin_start_is_the_relative_equilibrium(model):
    """A hub spinning at 4 rad/s from before t = 0 (a ramp from -1 s), started "steady_spin": the body
    starts stretched by the centrifugal load as linear.steady_spin finds it, and stays there up to the
    integrator's O(h^2) transient of a circular motion in world coordinates (measured tip range 4.7e-4 m
    at 5 ms, 1.2e-4 m at 2.5 ms, 1.9e-3 m at 10 ms); from rest the same drive shakes the tip by 4 x more."""
    from ffrf_fmu.linear import steady_spin
    from ffrf_fmu.reduction import reduce_scene_body
    from ffrf_fmu.runtime.body import BodySystem

    d = _tip(model, "spin")
    m = load_model(model)
    data = reduce_scene_body(m.body, m.scene("spin")).data
    s = steady_spin(BodySystem(data, terms="linear"), 4.0)
    stretch = (s.xN[-1] - data.node_positions[-1])[0]
    assert d[0, 0] == pytest.approx(stretch, rel=1e-6) and abs(d[0, 1]) < 1e-12
    settled = np.ptp(d, axis=0).max()
    assert settled < 6e-4
    assert np.ptp(_tip(model, "spin", "scenes.spin.initial.state=rest"), axis=0).max() > 4 * settled


def test_initial_state_errors(model, tmp_path, beam_toml):
    with pytest.raises(ModelError, match="state"):
        load_model(model, ["scenes.sag.initial.state=falling"])
    with pytest.raises(ModelError, match="no port_displacements, velocity or angular_velocity"):
        load_model(model, ["scenes.sag.initial.velocity=[1, 0, 0]"])
    # what a steady-spin start needs of the scene is checked as the file is read, naming the key
    with pytest.raises(ModelError, match=r"scenes.spin.initial.state: .*spin steadily"):  # a spin-up starts at rate 0
        load_model(model, ['scenes.spin.drives.hub.rotation.angle={kind = "haug_spinup", omega = 4.0, T = 1.0}'])
    with pytest.raises(ModelError, match=r"scenes.sag.initial.state: .*'steady_spin' needs a rotation drive"):
        load_model(model, ['scenes.sag.initial.state="steady_spin"'])
    with pytest.raises(ModelError, match=r"scenes.sag.initial.state: state 'static' is not available with compliant "
                                         r"ports \(compliant in this scene: \['hub'\]\)"):
        load_model(model, ['scenes.sag.causality.hub={rotation = "compliant"}', "body.ports.hub.coupling={step = 0.01}"])


def test_reference_starts_static_too(model):
    """The full-order beam starts at its own static equilibrium for state "static" (reference.static_reference
    under gravity and the loads at t = 0): its tip moves by 4.5e-4 m over the run (measured, 2.6e-4 of its
    1.73 m deflection under this heavy gravity: the static and dynamic loads' lumping of the rotary terms),
    against a swing of about twice the deflection from rest."""
    from ffrf_fmu.reference.solver import simulate_reference, tip_from_hub

    m = load_model(model)
    sc = m.scene("sag")
    d = tip_from_hub(simulate_reference(m.body, sc, n_elements=16), "hub", "tip")
    assert np.ptp(d, axis=0).max() < 1e-3 * abs(d[0, 2])


ROTOR = str(Path(__file__).resolve().parent.parent / "models" / "sagging_rotor.toml")
STEADY = ["scenes.lag_kick.loads=[]", "scenes.lag_kick.duration=1.0"]  # the bundled scene's start, no kick


def test_reference_starts_at_the_steady_spin():
    """The full-order beam started "steady_spin" (reference/steady.py: the relative equilibrium at 2 rad/s
    under gravity along the spin axis, sagged by 0.1227 m) stays there: over 1 s the elastic tip moves by
    3.8e-5 m at h = 5 ms and 9.5e-6 m at 2.5 ms (measured): the O(h^2) transient of the discrete scheme's
    circular motion in world coordinates (docs/model-format.md, initial state), a quarter per halving."""
    from ffrf_fmu.reference.solver import simulate_reference, tip_from_hub

    m = load_model(ROTOR, STEADY)
    ranges = []
    for h in (0.005, 0.0025):
        d = tip_from_hub(simulate_reference(m.body, m.scene("lag_kick"), n_elements=16, step=h), "root", "tip")
        ranges.append(np.ptp(d, axis=0).max())
    assert d[0, 2] == pytest.approx(-0.1227, abs=5e-4)
    assert ranges[0] < 5e-4 * abs(d[0, 2])
    assert 0.2 < ranges[1] / ranges[0] < 0.3


def test_reference_and_reduced_chain_share_the_steady_spin():
    """The steady sag of the sagging rotor (2 rad/s, gravity along the axis): the reduced chain started
    "steady_spin" (initial_state.settle) converges to the full-order beam's (32 elements) as superelements
    are added: measured +1.04 % (1 SE), +0.37 % (2), +0.10 % (4), +0.024 % (8) (docs/accuracy.md, "Out of
    sample: the sagging rotor": what one superelement's linear kinematics miss of a sagged, spun arm)."""
    from ffrf_fmu.reference.solver import simulate_reference, tip_from_hub
    from ffrf_fmu.simulate import elastic_tip, run_scene

    short = ["scenes.lag_kick.loads=[]", "scenes.lag_kick.duration=0.01", "step=0.005"]
    m = load_model(ROTOR, short)
    ref = tip_from_hub(simulate_reference(m.body, m.scene("lag_kick"), n_elements=32), "root", "tip")[0, 2]
    errors = {n: elastic_tip(run_scene(ROTOR, "lag_kick", [*short, f"superelements={n}"]), "root", "tip")[0, 2] / ref - 1
              for n in (2, 8)}
    assert 0 < errors[8] < 0.0005 and 0 < errors[2] < 0.0045
