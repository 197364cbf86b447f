"""Full FE beam (fe.beam): rigid modes, free-free frequencies, Timoshenko statics, mass kernel."""
import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla

from ffrf_fmu.fe import rigid_modes, skew
from ffrf_fmu.fe.beam import beam_model, local_frame
from ffrf_fmu.model import Section

# an unsymmetric section on an oblique axis, so that a swapped EI2/EI3 or GA2/GA3 or a wrong
# transformation shows up
ODD = Section(EA=3.0e5, GJ=70.0, EI2=120.0, EI3=45.0, m=2.0, m22=0.03, m33=0.01, GA2=4.0e3, GA3=9.0e3)
OBLIQUE = np.array([1.0, 2.0, 2.0]) / 3.0


def test_local_frame_rule():
    # documented rule: +X -> axes 2, 3 = +Y, +Z; parallel to Z -> axis 2 = normalize(e_x x e1)
    assert np.allclose(local_frame([1, 0, 0]), np.eye(3))
    assert np.allclose(local_frame([0, 0, 1]), np.column_stack([[0, 0, 1], [0, -1, 0], [1, 0, 0]]))
    R = local_frame(OBLIQUE)
    assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)


@pytest.mark.parametrize("section", [ODD, dataclasses.replace(ODD, GA2=None, GA3=None)])
def test_rigid_modes_are_strain_free(section):
    fe = beam_model(section, (1.0, -2.0, 0.5), OBLIQUE, 3.0, 7)
    U = rigid_modes(fe.coords, (0.3, 0.2, -0.1))
    # round-off: K entries ~EA/h, U entries ~|X| ~ 4, sums over 12-dof elements
    assert np.abs(U.T @ fe.K @ U).max() <= 1e-13 * np.abs(fe.K).max() * np.abs(U).max() ** 2


def test_free_free_bending_frequencies_euler_bernoulli(b1):
    # B1 section without shear (Euler-Bernoulli), 16 elements: closed form beta L = 4.7300,
    # 7.8532, 10.9956. Hermite consistent-mass error ~(beta h)^4 / 720 ~ 3e-4 for the third mode
    # and rotary inertia m22 = 22.7e-6 lowers by ~(beta r)^2 ~ 1e-4: 0.5 % covers both.
    section, L = b1
    section = dataclasses.replace(section, GA2=None, GA3=None)
    fe = beam_model(section, (0, 0, 0), (1, 0, 0), L, 16)
    w2 = sla.eigh(fe.K, fe.M, eigvals_only=True)
    f = np.sqrt(np.abs(w2)) / (2 * np.pi)
    assert np.all(f[:6] < 1e-3)  # six rigid modes (numerically ~1e-5 Hz)
    closed = np.array([4.7300, 7.8532, 10.9956]) ** 2 / (2 * np.pi) * np.sqrt(section.EI2 / (section.m * L**4))
    bending = f[6:12].reshape(3, 2)  # each bending frequency twice (EI2 = EI3); torsion is far higher
    assert np.allclose(bending, closed[:, None], rtol=5e-3)


@pytest.mark.parametrize("shear", [True, False])
def test_cantilever_end_loads_are_exact(shear):
    # IIE Timoshenko elements solve the homogeneous beam equations, so nodal end loads give
    # exact nodal displacements on any mesh; 1e-8 covers round-off amplified by cond(K) ~ 1e8.
    section = ODD if shear else dataclasses.replace(ODD, GA2=None, GA3=None)
    L, F, T = 2.5, 3.0, 0.7
    fe = beam_model(section, (0.5, 0.0, -1.0), OBLIQUE, L, 3)
    e1, e2, e3 = local_frame(OBLIQUE).T
    free = np.arange(6, fe.n_dof)
    tip = slice(fe.n_dof - 6, fe.n_dof)

    def tip_displacement(force, moment):
        f = np.zeros(fe.n_dof)
        f[tip] = np.concatenate([force, moment])
        u = np.zeros(fe.n_dof)
        u[free] = np.linalg.solve(fe.K[np.ix_(free, free)], f[free])
        return u[tip]

    inv = (lambda x: 0.0) if not shear else (lambda GA: 1.0 / GA)
    cases = [
        # (force, moment, expected tip [u, theta] in model axes)
        (F * e2, 0 * e1, np.concatenate([(F * L**3 / (3 * section.EI3) + F * L * inv(section.GA2)) * e2, F * L**2 / (2 * section.EI3) * e3])),
        (F * e3, 0 * e1, np.concatenate([(F * L**3 / (3 * section.EI2) + F * L * inv(section.GA3)) * e3, -F * L**2 / (2 * section.EI2) * e2])),
        (F * e1, 0 * e1, np.concatenate([F * L / section.EA * e1, 0 * e1])),
        (0 * e1, T * e1, np.concatenate([0 * e1, T * L / section.GJ * e1])),
        (0 * e1, T * e2, np.concatenate([-T * L**2 / (2 * section.EI2) * e3, T * L / section.EI2 * e2])),
    ]
    for force, moment, expected in cases:
        u = tip_displacement(force, moment)
        assert np.abs(u - expected).max() <= 1e-8 * np.abs(expected).max()


def test_mass_is_consistent_with_rigid_inertia():
    L = 3.0
    fe = beam_model(ODD, (0, 0, 0), OBLIQUE, L, 5)
    R = local_frame(OBLIQUE)
    c = 0.5 * L * OBLIQUE
    U = rigid_modes(fe.coords, c)
    MU = U.T @ fe.M @ U
    J_local = np.diag([(ODD.m22 + ODD.m33) * L, ODD.m * L**3 / 12 + ODD.m22 * L, ODD.m * L**3 / 12 + ODD.m33 * L])
    # rigid motions are represented exactly and the quadrature is exact: round-off only
    assert np.allclose(MU[:3, :3], ODD.m * L * np.eye(3), rtol=0, atol=1e-13 * ODD.m * L)
    assert np.abs(MU[:3, 3:]).max() < 1e-13 * ODD.m * L * L  # no static moment about the CM
    assert np.allclose(MU[3:, 3:], R @ J_local @ R.T, rtol=0, atol=1e-13 * J_local.max())


def test_mass_kernel_is_skew_and_matches_mass():
    # M_k = int N^T skew(e_k) N rho dV with the same kinematics as M:
    #  - skew-symmetric;
    #  - rigid translations t: N U_t = I, so U_t^T M_k = skew(e_k) U_t^T M;
    #  - rigid rotations theta, phi: (theta x X)^T skew(e_k) (phi x X) integrates to
    #    -e_k^T Sigma (theta x phi), Sigma = int rho X X^T dV = tr(J)/2 I - J (J from M).
    fe = beam_model(ODD, (0.2, 0.1, 0.0), OBLIQUE, 3.0, 5)
    U = rigid_modes(fe.coords, (0.0, 0.0, 0.0))
    Ut, Ur = U[:, :3], U[:, 3:]
    J = Ur.T @ fe.M @ Ur
    Sigma = 0.5 * np.trace(J) * np.eye(3) - J
    E = skew(np.eye(3))
    scale = np.abs(fe.M_kernel).max()
    for k in range(3):
        Mk = fe.M_kernel[k]
        assert np.abs(Mk + Mk.T).max() <= 1e-15 * scale  # round-off of the quadrature sums
        assert np.allclose(Ut.T @ Mk, E[k] @ Ut.T @ fe.M, rtol=0, atol=1e-13 * np.abs(Ut.T @ fe.M).max())
        expected = np.array([[-Sigma[k] @ np.cross(a, b) for b in np.eye(3)] for a in np.eye(3)])
        assert np.allclose(Ur.T @ Mk @ Ur, expected, rtol=0, atol=1e-13 * np.abs(Sigma).max())
