"""Geometric stiffening inside a superelement (docs/equations.md, "Geometric stiffening").

Independent checks: the closed-form axial force of a spinning bar, finite differences of the
residual, the plain one-superelement oracle, and the full-order geometrically exact reference beam
(ffrf_fmu.reference, no superelement code) for the B1 figures of docs/equations.md, "Geometric stiffening".
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.fe.beam import strain_kernels
from ffrf_fmu.model import Body, ModelError, Port, Section, load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime import equations
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.runtime.data import BodyData

B1_SECTION = Section(EA=5.03e6, GJ=435.38, EI2=566.0, EI3=566.0, m=0.201, m22=22.7e-6, m33=22.7e-6, GA2=1.94e6, GA3=1.94e6)


def _beam(n_se: int, n_el: int, modes: int, hub_rotation="motion") -> Body:
    return Body("b", 8.0, (0, 0, 0), (1, 0, 0), B1_SECTION, n_se, n_el, modes,
                (Port("hub", 0, "motion", hub_rotation), Port("tip", n_se, "force", "force")))


def test_correction_mode_gives_the_axial_force_of_a_spinning_bar():
    """One superelement spun at W about a normal axis through its root: the static state of the
    reduced equations (K q = f0(W) + hub force m W^2 x_cm, the centripetal force of its CM) has the
    axial force N(x) = m W^2 (L^2 - x^2) / 2 of the closed form. With linear axial elements the
    element force is the exact one averaged over the element, so the comparison is exact up to the
    section's rotary inertia (2e-5 of m: 1e-6). Without the correction mode the force is linear in x
    (the attachment shape's): > 10 % off."""
    W, L, m, n_el = 4.0, 8.0, 0.201, 8
    body = _beam(1, n_el, 2)
    for stiff, tol in ((True, 1e-6), (False, None)):
        reduced = reduce_body(body, stiffening=stiff)
        se, Y = reduced.data.superelements[0], reduced.reductions[0].Y
        W1 = se.W1 if stiff else reduce_body(body, stiffening=True).data.superelements[0].W1[: se.n]
        f = 0.5 * np.einsum("a,jab,b->j", [0, 0, W], W1, [0, 0, W])
        f[0] -= se.mass * W**2 * L / 2  # hub pulls the CM inward (x axial dof of node 0)
        q = np.linalg.solve(se.K, f)
        w, A, _, _ = strain_kernels(B1_SECTION, (1, 0, 0), L, n_el)
        N = B1_SECTION.EA * (A @ Y @ q)[::4]  # constant per element
        x = np.linspace(0, L, n_el + 1)
        a, b = x[:-1], x[1:]
        exact = 0.5 * m * W**2 * (L**2 - (a * a + a * b + b * b) / 3)
        err = np.abs(N - exact).max() / exact.max()
        if stiff:
            assert err < tol
        else:
            assert err > 0.1


def _random_state(stiff_scale: float, far_from_reference):
    data = reduce_body(_beam(2, 4, 3, hub_rotation="force"), stiffening=True).data
    ses = tuple(dataclasses.replace(se, W1=se.W1 * stiff_scale) for se in data.superelements)
    s = BodySystem(dataclasses.replace(data, superelements=ses), terms="linear", rho_inf=0.7)
    return s, far_from_reference(s)


@pytest.mark.parametrize("scale", [1.0, 1e5])
def test_newton_jacobian_with_stiffening_matches_finite_differences(scale, far_from_reference, iteration_matrix_error):
    """Iteration matrix against central differences at a random far-from-reference state, as in
    test_dynamics (1e-6 of the largest entry; eps = 1e-6 gives ~1e-8). The W1 terms are ~1e-6 of the
    EA-sized entries at the B1 data, so the second case scales W1 by 1e5 (any W1 is a valid body for
    this identity): then dropping any one of their seven derivative blocks fails by > 1e-4."""
    s, values = _random_state(scale, far_from_reference)
    assert iteration_matrix_error(s, values) <= 1e-6


@pytest.mark.parametrize("backend", ["native", "numpy"])
@pytest.mark.parametrize("terms", ["linear", "gyroscopic"])
def test_stiffened_body_matches_the_plain_oracle(terms, backend, far_from_reference):
    """A stiffened body's equations on each backend (BodySystem._local: the C runtime, the numpy path's
    assembly with the body's hooks) against the oracle's own assembly from the reduced data
    (runtime/equations.py with stiffening.plain_hooks), same state: round-off (1e-12 of each row's
    largest entry)."""
    r, _ = _random_state(1e3, far_from_reference)
    s = BodySystem(r.data, terms=terms, rho_inf=0.7, backend=backend)
    assert s.backend == backend
    s.xN, s.RN, s.x0, s.R0, s.eta, s.v = r.xN, r.RN, r.x0, r.R0, r.eta, r.v
    yd = np.random.default_rng(2).normal(size=s.yd.shape)
    F, Fz, Fy = s._local(s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd, True)
    F0, Fz0, Fy0 = equations.body_residual_and_jacobian(s.data, s.layout, terms, s.gravity, s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd)
    rel = lambda a, b: float((np.abs(a - b) / np.maximum(np.abs(b).max(axis=-1, keepdims=True), 1e-300)).max())
    assert np.abs(F - F0).max() <= 1e-12 * np.abs(F0).max()
    assert rel(Fz, Fz0) <= 1e-12 and rel(Fy, Fy0) <= 1e-12


def test_stiffening_data_round_trips_through_npz(tmp_path):
    """The FMU ships BodyData as npz: the stiffening arrays survive save/load bit for bit, and a body
    built without stiffening stays without (no correction mode, no arrays)."""
    data = reduce_body(_beam(2, 4, 2), stiffening=True).data
    data.save(tmp_path / "b.npz")
    back = BodyData.load(tmp_path / "b.npz")
    for a, b in zip(data.superelements, back.superelements):
        assert b.stiffening and a.n == b.n == 12 + 2 + 1  # one correction mode on a straight beam
        for k in ("W1", "vk_a", "vk_B", "K", "M"):
            assert np.array_equal(getattr(a, k), getattr(b, k))
    plain = reduce_body(_beam(2, 4, 2)).data
    plain.save(tmp_path / "p.npz")
    assert not any(se.stiffening for se in BodyData.load(tmp_path / "p.npz").superelements)
    assert plain.superelements[0].n == 14


def test_stiffening_scene_key_is_validated():
    m = load_model("models/haug_beam.toml", ["stiffening=true"])
    assert all(sc.stiffening for sc in m.scenes)
    assert not load_model("models/haug_beam.toml").scene("spinup").stiffening
    with pytest.raises(ModelError, match=r"scenes\.spinup\.stiffening: expected true or false.*--set stiffening=yes"):
        load_model("models/haug_beam.toml", ["stiffening=yes"])


# ------------------------------------------------------------------------- B1 against the full-order beam
@pytest.fixture(scope="module")
def b1_reference():
    """Full-order geometrically exact beam, 16 elements, h = 10 ms: max tip deflection 0.531784 m,
    7e-5 from the converged value (32 elements, 2 ms: 0.531819, docs/accuracy.md)."""
    from ffrf_fmu.reference import simulate_reference, tip_from_hub

    model = load_model("models/haug_beam.toml")
    ref = simulate_reference(model.body, model.scene("spinup"), n_elements=16, step=0.01)
    return ref.t, tip_from_hub(ref)


@pytest.fixture(scope="module")
def b1_stiff():
    return {n: sim.run_scene("models/haug_beam.toml", "spinup", [f"superelements={n}", "modes=2", "step=0.01", "stiffening=true"])
            for n in (1, 2)}


def _tip(result):
    hub, tip = sim.end_ports(result.body)
    return result.t, sim.elastic_tip(result, hub, tip)


@pytest.mark.parametrize("n, tol", [(1, 5e-3), (2, 2.5e-3)])
def test_b1_stiffened_superelements_match_the_converged_beam(b1_stiff, b1_reference, n, tol):
    """2 modes per SE, h = 10 ms, stiffening on: max tip deflection within 0.5 % (1 SE) and
    0.25 % (2 SE) of the full-order beam (measured +0.16 % and +0.15 %; without stiffening 1 SE is
    13 % high, 2 SE 3.5 %)."""
    t_ref, d_ref = b1_reference
    t, d = _tip(b1_stiff[n])
    assert b1_stiff[n].summary["completed"]
    assert np.abs(d[:, 1]).max() == pytest.approx(np.abs(d_ref[:, 1]).max(), rel=tol)


def test_b1_one_stiffened_superelement_has_the_slow_oscillation_and_the_stretch(b1_stiff, b1_reference):
    """1 SE: the in-plane oscillation after spin-up within 0.8 % of the reference's and the centrifugal
    stretch of the tip at t = 20 s within 0.6 % (docs/equations.md, "Geometric stiffening": measured
    +0.41 % (0.5351 vs 0.5329 Hz) and +0.34 %; each bound is the measured error plus 0.25 % points,
    more than round-off or a step path can move it and less than any physics lost: a linear 1 SE is
    at 0.425 Hz (-20 %) and misses 1/(4 n^2) of the stretch, 23 % for 1 SE). The reference's own
    frequency agrees with the linearized rotating cantilever (docs/background.md, 0.5334 Hz at
    4 rad/s) to 0.3 % (measured -0.09 %; 5 s of signal, 2.7 periods, for the fit)."""
    t_ref, d_ref = b1_reference
    t, d = _tip(b1_stiff[1])
    f_ref = sim.dominant_frequency(t_ref[t_ref > 15], d_ref[t_ref > 15, 1], 0.1, 3.0)
    f = sim.dominant_frequency(t[t > 15], d[t > 15, 1], 0.1, 3.0)
    assert f == pytest.approx(f_ref, rel=0.008)
    assert f_ref == pytest.approx(0.5334, rel=0.003)  # docs/background.md, rotating cantilever table, in-plane at 4 rad/s
    assert d[-1, 0] == pytest.approx(d_ref[-1, 0], rel=0.006)


def test_fmu_carries_stiffening_and_matches_standalone(tmp_path):
    """`stiffening = true` goes into the FMU as reduced data only (the correction mode, W1 and the
    strain tensors in the npz) and its modelDescription says so. Hub spun at a constant 4 rad/s from
    t = 0 (the FMU's extrapolation of the motion inputs is then exact): the beam starts unstretched
    and rings; the hub reaction of the FMU at H = h agrees with the standalone run to 1e-9 of its
    peak (same equations, same data; only the order of the steps' round-off differs)."""
    import zipfile

    from fmpy import read_model_description

    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.fmu.run import run_fmu

    ov = ["superelements=1", "modes=2", "step=0.01", "duration=0.5", "stiffening=true",
          'scenes.spinup.drives.hub.rotation.angle={kind="ramp", rate=4.0, t_start=-1.0}']
    model = load_model("models/haug_beam.toml", ov)
    sc = model.scene("spinup")
    ref = sim.run_scene(model, "spinup")
    fmu = build_fmu("models/haug_beam.toml", tmp_path / "b1s.fmu", scene="spinup", overrides=ov)
    assert "Geometric stiffening inside each superelement: on" in read_model_description(str(fmu)).description
    with zipfile.ZipFile(fmu) as z:
        assert not any(n.endswith(".toml") for n in z.namelist())  # no model file, no FE model
    names = [f"hub.f[{i}]" for i in (1, 2, 3)]
    run = run_fmu(fmu, sc, sim.scene_inputs(ref.body, sc), record=names)
    f_fmu = np.column_stack([run.columns[n] for n in names])
    f_ref = ref.port("hub", "f")
    assert np.abs(f_ref).max() > 1.0  # the spinning beam pulls on the hub
    assert np.abs(f_fmu[1:] - f_ref[1:]).max() <= 1e-9 * np.abs(f_ref).max()


def test_b1_energy_balance_with_stiffening(b1_stiff):
    """External work of the hub drive against kinetic + strain energy, with the stiffening energies
    (the membrane energy V2 in `strain`, 1/2 Omega0^T (W1 q) Omega0 in `kinetic_rigid`): within 1e-4
    of the peak at h = 2 ms (measured 2.1e-5; 1.7e-5 without stiffening), and the gap shrinks as h^2
    from h = 10 ms (measured ratio 24; a term outside the balance would leave an h-independent gap)."""
    fine = sim.run_scene("models/haug_beam.toml", "spinup", ["superelements=1", "modes=2", "step=0.002", "stiffening=true"])
    coarse = b1_stiff[1].summary["energy_balance_max_rel"]
    assert fine.summary["energy_balance_max_rel"] < 1e-4
    assert coarse / fine.summary["energy_balance_max_rel"] > 15.0


B3_OMEGA = "scenes.spinup_fast.drives.hub.rotation.angle.omega"


@pytest.mark.parametrize("omega, tol", [(8.0, 0.007), (12.0, 0.0105), (14.0, 0.013)])
def test_b3_one_stiffened_superelement_follows_the_beam_past_the_first_frequency(omega, tol):
    """B3 (spin-up to omega, up to 4.8 times the first cantilever frequency 2.92 rad/s): one
    superelement with stiffening, 2 modes, h = 10 ms, completes and its max tip deflection is within
    tol of the full-order beam's (16 elements; docs/equations.md measured +0.44 %, +0.78 %, +1.03 % at
    8, 12, 14 rad/s; tol = measured + 0.25 % points, as in the B1 test above; a linear single
    superelement fails past 8-10 rad/s, docs/stability.md)."""
    from ffrf_fmu.reference import simulate_reference, tip_from_hub

    ov = [f"{B3_OMEGA}={omega}"]
    model = load_model("models/haug_beam.toml", ov)
    ref = simulate_reference(model.body, model.scene("spinup_fast"), n_elements=16, step=0.01)
    run = sim.run_scene("models/haug_beam.toml", "spinup_fast", ov + ["superelements=1", "modes=2", "step=0.01", "stiffening=true"])
    assert run.summary["completed"]
    _, d = _tip(run)
    assert np.abs(d[:, 1]).max() == pytest.approx(np.abs(tip_from_hub(ref)[:, 1]).max(), rel=tol)


# ----------------------------------------------------------------------------- term set `full`
FULL = ("inertia_W1", "inertia_W2", "inertia_coupling", "coriolis")


def _full_state(full_terms, stiff: bool, far_from_reference):
    data = reduce_body(_beam(2, 4, 3, hub_rotation="force"), stiffening=stiff, inertia=True).data
    ses = tuple(dataclasses.replace(se, W1=se.W1 * 1e4, W2=se.W2 * 1e4) for se in data.superelements)
    data = dataclasses.replace(data, superelements=ses)
    r, values = _random_state(1.0, far_from_reference)
    s = BodySystem(data, terms="full", full_terms=full_terms, rho_inf=0.7)
    for k in ("xN", "RN", "x0", "R0", "eta", "v", "yd", "a"):
        setattr(s, k, getattr(r, k).copy() if getattr(r, k).shape == getattr(s, k).shape else getattr(s, k))
    return s, values


@pytest.mark.parametrize("full_terms, stiff", [(FULL, False), (FULL, True), (("inertia_W2",), False), (("inertia_W1",), True),
                                               (("inertia_coupling",), False), (("coriolis", "inertia_W2"), False),
                                               (("inertia_W1", "inertia_W2", "inertia_coupling"), True)])
def test_full_term_set_jacobian_and_oracle(full_terms, stiff, far_from_reference, iteration_matrix_error):
    """`full` and its switches: the iteration matrix against central differences (1e-6 of its largest
    entry, W1 and W2 scaled by 1e4 so their blocks are visible) and the body's residual (the C runtime's)
    against the one-superelement oracle (1e-12 per row)."""
    s, values = _full_state(full_terms, stiff, far_from_reference)
    if s.eta.shape != (2, s.layout.nm):
        s.eta = np.zeros((2, s.layout.nm))
    assert iteration_matrix_error(s, values) <= 1e-6
    yd = s.yd + 0.3
    F1, Fz, Fy = s._local(s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd, True)
    # the oracle sees the body's W2 as given, the body subtracts G^T M^-1 G when coriolis
    # is on: hand the oracle the same effective W2
    ses = tuple(dataclasses.replace(se, W2=s.W2[e]) if s.W2 is not None else se for e, se in enumerate(s.data.superelements))
    data = dataclasses.replace(s.data, superelements=ses)
    F0, Fz0, Fy0 = equations.body_residual_and_jacobian(data, s.layout, "full", s.gravity, s.xN, s.RN, s.x0, s.R0, s.eta,
                                                        s.v, yd, full_terms=full_terms)
    rel = lambda a, b: float((np.abs(a - b) / np.maximum(np.abs(b).max(axis=-1, keepdims=True), 1e-300)).max())
    assert np.abs(F1 - F0).max() <= 1e-12 * np.abs(F0).max()
    assert rel(Fz, Fz0) <= 1e-12 and rel(Fy, Fy0) <= 1e-12


@pytest.mark.parametrize("terms", ["gyroscopic", "full"])
def test_full_term_set_conserves_momentum_and_energy(terms):
    """B4 free beam (no loads), one superelement, tumbling with an initial deformation, rho_inf = 1:
    the angular momentum with the full inertia (J0 + W1 q + q W2 q, S(q)) and the energy with
    1/2 Omega^T (W1 q + q W2 q) Omega are conserved to the O(h^2) bound of the scheme (measured over
    1 s at h = 2 ms: gyroscopic 8e-8 / 6e-7, full 1.0e-7 / 5.2e-7); 1e-6 / 3e-6 fail if a term of
    the full set is missing from the equations or from momenta()/energies() (the W1 q term alone
    changes the angular momentum by ~1e-5 here)."""
    m = load_model("models/free_beam.toml", [f"terms={terms}", "duration=1.0", "superelements=1"])
    sc = m.scene("tumble")
    from ffrf_fmu.reduction import reduce_scene_body

    body = reduce_scene_body(m.body, sc).data
    s, inputs = sim.build_system(body, sc, m.body.origin)
    _, L0 = s.momenta()
    E0 = sum(v for k, v in s.energies().items() if k != "work_external")
    dL = dE = 0.0
    while s.t < sc.duration - 1e-9:
        s.step(sc.step, inputs)
        _, L = s.momenta()
        E = sum(v for k, v in s.energies().items() if k != "work_external")
        dL, dE = max(dL, np.abs(L - L0).max() / np.abs(L0).max()), max(dE, abs(E - E0) / abs(E0))
    assert dL < 1e-6 and dE < 3e-6


def test_full_terms_key_is_validated():
    assert load_model("models/haug_beam.toml", ['full_terms=["inertia_W2"]']).scene("spinup").full_terms == ("inertia_W2",)
    with pytest.raises(ModelError, match=r"full_terms: expected an array of Witteveen's terms"):
        load_model("models/haug_beam.toml", ['full_terms=["inertia_W3"]'])
    data = reduce_body(_beam(1, 4, 2)).data
    with pytest.raises(ValueError, match="term set 'full' needs the inertia data"):
        BodySystem(data, terms="full")
