"""Geometric stiffening of a solid superelement from the element stresses of its mesh
(docs/equations.md, "Geometric stiffening of a solid"; ffrf_fmu/solid/stiffening.py).

The reduced tensors against the FE model's own geometric stiffness, the Newton matrix against
central differences, and the refusal for a solid given by its matrices only.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.model import ModelError, load_model
from ffrf_fmu.reduction import reduce_scene_body
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.solid.stiffening import geometric_stiffness, membrane_tensors

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_membrane_tensors_are_the_mesh_geometric_stiffness(solid_bar):
    """a^T a = K_bar (the linear strain of the basis in the orthonormal strain coordinates) and
    sum_k (a q)_k B_k = Y^T K_G(sigma(Y q)) Y, K_G the FE geometric stiffness assembled independently
    (solid/stiffening.geometric_stiffness): both identities of the module doc, to round-off (measured
    3e-12 and 9e-15 on haug_solid)."""
    data, red = solid_bar()
    se = data.superelements[0]
    assert se.stiffening and se.W1 is not None
    assert se.n > 12 + 3 and len(se.frequencies_hz) == 3  # a centrifugal correction mode appended to eta
    assert np.abs(se.vk_a.T @ se.vk_a - se.K).max() <= 1e-10 * np.abs(se.K).max()
    for seed in range(2):
        q = np.random.default_rng(seed).standard_normal(se.n)
        KG = red.Y.T @ (geometric_stiffness(red.fe.strain, red.Y @ q) @ red.Y)
        reduced = np.einsum("k,kil->il", se.vk_a @ q, se.vk_B)
        assert np.abs(reduced - KG).max() <= 1e-12 * np.abs(KG).max()
    vk = membrane_tensors(red.fe.strain, red.Y)
    assert np.abs(vk["K_strain"] - se.K).max() <= 1e-10 * np.abs(se.K).max()


def test_correction_mode_holds_the_centrifugal_response(solid_bar):
    """The FE model's free (inertia-relief) static response x to the centrifugal load about the CM
    (w along z; dense bordered solve K x + M U l = F, U^T M x = 0 on this 200-dof bar, the hub face
    rigidly linked as in the reduction) lies in the
    reduced basis: the reduced solution u = Y K_bar^-1 Y^T F equals it to 1e-6 (measured 4.7e-7: the
    correction shapes below 1e-3 of the largest response are dropped; without the correction columns
    the attachment and vibration shapes miss > 1 % of it), and Y^T F is Witteveen's
    f0 = w^T W1 w / 2."""
    from ffrf_fmu.solid.constraints import constraints, mass_properties
    from ffrf_fmu.solid.stiffening import centrifugal_loads

    data, red = solid_bar()
    se = data.superelements[0]
    w = np.array([0.0, 0.0, 50.0])
    f0 = 0.5 * np.einsum("a,jab,b->j", w, se.W1, w)
    F = centrifugal_loads(red.fe, red.U[:, 3:]) @ np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, 2 * w[0] * w[1],
                                                             2 * w[0] * w[2], 2 * w[1] * w[2]])
    assert np.allclose(red.Y.T @ F, f0, rtol=0, atol=1e-10 * np.abs(f0).max())
    c = constraints(red.fe, red.frames, mass_properties(red.fe)[1])  # the hub face's rigid link: u = T z
    T = c.T.toarray()
    K, MU = T.T @ (red.fe.K @ T), T.T @ (red.fe.M @ (T @ c.U))
    A = np.block([[K, MU], [MU.T, np.zeros((6, 6))]])
    x = T @ np.linalg.solve(A, np.concatenate([T.T @ F, np.zeros(6)]))[: K.shape[0]]
    u = red.Y @ np.linalg.solve(se.K, f0)
    assert np.linalg.norm(u - x) <= 1e-6 * np.linalg.norm(x)
    n = 12 + 3
    u_short = red.Y[:, :n] @ np.linalg.solve(se.K[:n, :n], f0[:n])
    assert np.linalg.norm(u_short - x) > 1e-2 * np.linalg.norm(x)


@pytest.mark.parametrize("scale", [1.0, 1e5])
def test_newton_jacobian_of_a_stiffened_solid_matches_finite_differences(scale, solid_bar, far_from_reference,
                                                                        iteration_matrix_error):
    """The iteration matrix of the stiffened solid bar against central differences at a random state
    far from the reference (1e-6 of the largest entry, as for the beam, test_stiffening.py); the second
    case scales the membrane tensors' B by 1e5 so that their Hessian blocks stand out."""
    data, _ = solid_bar(True, False)
    ses = tuple(dataclasses.replace(se, vk_B=se.vk_B * scale) for se in data.superelements)
    s = BodySystem(dataclasses.replace(data, superelements=ses), terms="linear", rho_inf=0.7)
    values = far_from_reference(s)
    assert iteration_matrix_error(s, values) <= 1e-6


def test_a_solid_from_matrices_alone_refuses_stiffening():
    """A partner's export has no mesh stresses: `stiffening = true` is refused, saying why."""
    m = load_model(MODELS / "rotor_abaqus.toml", ["stiffening=true"])
    with pytest.raises(ModelError, match=r"has none \(an export, shells or beams\): set stiffening = false"):
        reduce_scene_body(m.body, m.scenes[0])


# The project's full-order geometrically exact beam on B1 (ffrf_fmu/reference, 16 elements, h = 10 ms;
# tests/test_stiffening.py's b1_reference, docs/equations.md "Geometric stiffening"): stored, not rerun.
B1_REFERENCE_TIP_MAX_M = 0.531784
B1_REFERENCE_IN_PLANE_HZ = 0.5329


def test_haug_solid_with_stiffening_follows_the_full_order_beam():
    """B1 as the hex27 solid bar (haug_solid.toml, scene spinup_stiffened), 1 superelement, stiffening
    from its mesh, h = 10 ms: the max tip
    deflection within 1 % of the full-order beam's and the in-plane oscillation after the spin-up within
    2 % (measured -0.06 % and +1.0 %, 0.531471 m and 0.5385 Hz; without stiffening +12.6 % and -20 %)."""
    from ffrf_fmu.simulate import run_scene

    r = run_scene(load_model(str(MODELS / "haug_solid.toml")), "spinup_stiffened")
    m = r.summary["metrics"]
    assert m["tip_deflection_max_m"] == pytest.approx(B1_REFERENCE_TIP_MAX_M, rel=0.01)
    assert m["in_plane_frequency_hz"] == pytest.approx(B1_REFERENCE_IN_PLANE_HZ, rel=0.02)


# ------------------------------------------------------------------ steady spin against the full FE model
def _steady_spin(model, rates, overrides=()):
    from ffrf_fmu.studies.campbell import campbell

    return campbell(load_model(model, list(overrides)), rates, n=1, full=True, terms="full")


@pytest.mark.parametrize("model, rates, overrides", [
    (str(MODELS / "plate.toml"), (100.0, 200.0, 400.0), ()),
    (str(MODELS / "haug_solid.toml"), (2.0, 4.0, 8.0), ()),
])
def test_first_frequency_about_the_steady_spin_matches_the_full_fe_model(model, rates, overrides):
    """The reduced solid (1 superelement, stiffening from its mesh, term set full) linearized about its
    steady spin (linear.spin_modes) against the full FE model linearized about the same spin (stress
    stiffening K_G of the steady stress, spin softening, Coriolis; studies/campbell.full_frequencies):
    the first frequency within 1 % at 3 rates (measured +0.04, +0.15, +0.52 % on the plate at 100, 200,
    400 rad/s; +0.09, +0.27, +0.65 % on the bar at 2, 4, 8 rad/s; docs/solids.md). Both rise with spin;
    without stiffening the reduced plate falls to 60.16 Hz at 400 rad/s (-13 %: spin softening alone)."""
    c = _steady_spin(model, rates, overrides)
    assert c.stiffening
    np.testing.assert_allclose(c.reduced[:, 0], c.full[:, 0], rtol=0.01)
    assert np.all(np.diff(c.full[:, 0]) > 0)


def test_rotor_campbell_from_exported_matrices_matches_the_full_export():
    """rotor_abaqus.toml (a partner's matrices: no stress stiffening in either model, said in the notes):
    the first three frequencies about the steady spin, term set full, within 1 % of the full exported
    model's at 0, 200 and 400 rad/s (measured at most +0.66 %, the first mode at 400 rad/s: the shaft's
    torsion, which the full linear export softens by W^2 for want of stress stiffening, docs/solids.md;
    the whirl pair 819.02 / 890.57 Hz against 818.52 / 890.02)."""
    from ffrf_fmu.studies.campbell import campbell

    c = campbell(load_model(MODELS / "rotor_abaqus.toml"), (0.0, 200.0, 400.0), n=3, full=True, terms="full")
    assert not c.stiffening and "stress" in c.notes
    np.testing.assert_allclose(c.reduced, c.full, rtol=0.01)
    assert c.full[2, 2] - c.full[2, 1] > 0.08 * c.full[0, 1]  # the whirl pair splits with spin (Coriolis)


def test_campbell_command_draws_and_refuses_bad_rates(tmp_path):
    """`ffrf-fmu campbell` prints the table (reduced against full), draws the PNG, and names a bad
    --rates value and a scene without a rotation drive (exit 2)."""
    from ffrf_fmu.cli import main

    png = tmp_path / "c.png"
    assert main(["campbell", str(MODELS / "haug_solid.toml"), "--rates", "0,4", "--modes", "1", "--full", "--terms", "full",
                 "-o", str(png)]) == 0
    assert png.stat().st_size > 10_000
    assert main(["campbell", str(MODELS / "haug_solid.toml"), "--rates", "0:4"]) == 2
    assert main(["campbell", str(MODELS / "free_beam.toml"), "--rates", "0,4"]) == 2  # no rotation drive


def test_stiffened_solid_fmu_equals_its_standalone_run(tmp_path):
    """haug_solid's stiffened scene as an FMU (the membrane tensors travel as reduced data) under fmpy
    against its standalone run, the first 2 s, within validate's default tolerances."""
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.validate import validate

    model, over = MODELS / "haug_solid.toml", ["duration=2"]
    fmu = build_fmu(model, tmp_path / "s.fmu", scene="spinup_stiffened", overrides=over)
    rep = validate(fmu, model=model, scene="spinup_stiffened", overrides=over, plots=False)
    assert rep["fmu_reached_stop_time"] and rep["fmu_matches_model"] and rep["passed"]
