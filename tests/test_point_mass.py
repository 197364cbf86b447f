"""Point masses lumped at FE nodes ([[body.masses]], fe.lumped_kernels): the FE kernels, the reduced
superelements, the full-order reference and the model file (docs/model-format.md)."""
import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

from ffrf_fmu import linear
from ffrf_fmu.fe import lumped_kernels, rigid_modes, with_lumped_masses
from ffrf_fmu.fe.beam import beam_model
from ffrf_fmu.fe.beam import tensor_kernel
from ffrf_fmu.model import ModelError, PointMass, load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.reference import static_reference

HAUG = "models/haug_beam.toml"


def test_lumped_kernels_are_those_of_a_rigid_body():
    """A rigid body at a node: rigid translations/rotations see mass m and inertia J (M), the kernel
    M_k is skew with U_t^T M_k = e_k~ U_t^T M and the rotation block -e_k^T S (theta x phi) with
    S = tr(J)/2 I - J, and sum_a T_aa = M, -eps_kab T_ab = M_k (the identities the beam's kernels
    satisfy, tests/test_fe.py): exact algebra, round-off tolerances."""
    J = np.array([[3.0, 0.2, -0.1], [0.2, 2.0, 0.3], [-0.1, 0.3, 1.5]])
    M, Mk, T = lumped_kernels(2.5, J)
    U = rigid_modes(np.zeros((1, 3)), np.zeros(3))
    assert np.allclose(U.T @ M @ U, np.block([[2.5 * np.eye(3), np.zeros((3, 3))], [np.zeros((3, 3)), J]]))
    S = 0.5 * np.trace(J) * np.eye(3) - J
    eps = np.zeros((3, 3, 3))
    for k, a, b in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[k, a, b], eps[k, b, a] = 1.0, -1.0
    for k in range(3):
        assert np.abs(Mk[k] + Mk[k].T).max() < 1e-15
        expected = np.array([[-S[k] @ np.cross(a, b) for b in np.eye(3)] for a in np.eye(3)])
        assert np.allclose(Mk[k, 3:, 3:], expected, atol=1e-15)
        assert np.allclose(-np.einsum("ab,abij->ij", eps[k], T), Mk[k], atol=1e-14)
    assert np.allclose(np.einsum("aaij->ij", T), M, atol=1e-14)


def test_tensor_kernel_with_lumped_body_matches_fe_model(b1):
    section, _ = b1
    d = np.array([0.6, 0.0, 0.8])
    J = np.diag([0.3, 0.2, 0.1])
    lumped = [(4, 1.7, J)]
    fe = with_lumped_masses(beam_model(section, (0, 0, 0), d, 2.0, 4), lumped)
    T = tensor_kernel(section, d, 2.0, 4, lumped)
    assert np.allclose(np.einsum("aaij->ij", T), fe.M, atol=1e-14 * np.abs(fe.M).max())


def _tip_mass_body(n_se, mass, inertia=(0.0, 0.0, 0.0), at=8.0):
    m = load_model(HAUG, [f"superelements={n_se}", "modes=4"])
    return dataclasses.replace(m.body, masses=(PointMass(at, mass, inertia),))


@pytest.mark.parametrize("n_se", [1, 2])
def test_cantilever_with_tip_mass_frequency(n_se):
    """B1 cantilever with a 2 kg tip mass (1.25 x the beam's mass): first frequency against the
    Euler-Bernoulli characteristic equation 1 + cos b cosh b + r b (cos b sinh b - sin b cosh b) = 0,
    r = M / (m L). Measured 8e-6 (Timoshenko shear and the 8-element mesh); 1e-4."""
    body = _tip_mass_body(n_se, 2.0)
    data = reduce_body(body).data
    assert sum(se.mass for se in data.superelements) == pytest.approx(0.201 * 8 + 2.0, rel=1e-14)
    f = linear.natural_frequencies(data, linear.motion_fixed_dofs(data))
    sec, L = body.section, body.length
    r = 2.0 / (sec.m * L)
    b = brentq(lambda b: 1 + np.cos(b) * np.cosh(b) + r * b * (np.cos(b) * np.sinh(b) - np.sin(b) * np.cosh(b)), 0.3, 1.875)
    assert f[0] == pytest.approx(b**2 * np.sqrt(sec.EI3 / (sec.m * L**4)) / (2 * np.pi), rel=1e-4)


def test_point_mass_on_a_shared_node_belongs_to_the_superelement_before_it():
    data = reduce_body(_tip_mass_body(2, 3.0, at=4.0)).data
    assert [se.mass for se in data.superelements] == pytest.approx([0.201 * 4 + 3.0, 0.201 * 4])


def test_reference_carries_the_point_mass():
    """Gravity along the beam (axis X) on the B1 cantilever with a 2 kg tip mass: tip stretch
    (M g L + m g L^2 / 2) / EA, exact for linear bar elements with the consistent load (nodally
    exact); the rest is geometric (1e-7): 1e-6. A tip inertia along the (unrotated) axes adds nothing."""
    g = 9.81
    body = _tip_mass_body(1, 2.0, inertia=(0.1, 0.2, 0.3))
    r, _ = static_reference(body, {}, n_elements=8, gravity=(g, 0.0, 0.0), load_steps=1)
    sec, L = body.section, body.length
    assert r[-1, 0] - L == pytest.approx((2.0 * g * L + sec.m * g * L**2 / 2) / sec.EA, rel=1e-6)


def test_model_file_point_masses_are_validated():
    body = load_model(HAUG, ['body.masses=[{at = 8.0, mass = 2.0, inertia = [1.0, 0.5, 0.5]}]']).body
    assert body.masses == (PointMass(8.0, 2.0, (1.0, 0.5, 0.5)),)
    with pytest.raises(ModelError, match=r"body\.masses\.0\.at: expected a node of the FE mesh"):
        load_model(HAUG, ['body.masses=[{at = 0.1, mass = 2.0}]'])
    with pytest.raises(ModelError, match=r"body\.masses\.0\.mass: expected a positive mass"):
        load_model(HAUG, ['body.masses=[{at = 8.0, mass = 0.0}]'])
    with pytest.raises(ModelError, match=r"body\.masses\.0\.inertia"):
        load_model(HAUG, ['body.masses=[{at = 8.0, mass = 1.0, inertia = [1.0, -1.0, 0.0]}]'])
