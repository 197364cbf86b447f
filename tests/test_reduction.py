"""Superelement reduction (docs/background.md, geradin eq. 74-76)."""
import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla

from ffrf_fmu.fe import node_dofs
from ffrf_fmu.fe.beam import beam_model
from ffrf_fmu.model import Body, Port
from ffrf_fmu.reduction import reduce_body, reduce_superelement


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
    # 1/max|M| ~ n_el): 1e-10 holds that with a margin of 2.5
    assert red.orthogonality_error < 1e-10
    assert red.block_diagonality_error < 1e-10
    Y = red.Y
    assert np.array_equal(Y[node_dofs((0, n_el))], np.eye(12, Y.shape[1]))  # eq. (76): q_B = boundary dofs


def _rigid_at(points, x_cm):
    """(6 n, 6) rigid motions (translation, small rotation about x_cm) of the 6-dof nodes at points."""
    rows = []
    for x in points:
        r = np.asarray(x, float) - x_cm
        rows.append(np.block([[np.eye(3), -np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])],
                              [np.zeros((3, 3)), np.eye(3)]]))
    return np.vstack(rows)


@pytest.mark.parametrize("n_el", [4, 8, 16])
@pytest.mark.parametrize("n_se", [1, 2, 4])
def test_boundary_flexibility_against_a_direct_static_solve(beam, n_se, n_el):
    """K_bar_BB^-1 = F_BB (eq. 75, free attachment modes with inertia relief) against the full FE
    model solved directly: first node clamped, a self-equilibrated load on the two boundary nodes
    (no inertia relief then: P^T f = f), u = K_ff^-1 f. F_BB f must equal u_B up to a rigid motion of
    the segment (the free body's flexibility is defined modulo rigid modes): the residual after
    removing span(U_B) by least squares is round-off, ~eps cond(K_ff) (grows with n_el): measured
    <= 4.3e-13 of |u_B| (B1, 4 superelements of 16 elements), bound 1e-10; F_BB f - u_B itself is
    0.5-0.9 of |u_B| (the rigid part), so a wrong support, a missing inertia relief or a
    mis-scaled mode shows at O(1)."""
    section, L = beam
    fe, red = segment(section, L, n_se, n_el)
    boundary = node_dofs((0, n_el))
    F_BB = np.linalg.inv(red.data.K[:12, :12])
    U_B = _rigid_at(fe.coords[[0, n_el]], red.data.x_cm)
    # the 6 self-equilibrated loads: the null space of the resultant map U_B^T (force and moment)
    loads = sla.null_space(U_B.T)
    free = np.setdiff1d(np.arange(fe.n_dof), boundary[:6])
    f = np.zeros((fe.n_dof, 6))
    f[boundary] = loads
    u = np.zeros_like(f)
    u[free] = np.linalg.solve(fe.K[np.ix_(free, free)], f[free])
    diff = F_BB @ loads - u[boundary]
    rigid, *_ = np.linalg.lstsq(U_B, diff, rcond=None)
    assert np.abs(diff - U_B @ rigid).max() < 1e-10 * np.abs(u[boundary]).max()


def _fields(fe, section, q):
    """Centreline displacement and section rotation (n_points, 3, n_cols) of the dof columns q of a
    beam along +X (local axes = model axes), written out from the IIE interpolation (fe/beam.py
    module doc) at 10 Gauss points per element, with the quadrature weights ds (n_points,)."""
    from ffrf_fmu.fe.beam import _phi, iie_shape

    xg, wg = np.polynomial.legendre.leggauss(10)
    xi, wi = 0.5 * (xg + 1), 0.5 * wg
    Le = np.diff(fe.coords[:, 0])
    u, th, ds = [], [], []
    sign = np.array([1.0, -1.0, 1.0, -1.0])
    for e, l in enumerate(Le):
        qe = q[6 * e : 6 * e + 12]
        lin = np.stack([1 - xi, xi], -1)
        Nv2, _, Nr2, _ = iie_shape(xi, np.array([l]), _phi(section.EI3, section.GA2, np.array([l])))
        Nv3, _, Nr3, _ = iie_shape(xi, np.array([l]), _phi(section.EI2, section.GA3, np.array([l])))
        bend2, bend3 = qe[[1, 5, 7, 11]], sign[:, None] * qe[[2, 4, 8, 10]]
        u.append(np.stack([lin @ qe[[0, 6]], Nv2[0] @ bend2, Nv3[0] @ bend3], 1))
        th.append(np.stack([lin @ qe[[3, 9]], -(Nr3[0] @ bend3), Nr2[0] @ bend2], 1))
        ds.append(wi * l)
    return np.concatenate(u), np.concatenate(th), np.concatenate(ds)


def test_gyroscopic_matrices_against_quadrature_of_the_kernel(b1):
    """G_k = Y^T M_k Y (eq. 53) against the kernel integrated over the reduced basis' own fields:
    G_k[a, b] = int m u_a . (e_k x u_b) + theta_a . ((S e_k) x theta_b) ds, S = diag(0, m33, m22)
    the section's second moments of mass, the fields of each column of Y evaluated pointwise from
    the interpolation (10 Gauss points per element: exact for these polynomials, as the 4 of the
    FE kernel are). Independent of the assembled M_k and of the einsum that projects it; agreement
    to round-off: measured 3.9e-16 of max|G|, bound 1e-12 (leaving out the rotary part S alone
    moves G by 2.7e-5)."""
    section, L = b1
    fe, red = segment(section, L, 2, 8)
    u, th, ds = _fields(fe, section, red.Y)
    S = np.diag([0.0, section.m33, section.m22])
    G = np.empty((3,) + (red.Y.shape[1],) * 2)
    for k, e in enumerate(np.eye(3)):
        G[k] = section.m * np.einsum("p,pia,pib->ab", ds, u, np.cross(e, u, axisb=1, axisc=1)) \
            + np.einsum("p,pia,pib->ab", ds, th, np.cross(S @ e, th, axisb=1, axisc=1))
    assert np.abs(G + G.transpose(0, 2, 1)).max() < 1e-13 * np.abs(G).max()  # skew by construction
    assert np.abs(red.data.G - G).max() < 1e-12 * np.abs(G).max()
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


def test_reduce_body(b1):
    section, L = b1
    ports = (Port("hub", 0, "motion", "force"), Port("tip", -1, "force", "force"))
    body = Body("beam", L, (1.0, 2.0, 0.0), (0.0, 1.0, 0.0), section, 4, 4, 6, ports)
    reduced = reduce_body(body)
    data = reduced.data
    assert np.allclose(data.node_positions, [[1.0, 2.0 + 2.0 * i, 0.0] for i in range(5)])
    assert [tuple(se.nodes) for se in data.superelements] == [(0, 1), (1, 2), (2, 3), (3, 4)]
    for i, se in enumerate(data.superelements):
        assert np.allclose(se.x_cm, [1.0, 3.0 + 2.0 * i, 0.0])
        assert np.allclose(se.x_cm + se.X_B, data.node_positions[i : i + 2])
        assert se.K.shape == se.M.shape == (18, 18) and se.G.shape == (3, 18, 18)
    assert data.port("hub").rotation == "force" and data.port("tip").node == 4
    with pytest.raises(ValueError, match="at least 2"):
        reduce_body(dataclasses.replace(body, elements_per_superelement=1))
