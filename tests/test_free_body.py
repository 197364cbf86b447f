"""A free body (B4, metrics kind 'momentum'): its CM-frame tip deflection, the mass properties and
momenta both models record, and the initial deformation both start from."""
from pathlib import Path

import numpy as np

from ffrf_fmu import simulate as sim
from ffrf_fmu.fmu.variables import port_variables
from ffrf_fmu.model import load_model, scene_body
from ffrf_fmu.reduction import reduce_scene_body
from ffrf_fmu.reference import simulate_reference
from ffrf_fmu.runtime.rotation import expm

B4 = str(Path(__file__).resolve().parent.parent / "models" / "free_beam.toml")


def _moving(body, Q, c, tip_body, J_body, h):
    """A result whose tip, CM, inertia and angular momentum follow the rotations Q (nt, 3, 3) and the CM c."""
    _, tip = sim.end_ports(body)
    r = c + np.einsum("nij,j->ni", Q, tip_body)
    cols = dict(zip(port_variables(tip, "r"), r.T))
    J = np.einsum("nij,jk,nlk->nil", Q, J_body, Q)
    cols |= sim.free_body_columns(c, J, np.zeros_like(c), np.repeat(h[None], len(c), 0))
    return sim.SimulationResult(np.linspace(0.0, 1.0, len(c)), cols, {}, body)


def test_tip_from_cm_sees_no_deflection_in_a_rigid_tumble():
    """A rigid body tumbling (any rotation, a moving CM): the tip seen from the CM frame does not move from
    the axis (exactly 0 but rounding); a body bent by a fixed amount and spinning about its angular momentum
    keeps that deflection, whatever its orientation (the frame is the body's own)."""
    m = load_model(B4)
    body = reduce_scene_body(m.body, m.scene("tumble")).data
    nt = 50
    t = np.linspace(0.0, 3.0, nt)
    Q = np.array([expm(np.array([0.3, -1.1, 2.0]) * s) @ expm(np.array([0.0, 0.7 * s, 0.0])) for s in t])
    c = np.array([1.0, -2.0, 0.5]) + np.outer(t, [0.2, 0.1, -0.3])
    J_body = np.diag([3.6e-4, 8.6, 8.6])
    rigid = _moving(body, Q, c, np.array([4.0, 0.0, 0.0]), J_body, np.array([0.0, 0.5, 2.0]))
    assert np.abs(sim.tip_from_cm(rigid)).max() < 1e-12
    n = np.array([0.0, 0.0, 1.0])  # spin about the angular momentum: the body-fixed frame's e3 = n
    Qn = np.array([expm(n * 2.1 * s) for s in t])
    bent = _moving(body, Qn, c, np.array([4.0, 0.01, -0.02]), J_body, n)
    d = sim.tip_from_cm(bent)
    assert np.allclose(d, [0.0, 0.01, -0.02], atol=1e-12)


def test_tip_from_cm_refuses_a_body_without_angular_momentum_at_the_start():
    """The CM frame's roll is set by h_cm(0): a body that starts without angular momentum has none, and
    tip_from_cm says so instead of returning NaN (0/0). A spin of 1e-6 rad/s (|h_cm(0)| / J_max, 1000 x
    NO_SPIN_RAD_S) still fixes it: the same frame as any larger spin about that axis."""
    import pytest

    m = load_model(B4)
    body = reduce_scene_body(m.body, m.scene("tumble")).data
    t = np.linspace(0.0, 1.0, 20)
    Q, c, J_body = np.repeat(np.eye(3)[None], len(t), 0), np.zeros((len(t), 3)), np.diag([3.6e-4, 8.6, 8.6])
    tip = np.array([4.0, 0.01, -0.02])
    with pytest.raises(ValueError, match=r"no angular momentum about its CM .* roll of its CM frame"):
        sim.tip_from_cm(_moving(body, Q, c, tip, J_body, np.zeros(3)))
    slow = sim.tip_from_cm(_moving(body, Q, c, tip, J_body, np.array([0.0, 0.0, 8.6e-6])))
    assert np.allclose(slow, [0.0, 0.01, -0.02], atol=1e-12)


def test_mass_properties_of_both_models_agree_and_the_reference_conserves_momenta():
    """At rest the runtime's CM and inertia (superelement CMs and J0) and the reference's (consistent mass,
    rotary inertia at the nodes) are the same beam's: m L^3 / 12 about the transverse axes. Released from the
    deformed start, the reference conserves the linear momentum to rounding and the angular momentum about
    the CM to the scheme's O(h^2) oscillation (rho_inf = 1; measured 8.5e-6 over 2 s at 2 ms)."""
    m = load_model(B4, ["scenes.tumble.duration=0.5"])
    sc = m.scene("tumble")
    body = reduce_scene_body(m.body, sc).data
    still = load_model(B4, ["scenes.tumble.initial.port_displacements={}"]).scene("tumble")
    system, _ = sim.build_system(body, still, m.body.origin)
    mass, c, J = system.mass_properties()
    L, mu = m.body.length, m.body.section.m
    assert np.isclose(mass, mu * L, rtol=1e-12) and np.allclose(c, [L / 2, 0.0, 0.0], atol=1e-12)
    rotary = np.array([m.body.section.m22 + m.body.section.m33, m.body.section.m22, m.body.section.m33]) * L
    assert np.allclose(np.diag(J), rotary + mu * L**3 / 12 * np.array([0.0, 1.0, 1.0]), rtol=1e-9)
    ref = simulate_reference(scene_body(m.body, sc), sc, n_elements=16)
    p, h = ref.mass["p"], ref.mass["h_cm"]
    assert np.abs(p - p[0]).max() <= 1e-12 * np.linalg.norm(p[0])
    assert np.abs(h - h[0]).max() <= 2e-5 * np.linalg.norm(h[0])
    sys_def, _ = sim.build_system(body, sc, m.body.origin)  # the same deformed start in the runtime
    c_rt, J_rt, p_rt, h_rt = sim.free_body_state(sys_def)
    assert np.linalg.norm(c_rt - ref.mass["cm"][0]) < 1e-4 * L
    assert np.linalg.norm(p_rt - p[0]) < 1e-4 * np.linalg.norm(p[0])
    assert np.linalg.norm(h_rt - h[0]) < 1e-3 * np.linalg.norm(h[0])


def test_initial_deformation_is_the_cantilevers_in_both_models():
    """A port displaced by u is fixed along u only: the free beam with end b pulled sideways by u takes the
    cantilever's shape (strain energy 3 EI |u|^2 / (2 L^3) = 0.00481 J) and its end moves in (shortens the
    chord) rather than stretching the beam; holding its whole translation stretched it (1 SE runtime: 0.0151 J,
    0.0103 J of it axial, which rang the axial modes after the release)."""
    m = load_model(B4, ["scenes.tumble.duration=0.002"])
    sc = m.scene("tumble")
    u = np.array([0.0, 0.05, 0.02])
    EI, L = m.body.section.EI2, m.body.length
    bending = 3 * EI * (u @ u) / (2 * L**3)
    body = reduce_scene_body(m.body, sc).data
    system, _ = sim.build_system(body, sc, m.body.origin)
    assert abs(system.energies()["strain"] / bending - 1) < 0.01  # measured 0.0048101 J
    ref = simulate_reference(scene_body(m.body, sc), sc, n_elements=16)
    assert abs(ref.energy["strain"][0] / bending - 1) < 0.01  # measured 0.0048135 J
    for r_b in (system.outputs()["b"].r, ref.ports["b"]["r"][0]):
        assert np.isclose((r_b - [L, 0.0, 0.0]) @ u / np.linalg.norm(u), np.linalg.norm(u), rtol=1e-9)
        assert r_b[0] < L - 1e-4  # the end moved in: no stretch
