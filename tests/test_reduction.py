"""Superelement reduction (formulation.md section 2, geradin eq. 74-76)."""
import dataclasses

import numpy as np
import pytest

from ffrf_fmu.fe import node_dofs
from ffrf_fmu.fe.beam import beam_model
from ffrf_fmu.model import Body, Port
from ffrf_fmu.reduction import attachment_modes, build_body, reduce_superelement


def segment(section, L, n_se, n_el, modes=6):
    fe = beam_model(section, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), L / n_se, n_el)
    return fe, reduce_superelement(fe, (0, n_el), modes, (0, 1))


@pytest.mark.parametrize("n_el", [4, 8, 16, 32])
@pytest.mark.parametrize("n_se", [1, 2, 4])
def test_basis_is_rigid_orthogonal_and_block_diagonal(beam, n_se, n_el):
    section, L = beam
    fe, red = segment(section, L, n_se, n_el)
    # eq. (74) and K_bar block diagonality hold to round-off: measured <= 4e-11 (B2, one
    # 141 m superelement, 32 elements: the metric scales with the lever arms in U and with
    # 1/max|M| ~ n_el), 1e-10 is the bound of formulation.md
    assert red.orthogonality_error < 1e-10
    assert red.block_diagonality_error < 1e-10
    Y = red.Y
    assert np.array_equal(Y[node_dofs((0, n_el))], np.eye(12, Y.shape[1]))  # eq. (76): q_B = boundary dofs


@pytest.mark.parametrize("n_el", [4, 8, 16])
@pytest.mark.parametrize("n_se", [1, 2, 4])
def test_boundary_stiffness_is_inverse_flexibility(beam, n_se, n_el):
    # K_bar_BB = F_BB^-1; F_BB recomputed with the other end held (G_e = P^T G_c P does not
    # depend on the isostatic support). Two independent solves, each losing ~eps cond(K_ff):
    # measured <= 8e-11, bound 1e-8.
    section, L = beam
    fe, red = segment(section, L, n_se, n_el)
    boundary = node_dofs((0, n_el))
    F_BB = attachment_modes(fe, red.U, boundary, support=boundary[6:])[boundary]
    assert np.abs(red.data.K[:12, :12] @ F_BB - np.eye(12)).max() < 1e-8


def test_gyroscopic_matrices_are_skew_and_from_the_kernel(b1):
    section, L = b1
    fe, red = segment(section, L, 2, 8)
    G = np.einsum("ia,kij,jb->kab", red.Y, fe.M_kernel, red.Y)
    # unforced Y^T M_k Y is skew to round-off; the stored G is its skew part
    assert np.abs(G + G.transpose(0, 2, 1)).max() < 1e-14 * np.abs(G).max()
    assert np.allclose(red.data.G, G, rtol=0, atol=1e-14 * np.abs(G).max())
    assert np.array_equal(red.data.G, -red.data.G.transpose(0, 2, 1))


def test_superelement_rigid_data(b1):
    section, L = b1
    fe, red = segment(section, L, 2, 8)
    d, Ls, m = red.data, L / 2, section.m
    J = np.diag([(section.m22 + section.m33) * Ls, m * Ls**3 / 12 + section.m22 * Ls, m * Ls**3 / 12 + section.m33 * Ls])
    # exact quadrature of exactly represented rigid motions: round-off only
    assert np.isclose(d.mass, m * Ls, rtol=1e-13)
    assert np.allclose(d.x_cm, [Ls / 2, 0, 0], rtol=0, atol=1e-13 * Ls)
    assert np.allclose(d.J0, J, rtol=0, atol=1e-13 * J.max())
    assert np.allclose(d.X_B, [[-Ls / 2, 0, 0], [Ls / 2, 0, 0]], rtol=0, atol=1e-13 * Ls)
    # free-free frequencies of the 4 m segment, beta L = 4.7300, 7.8532 (Euler-Bernoulli);
    # 8 elements: discretization 1e-4, shear and rotary inertia ~1e-3, so 0.5 %
    closed = np.array([4.7300, 7.8532]) ** 2 / (2 * np.pi) * np.sqrt(section.EI2 / (m * Ls**4))
    assert np.allclose(d.frequencies_hz[:4].reshape(2, 2), closed[:, None], rtol=5e-3)


def test_mesh_errors(b1):
    section, L = b1
    fe = beam_model(section, (0, 0, 0), (1, 0, 0), L, 1)
    with pytest.raises(ValueError, match="F_BB is singular"):
        reduce_superelement(fe, (0, 1), 0, (0, 1))
    fe = beam_model(section, (0, 0, 0), (1, 0, 0), L, 3)
    with pytest.raises(ValueError, match="room for at most 6"):
        reduce_superelement(fe, (0, 3), 7, (0, 1))
    # 3 elements: 6 elastic dofs per bending plane minus 4 boundary ones leave 2 modes per
    # plane, so the third bending pair is spanned by the attachment modes
    with pytest.raises(ValueError, match="not independent"):
        reduce_superelement(fe, (0, 3), 6, (0, 1))


def test_build_body(b1):
    section, L = b1
    ports = (Port("hub", 0, "motion", "motion"), Port("tip", -1, "force", "force"))
    body = Body("beam", L, (1.0, 2.0, 0.0), (0.0, 1.0, 0.0), section, 4, 4, 6, ports)
    data, reds = build_body(body, causality=(("hub", "motion", "force"),))
    assert np.allclose(data.node_positions, [[1.0, 2.0 + 2.0 * i, 0.0] for i in range(5)])
    assert [tuple(se.nodes) for se in data.superelements] == [(0, 1), (1, 2), (2, 3), (3, 4)]
    for i, se in enumerate(data.superelements):
        assert np.allclose(se.x_cm, [1.0, 3.0 + 2.0 * i, 0.0])
        assert np.allclose(se.x_cm + se.X_B, data.node_positions[i : i + 2])
        assert se.K.shape == se.M.shape == (18, 18) and se.G.shape == (3, 18, 18)
    assert data.port("hub").rotation == "force" and data.port("tip").node == 4
    with pytest.raises(ValueError, match="at least 2"):
        build_body(dataclasses.replace(body, elements_per_superelement=1))
