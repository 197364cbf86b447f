"""Two-field superelement dynamics: Jacobian, linearization, and the published benchmarks B1, B2, B4.

Reference values: docs/background.md (Geradin, two-field FFRF paper, sections 9.1-9.2).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla

from ffrf_fmu import simulate as sim
from ffrf_fmu.linear import natural_frequencies
from ffrf_fmu.model import Body, Initial, Port, Section, load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime.ports import StepFailure
from ffrf_fmu.runtime.body import BodySystem

B1_SECTION = Section(EA=5.03e6, GJ=435.38, EI2=566.0, EI3=566.0, m=0.201, m22=22.7e-6, m33=22.7e-6, GA2=1.94e6, GA3=1.94e6)


@pytest.mark.parametrize("terms", ["linear", "gyroscopic"])
def test_newton_jacobian_matches_finite_differences(terms, far_from_reference, iteration_matrix_error):
    """The analytic iteration matrix (incl. SO(3) tangents, vect tangent, gyroscopic terms) equals
    central differences of the residual at a random, far-from-reference state. Central differences
    with eps = 1e-6 on rates of O(1) are accurate to ~1e-8 of the entry; we allow 1e-6."""
    body = Body("j", 8.0, (0, 0, 0), (1, 0, 0), B1_SECTION, 2, 4, 3,
                (Port("hub", 0, "motion", "force"), Port("tip", 2, "force", "force")))
    s = BodySystem(reduce_body(body).data, terms=terms, rho_inf=0.7)
    assert iteration_matrix_error(s, far_from_reference(s)) <= 1e-6


def test_linearized_dynamics_reproduce_modal_frequencies():
    """Small motions of the nonlinear two-field equations about rest have exactly the frequencies of
    the linearized reduced chain (linear.py): two independent codings of the same body (1e-6 rel)."""
    model = load_model("models/haug_beam.toml")
    body = reduce_body(model.body).data
    system, _ = sim.build_system(body, model.scene("spinup"))
    A, B = system.linearization()
    lam = sla.eigvals(-B, A)
    lam = lam[np.isfinite(lam) & (np.abs(lam) < 1e4)]
    dynamic = np.sort(np.abs(lam.imag[lam.imag > 1e-3])) / (2 * np.pi)
    modal = natural_frequencies(body)
    np.testing.assert_allclose(dynamic[:10], modal[:10], rtol=1e-6)
    assert dynamic[0] == pytest.approx(0.4640, rel=5e-3)  # docs/background.md B1 closed form


def _b1(superelements: int):
    return sim.run_scene("models/haug_beam.toml", "spinup", [f"superelements={superelements}"])


@pytest.fixture(scope="module")
def b1_runs():
    return {n: _b1(n) for n in (1, 2, 4)}


PAPER_TABLE_1 = {1: 0.6015, 2: 0.5520, 4: 0.5386}


@pytest.mark.parametrize("n", [1, 2, 4])
def test_b1_max_tip_deflection_matches_paper_table_1(b1_runs, n):
    """Term set `linear`, 6 modes, h = 2 ms, rho_inf = 0.8, as in the paper. Measured gaps to Table 1:
    -0.07 %, -0.29 %, -0.37 % for 1, 2, 4 SE (docs/benchmarks.md; the paper does not give its FE mesh
    per superelement nor its rotary inertia, we use 22.7e-6, docs/background.md, B1 note 2). 0.5 %: above
    those gaps, and a window that tells the chains apart: the neighbouring chain is >= 2.4 % away
    (2 SE 0.5520 vs 4 SE 0.5386) and the converged nonlinear beam (0.5319, 64 elements) is 1.2 %
    below the 4-SE value, so a chain that recovered the full stiffening would fail."""
    m = b1_runs[n].summary["metrics"]
    assert b1_runs[n].summary["completed"]
    assert m["tip_deflection_max_m"] == pytest.approx(PAPER_TABLE_1[n], rel=5e-3)


def test_b1_deflection_decreases_with_superelements(b1_runs):
    """More superelements carry the centrifugal axial force between CM frames: geometric stiffening."""
    d = [b1_runs[n].summary["metrics"]["tip_deflection_max_m"] for n in (1, 2, 4)]
    assert d[0] > d[1] > d[2]


def test_b1_shortening_and_rigid_energy(b1_runs):
    """Axial shortening ~0.28 % of L at the peak (paper 9.2) and rigid kinetic energy at full speed
    m L^3 w^2 / 6 = 274.43 J (no hub inertia). 10 % on the shortening: the paper prints two digits.
    The energy is averaged over t > 16 s, where the beam swings about the steady spin (its peak
    overshoots by ~0.2 %); 0.1 %: the rotary inertia adds 4e-6 of it, the elastic motion less."""
    r = b1_runs[1]
    assert -r.summary["metrics"]["tip_axial_at_max_m"] / 8.0 == pytest.approx(0.0028, rel=0.1)
    spinning = r.t > 16.0
    assert np.mean(r.columns["energy.kinetic_rigid"][spinning]) == pytest.approx(0.201 * 8.0**3 * 16 / 6, rel=1e-3)


@pytest.mark.xfail(strict=True, reason="we measure 0.52 Hz, not the paper's 0.446 Hz; see docs/benchmarks.md "
                   "(a spinning cantilever stiffens: Southwell gives ~0.54 Hz at 4 rad/s)")
def test_b1_slow_oscillation_after_spin_up(b1_runs):
    """After spin-up (t > 15 s) a slow oscillation of 0.446 Hz remains with 4 SE (paper 9.2). 5 %:
    the frequency is read from 5 s of signal (about two periods)."""
    f = b1_runs[4].summary["metrics"]["oscillation_frequency_hz"]
    assert f == pytest.approx(0.446, rel=0.05)


def test_b1_slow_oscillation_matches_nonlinear_reference(b1_runs):
    """Our 4-SE oscillation after spin-up against the independent geometrically exact beam
    (16 elements). Both see the centrifugal stiffening of the spinning cantilever (Southwell:
    sqrt(w0^2 + (1.19 - 1) W^2) -> 0.54 Hz at 4 rad/s). 5 %: four superelements recover the
    stiffening only partly (the peak deflection is 1 % high for the same reason)."""
    from ffrf_fmu.reference import simulate_reference, tip_from_hub

    model = load_model("models/haug_beam.toml")
    ref = simulate_reference(model.body, model.scene("spinup"), n_elements=16, step=0.01)
    d = tip_from_hub(ref)
    after = ref.t > 15.0
    f_ref = sim.dominant_frequency(ref.t[after], d[after, 1], 0.1, 2.0)
    assert b1_runs[4].summary["metrics"]["oscillation_frequency_hz"] == pytest.approx(f_ref, rel=0.05)
    assert f_ref == pytest.approx(0.54, rel=0.05)


@pytest.mark.parametrize("n", [1, 4])
def test_b1_energy_balance(b1_runs, n):
    """External work of the hub drive against the sum of the energies: within 1 % of the peak."""
    assert b1_runs[n].summary["energy_balance_max_rel"] < 0.01


@pytest.fixture(scope="module")
def b2_run():
    return sim.run_scene("models/spherical_beam.toml", "torque_then_tip")


def test_b2_published_values(b2_run):
    """Paper 9.1 with our reconstruction of the load windows (docs/background.md B2).
    omega_z after the torque: 3 % (rigid estimate 2000/66183 = 0.0302 is itself 2.4 % above the
    printed 0.0295); mean omega_y after the tip impulse: 6 % (the full-order beam gives -0.041005,
    5.5 % from the printed -0.0434, docs/accuracy.md; this run -0.041219, 0.5 % from the full-order
    beam: the published value, not the model, sets the margin); hinged-free frequency 1.74 Hz: 2 %."""
    m = b2_run.summary["metrics"]
    assert b2_run.summary["completed"]
    assert m["omega_z_at_15s"] == pytest.approx(0.0295, rel=0.03)
    assert m["omega_y_mean_after_load"] == pytest.approx(-0.0434, rel=0.06)
    assert m["tip_frequency_hz"] == pytest.approx(1.74, rel=0.02)
    assert b2_run.summary["energy_balance_max_rel"] < 0.01


def test_b4_free_body_conserves_momentum_and_energy():
    """B4: free flight, spin about a non-principal axis plus an initial bend. Linear momentum is
    conserved to round-off (the scheme is linear in it). Angular momentum and energy are quadratic:
    the trapezoidal-like scheme (rho_inf = 1) keeps them to a bounded O(h^2) oscillation without
    drift; the bound we state, measured at h = 2 ms, is 1e-4 relative."""
    model = load_model("models/free_beam.toml", ["duration=2.0"])
    r = sim.run_scene(model, "tumble")
    m = r.summary["metrics"]
    assert r.summary["completed"]
    assert m["linear_momentum_drift_rel"] < 1e-12
    assert m["angular_momentum_drift_rel"] < 1e-4
    assert m["total_energy_drift_rel"] < 1e-4


def test_b4_angular_momentum_error_is_second_order_in_h():
    """Halving the step divides the angular momentum error by ~4 (2nd order, no secular drift)."""
    errs = []
    for h in (2e-3, 1e-3):
        model = load_model("models/free_beam.toml", ["duration=0.5", f"step={h}"])
        scene = dataclasses.replace(model.scene("tumble"), initial=Initial(angular_velocity=(0.3, 0.5, 2.0)))
        r = sim.run_scene(dataclasses.replace(model, scenes=(scene,)))
        errs.append(r.summary["metrics"]["angular_momentum_drift_rel"])
    assert 3.0 < errs[0] / errs[1] < 5.0


def test_step_failure_names_time_and_cause():
    """A NaN input is reported as a StepFailure naming the port, the input and the time."""
    model = load_model("models/haug_beam.toml")
    body = reduce_body(model.body).data
    system, inputs = sim.build_system(body, model.scene("spinup"))

    def bad(t):
        values = inputs(t)
        values["hub"].w = np.array([np.nan, 0.0, 0.0])
        return values

    with pytest.raises(StepFailure, match=r"t = 0.002.*'hub'.*input w"):
        system.step(0.002, bad)


def test_state_roundtrip_is_bit_identical():
    """get_state / set_state restore everything the next step depends on (FMU rollback)."""
    model = load_model("models/haug_beam.toml", ["superelements=2"])
    body = reduce_body(model.body).data
    system, inputs = sim.build_system(body, model.scene("spinup"))
    for _ in range(5):
        system.step(0.01, inputs)
    saved = system.get_state()
    system.step(0.01, inputs)
    first = sim.record(system)
    system.set_state(saved)
    system.step(0.01, inputs)
    assert np.array_equal(first, sim.record(system))


@pytest.mark.parametrize("duration, steps", [(0.009, 5), (0.011, 6), (0.010, 5)])
def test_duration_not_a_whole_number_of_steps_is_not_rounded(duration, steps):
    """Step 2 ms: 0.009 s and 0.011 s are no whole number of steps. The run must end at the
    duration (not at 0.008 or 0.012 s), with the step reduced to divide it (duration / ceil, as the
    reference solver does) and a warning that says so; 0.010 s keeps the step, silently."""
    model = load_model("models/haug_beam.toml", ["superelements=1", "modes=2", f"duration={duration}", "step=0.002"])
    if steps * 0.002 == pytest.approx(duration):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("error")
            r = sim.run_scene(model, "spinup")
        assert r.summary["step"] == 0.002
    else:
        with pytest.warns(UserWarning, match=rf"not a whole number of steps.*reduced to {duration / steps:.6g} s"):
            r = sim.run_scene(model, "spinup")
        assert r.summary["step"] == pytest.approx(duration / steps, rel=1e-12) and r.summary["step_requested"] == 0.002
    assert r.summary["completed"] and r.summary["steps"] == steps == len(r.t) - 1
    assert r.t[-1] == pytest.approx(duration, rel=1e-12)
