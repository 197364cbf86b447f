"""Stability boundaries (docs/stability.md): one configuration on each side of every boundary the
maps found, so that a change that moves a boundary is noticed. The maps themselves (docs/
stability_*.csv) come from `ffrf-fmu stability`; these tests rerun single points, shortened to the
time the mechanism needs (each test says why its duration is enough).
"""
from __future__ import annotations

from pathlib import Path

import fmpy  # noqa: F401 - core dependencies (the co-simulation tests): a broken install fails, never skips
import libcosimpy.CosimExecution  # noqa: F401 - loads libcosim's shared library
import numpy as np
import pytest
import pythonfmu  # noqa: F401

from ffrf_fmu.model import load_model
from ffrf_fmu.reference.solver import ENERGY_ERROR_SUSPECT
from ffrf_fmu.studies import stability as st
from ffrf_fmu.studies.runners import run_beam, run_reference, transverse

ROOT = Path(__file__).resolve().parent.parent
HAUG = ROOT / "models" / "haug_beam.toml"
SPHERICAL = ROOT / "models" / "spherical_beam.toml"


# ------------------------------------------------------------------------------------ helpers

def test_csv_round_trip(tmp_path):
    """map.csv (table.py): numbers, booleans, texts and empty cells come back as written."""
    from ffrf_fmu.studies.table import read_rows, write_rows

    rows = [{"a": 1.5, "b": "x", "u": True, "n": 3}, {"a": 2.0, "b": "y", "u": False, "c": 3.0, "f": None}]
    write_rows(tmp_path / "m.csv", rows)
    back = read_rows(tmp_path / "m.csv", text=("b",))
    assert back[0]["a"] == 1.5 and back[0]["u"] is True and back[1]["u"] is False and back[1]["c"] == 3.0
    assert back[0]["n"] == 3 and back[1]["b"] == "y" and back[0]["c"] is None and back[1]["f"] is None


def test_split_models_are_the_halves_of_the_beam(tmp_path):
    a, b = st.split_models(HAUG, tmp_path)
    ma, mb, m = load_model(a), load_model(b), load_model(HAUG)
    assert ma.body.modes == mb.body.modes == m.body.modes and ma.scene("run").step == m.scene("spinup").step
    assert ma.body.length + mb.body.length == pytest.approx(m.body.length)
    assert ma.body.superelements + mb.body.superelements == m.body.superelements
    assert mb.body.origin[0] == pytest.approx(m.body.length / 2)
    assert ma.body.section == m.body.section == mb.body.section
    assert {(p.name, p.translation) for p in ma.body.ports} == {("hub", "motion"), ("cut", "force")}
    assert {(p.name, p.translation) for p in mb.body.ports} == {("cut", "motion"), ("tip", "force")}


# ------------------------------------------------------------------------------------ the hub drive FMU

@pytest.fixture(scope="module")
def hub_drive(tmp_path_factory):
    from ffrf_fmu.examples import build_hub_drive

    return build_hub_drive(tmp_path_factory.mktemp("drive") / "hub_drive.fmu")


def test_hub_drive_is_valid_and_follows_ports_md(hub_drive):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(hub_drive)) == []
    md = read_model_description(str(hub_drive))
    caus = {v.name: v.causality for v in md.modelVariables}
    assert all(caus[f"hub.R[{i},{j}]"] == "input" for i in (1, 2, 3) for j in (1, 2, 3))
    assert all(caus[f"hub.{f}[{i}]"] == "input" for f in "wf" for i in (1, 2, 3))
    assert all(caus[f"hub.{f}[{i}]"] == "output" for f in "rvt" for i in (1, 2, 3))
    assert md.coSimulation.canGetAndSetFMUstate


def test_hub_drive_torque_sign_and_rollback(hub_drive):
    """Beam root fixed at rest (R = I, w = 0), the motor turns the hub ahead: the shaft twist is
    positive, the torque on the beam positive, and hub.t (the moment of the beam ON the drive) is
    minus it. A restored FMU state repeats the steps exactly."""
    from ffrf_fmu.master import FmuInstance

    inst = FmuInstance("drive", hub_drive, start_values={"profile.T": 0.5})
    try:
        f = inst.fmu
        f.setupExperiment(startTime=0.0)
        inst.set_start_values()
        f.enterInitializationMode()
        f.exitInitializationMode()
        for k in range(20):
            f.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
        state = f.getFMUstate()
        out = ["drive.angle", "drive.shaft_torque", "hub.t[3]", "drive.speed"]
        before = inst.get(out)
        assert before[0] > 0 and before[1] > 0
        assert before[2] == pytest.approx(-before[1])
        # the FMU's defaults are the B5 configuration of the maps (stability.DRIVE): undamped shaft
        from ffrf_fmu.examples.hub_drive_slave import PARAMETERS

        assert all(PARAMETERS[k][0] == v for k, v in st.DRIVE.items()) and st.DRIVE["drive.c"] == 0.0
        assert before[1] == pytest.approx(st.DRIVE["drive.k"] * before[0], rel=1e-12)
        for k in range(20, 25):
            f.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
        after = inst.get(out)
        f.setFMUstate(state)
        assert np.array_equal(inst.get(out), before)
        for k in range(20, 25):
            f.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
        assert np.array_equal(inst.get(out), after)
        f.freeFMUstate(state)
    finally:
        inst.close()


# ------------------------------------------------------------------------------------ co-simulation map

@pytest.fixture(scope="module")
def motor(tmp_path_factory):
    return st.CosimCase("motor", HAUG, tmp_path_factory.mktemp("motor"), st.CosimSettings())


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    return st.CosimCase("split", HAUG, tmp_path_factory.mktemp("split"), st.CosimSettings())


def test_split_beam_explicit_is_unstable_implicit_is_exact(split):
    """The beam cut at its middle node: explicit Gauss-Seidel lags the interface force one step
    behind an interface mass of the same order on both sides (added-mass instability): Newton fails
    within ~50 ms at H = 2 ms, as at every H of the map. Implicit coupling (FMU rollback, IQN-ILS)
    solves the node equilibrium at every step end: it equals the one-body FMU (same superelements,
    internal step = H) to the coupling tolerance. 0.1 s: the explicit run fails at ~0.045 s."""
    H = 0.002
    one = split.run(H, one_body=True, duration=0.1)
    explicit = split.run(H, "gauss-seidel", duration=0.1)
    assert "Newton" in explicit.stopped_early and explicit.t[-1] < 0.08
    implicit = split.run(H, "gauss-seidel", iterations=50, duration=0.1)
    assert implicit.stopped_early == ""
    scale = np.max(one.deflection)
    assert scale > 1e-3  # the beam bends (fast spin-up, T = 1 s): the comparison means something
    assert np.max(np.abs(implicit.deflection - one.deflection)) < 1e-6 * scale
    assert 1.0 < implicit.sweeps < 10.0


def test_split_beam_interface_jacobian_is_stable_at_10_ms_and_equals_the_one_body(split):
    """Linearly implicit coupling (coupling Jacobian of the sweep, one linear solve, one real step;
    no iteration): at H = 10 ms, where every explicit scheme fails within 15-30 steps
    (docs/stability.md), the split beam follows the one-body FMU. The rigid joint makes the
    interface equations nearly linear over a step, so the one Newton step lands within 1e-6 of the
    peak. The Jacobian from the FMUs' directional derivatives (the default: both halves provide
    them) gives the run of the finite-difference Jacobian: measured 2.8e-8 of the peak apart over
    0.2 s, 2.7e-8 and 8.9e-9 from the one body; sweeps: 2 (G(x0) and the real step) against 8
    (+ one per iterated input: cut force and moment)."""
    H = 0.01
    one = split.run(H, one_body=True, duration=0.2)
    lin = split.run(H, "gauss-seidel", duration=0.2, interface_jacobian=True)
    fd = split.run(H, "gauss-seidel", duration=0.2, interface_jacobian=True, jacobian="fd")
    assert lin.stopped_early == "" and fd.stopped_early == ""
    scale = np.max(one.deflection)
    assert scale > 1e-3  # the beam bends: the comparison means something
    assert np.max(np.abs(lin.deflection - one.deflection)) < 1e-6 * scale
    assert np.max(np.abs(fd.deflection - one.deflection)) < 1e-6 * scale
    assert np.max(np.abs(lin.deflection - fd.deflection)) < 1e-6 * scale
    # exact counts by construction, not by convergence (no round-off can change them): the linearly
    # implicit scheme always makes 2 sweeps a step, its finite-difference Jacobian 6 more (one re-run per
    # input of the cut: force and moment); passes the round-off check of .ci/run
    assert lin.sweeps == 2.0 and fd.sweeps == 8.0


def test_split_beam_acceleration_links_carry_the_partner_accelerations(split):
    """connect_ports(..., accelerations=True): B's motion inputs B.cut.a, B.cut.dw are A's outputs
    A.cut.a, A.cut.dw, fresh in Gauss-Seidel (A steps first: equal at every communication point)
    and one step old in Jacobi; without the option they stay at their start value 0. The
    interface-Jacobian run with them is the run without them (docs/cosim.md, "Acceleration links"):
    at internal step = H a body evaluates its motion inputs at t_c + H only, where the fresh rule
    ends on A's frame and rate with or without a; measured 5.1e-12 of the peak apart over 0.2 s
    (the different arithmetic, kept by the Newton iterations), both 1.2e-7 from the one body."""
    from ffrf_fmu.master import CoSimulation

    names = [f"cut.{f}[{i}]" for f in ("a", "dw") for i in (1, 2, 3)]
    H, sv = 0.01, {"A.solver.step": 0.01, "B.solver.step": 0.01}
    got = {}
    for scheme, acc in (("gauss-seidel", True), ("jacobi", True), ("gauss-seidel", False)):
        with CoSimulation(split.fmus, step=H, scheme=scheme, start_values=sv) as sim:
            sim.connect_ports("A", "cut", "B", "cut", accelerations=acc)
            res = sim.run(0.05, sources=split._hub_sources("A"), record=[f"{p}.{n}" for p in "AB" for n in names])
        got[scheme, acc] = [np.stack([res.columns[f"{p}.{n}"] for n in names], -1) for p in "AB"]
    a, b = got["gauss-seidel", True]
    assert np.max(np.abs(a[2:, :])) > 1e-3  # the cut accelerates (spin-up): the comparison means something
    assert np.array_equal(b, a)
    a, b = got["jacobi", True]
    assert np.array_equal(b[1:], a[:-1])
    a, b = got["gauss-seidel", False]
    assert np.max(np.abs(a)) > 1e-3 and not b.any()
    one = split.run(H, one_body=True, duration=0.2)
    without = split.run(H, "gauss-seidel", duration=0.2, interface_jacobian=True)
    lin = split.run(H, "gauss-seidel", duration=0.2, interface_jacobian=True, accelerations=True)
    scale = np.max(one.deflection)
    assert lin.stopped_early == "" and scale > 1e-3
    assert np.max(np.abs(lin.deflection - without.deflection)) < 1e-9 * scale
    assert np.max(np.abs(lin.deflection - one.deflection)) < 1e-6 * scale


def test_cosim_map_row_on_the_pool_equals_the_direct_run(tmp_path):
    """The co-simulation map through the sweep layer (runner "cosim" on a two-process pool; each
    worker builds the split case's FMUs itself) gives the numbers of the same runs made directly
    here: split beam, H = 10 ms, 0.1 s, Jacobi and the monolithic reference, the one-body scene
    standalone (same code, same FMUs built from the same model: bit-identical)."""
    from ffrf_fmu.studies.stability.case import COSIM_SCHEMES
    from ffrf_fmu.studies.stability.cosim import compare
    from ffrf_fmu.studies.stability.monolithic import split_monolithic
    from ffrf_fmu.studies.sweep import Scheduler

    s = st.CosimSettings(split_steps=(0.01,), split_duration=0.1, schemes=COSIM_SCHEMES[:1])
    rows = st.cosim_map(HAUG, s, tmp_path, cases=("split",), sweep=st.SweepOptions(Scheduler("pool", 2), progress=False))
    by = {r["scheme"]: r for r in rows}
    assert set(by) == {"monolithic reference", "jacobi", "gauss-seidel implicit", "interface-jacobian"}
    case = st.CosimCase("split", HAUG, tmp_path / "direct", s)
    ref, run = split_monolithic(HAUG, s, 0.01), case.run(0.01, "jacobi")
    direct = compare(run, ref, case.length, float(np.max(np.abs(ref.torque))))
    assert by["jacobi"]["rel_error"] == direct["rel_error"] and by["jacobi"]["failure"] == direct["failure"]
    assert by["monolithic reference"]["t_end"] == pytest.approx(0.1)
    assert by["jacobi"]["verdict"] == direct["verdict"] and by["gauss-seidel implicit"]["verdict"] == "stable"


# ------------------------------------------------------------------------------------ spin map (B3)

def test_one_superelement_loses_stability_at_constant_spin():
    """One superelement, spun at a constant rate and kicked: bounded at 7 rad/s, diverging at
    10 rad/s (the tip passes L within 2.4 s; docs/stability.md: the missing tension-rotation
    stiffening inside the superelement). 4.5 s at 7 rad/s: the envelope of an unstable mode at
    9 rad/s already grows x3.8 in 6 s; at 7 rad/s it stays within 2 %."""
    stable = st.steady_spin(HAUG, "spinup_fast", 7.0, n_se=1, terms="gyroscopic", duration=4.5)
    assert not stable["unstable"] and stable["growth"] < 1.2, stable
    unstable = st.steady_spin(HAUG, "spinup_fast", 10.0, n_se=1, terms="gyroscopic", duration=4.5)
    assert unstable["unstable"] and "> 8 m" in unstable["failure"] and unstable["t_end"] < 3.0, unstable


def test_several_superelements_recover_the_stiffening_at_12_rad_s():
    """The spin-up of the map (Wu-Haug profile to 12 rad/s, T = 7.5 s) over its first 4.5 s (the
    deflection peaks at ~4 s): 4 superelements (linear term set) stay within 3.5 % of the nonlinear
    beam's peak (map and measured here: +2.75 %; the bound leaves room for the reference's own
    spatial error and separates 4 SE from 2 SE, +16 %); one superelement bends past L at ~4.1 s."""
    ov = st.spin_overrides("spinup_fast", 12.0, T=7.5, duration=4.5)
    ref = run_reference(str(HAUG), "spinup_fast", ov, 16, st.reference_step(12.0))
    assert ref["energy_error"] < ENERGY_ERROR_SUSPECT  # the reference is trusted
    d_ref = transverse(ref["d"], np.array([1.0, 0.0, 0.0]))
    four = run_beam(*_model_scene(12.0, 4, "linear"), record_every=10)
    assert not four.unstable
    assert abs(four.max_deflection - np.max(d_ref)) < 0.035 * np.max(d_ref)
    one = run_beam(*_model_scene(12.0, 1, "linear"), record_every=10)
    assert one.unstable and "> 8 m" in one.failure


def _model_scene(omega, n_se, terms, T=7.5, duration=4.5):
    return st.spin_scene(HAUG, "spinup_fast", omega, T=T, duration=duration, n_se=n_se, terms=terms)


def test_spin_map_marks_rows_whose_reference_is_suspect(tmp_path, monkeypatch):
    """The spin map compares every model with the nonlinear reference; a reference whose energy error
    exceeds the solver's warning level (2 %) is marked in its row and in every row compared with it.
    Here the reference is forced coarse (4 elements, h = 0.1 s over a 1.5 s spin-up to 4 rad/s:
    measured energy error 10.6 %); the 1-SE model run is short (1.5 s)."""
    from ffrf_fmu.studies.stability import spin

    monkeypatch.setattr(spin, "reference_step", lambda omega: 0.1)
    settings = st.SpinSettings(omegas=(4.0,), models=((1, "linear"),), T=1.5, duration=1.5, reference_elements=4)
    rows = st.spin_map(HAUG, "spinup_fast", settings, tmp_path, st.SweepOptions(progress=False))
    assert [r["model"] for r in rows] == ["reference", "1SE-linear"]
    assert rows[0]["ref_energy_error"] > ENERGY_ERROR_SUSPECT
    assert all(r["reference_suspect"] for r in rows)
    assert all(r["reference_suspect"] is True for r in st.read_map(tmp_path / "map.csv"))


def test_spin_map_row_on_the_pool_equals_the_direct_run(tmp_path):
    """The spin map through the sweep layer on a two-process pool gives the numbers of the runs made
    directly in this process (same code, same inputs: bit-identical): the model row's maximum
    deflection is runners.run_beam's, the reference row's is the full-order beam's. A rerun takes
    every run from the store. 4 rad/s, spin-up 2 s, 1.2 s, 1 SE; reference 4 elements at 20 ms."""
    from ffrf_fmu.studies.sweep import Scheduler
    from ffrf_fmu.studies.stability import spin

    settings = st.SpinSettings(omegas=(4.0,), models=((1, "linear"),), T=2.0, duration=1.2, reference_elements=4)
    pool = st.SweepOptions(Scheduler("pool", 2), progress=False)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(spin, "reference_step", lambda omega: 0.02)  # the parent names the step: the workers get it
        rows = st.spin_map(HAUG, "spinup_fast", settings, tmp_path, pool)
    ref, model_row = rows
    direct = run_beam(*_model_scene(4.0, 1, "linear", T=2.0, duration=1.2), record_every=spin.RECORD_EVERY)
    assert model_row["max_deflection"] == direct.max_deflection and not model_row["unstable"]
    ov = st.spin_overrides("spinup_fast", 4.0, T=2.0, duration=1.2)
    d_ref = transverse(run_reference(str(HAUG), "spinup_fast", ov, 4, 0.02)["d"], np.array([1.0, 0.0, 0.0]))
    assert ref["max_deflection"] == float(np.max(d_ref)) and ref["first_frequency_rad_s"] == pytest.approx(2.915, rel=2e-3)
    assert model_row["rel_error"] == pytest.approx(direct.max_deflection / np.max(d_ref) - 1.0, rel=1e-12)
    lines = (tmp_path / "runs.jsonl").read_text().count("\n")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(spin, "reference_step", lambda omega: 0.02)
        again = st.spin_map(HAUG, "spinup_fast", settings, tmp_path, pool)
    assert again == rows and (tmp_path / "runs.jsonl").read_text().count("\n") == lines == 2


# ------------------------------------------------------------------------------------ integrator map

def test_b1_newton_fails_between_100_and_200_ms():
    """B1 as in the map (T = 7.5 s, 10 s, rho_inf 0.8): h = 20 ms runs through (max deflection
    within 0.2 % of the converged run, measured 0.15 %); h = 50 ms runs through (per-field
    convergence, refresh when 3 more iterations would not do), max deflection 0.96 % above the
    converged run (bound 1.5 %: the error is the step's, second order); h = 100 ms runs through
    (co-rotated predictor, matrix rebuilt at the predictor), max deflection 4.0 % above (bound 5 %);
    h = 200 ms loses Newton convergence (docs/stability.md, section 2). When is marginal: from t = 0.8 s
    every step's first increment is 1e7-1e9 tolerances and takes 5-25 iterations on the numpy path
    whatever the reuse rule; the C runtime gave up at t = 5 s with the rule before runtime/newton.py's
    KEPT_RADIUS transient allowance, at t = 1.4 s with it (measured 2026-12-08)."""
    s = st.IntegratorSettings(**st.INTEGRATOR_DEFAULTS[("haug_beam", "spinup")])
    ok, _ = st.integrator_run(HAUG, "spinup", 0.02, 0.8, s)
    assert ok.completed and ok.t[-1] == pytest.approx(10.0)
    assert ok.max_deflection == pytest.approx(1.1014, rel=2e-3)  # converged (h = 0.5 ms): 1.10140 m
    coarse, _ = st.integrator_run(HAUG, "spinup", 0.05, 0.8, s)
    assert coarse.completed and coarse.max_deflection == pytest.approx(1.1014, rel=1.5e-2)
    coarser, _ = st.integrator_run(HAUG, "spinup", 0.1, 0.8, s)
    assert coarser.completed and coarser.max_deflection == pytest.approx(1.1014, rel=5e-2)
    bad, _ = st.integrator_run(HAUG, "spinup", 0.2, 0.8, s)
    assert bad.unstable and "Newton" in bad.failure and bad.t[-1] < 6.0


def test_b2_runs_through_at_200_ms_and_500_ms():
    """B2 (20 s), with each load window applied as its mean over the step (docs/equations.md, "Loads
    between steps"): rho_inf = 0.8 runs through at h = 0.2 s and at h = 0.5 s, one step longer than the
    0.2 s tip-load window (the step carries the window's impulse as 40 N over 0.5 s, where the former point
    rule applied the full 100 N over the whole step: 2.5 x the impulse, and Newton failed at 15.5 s).
    The trapezoidal rule (rho_inf = 1, no dissipation) is not asserted: its verdicts are marginal and
    depend on the CPU's round-off. Measured: at h = 0.2 s it failed at t = 19.2 s on one x86-64 CPU and
    ran through on another; at h = 0.5 s it failed at t = 17 s (a rotation increment over pi) on one and
    ran through on another; at h = 1 s Newton failed at t = 17 s (docs/stability.md, "Marginal points")."""
    s = st.IntegratorSettings(**st.INTEGRATOR_DEFAULTS[("spherical_beam", "torque_then_tip")])
    for h in (0.2, 0.5):
        ok, _ = st.integrator_run(SPHERICAL, "torque_then_tip", h, 0.8, s)
        assert ok.completed and ok.t[-1] == pytest.approx(20.0)


# ------------------------------------------------------------------------------------ established engine

def test_libcosim_fixed_step_agrees_with_the_master_jacobi(split, motor, tmp_path):
    """libcosim (libcosimpy, OSP) loads the pythonfmu FMUs from a generated SSD and runs its
    fixed-step algorithm, a Jacobi scheme with held inputs: the same discrete map as
    master.CoSimulation(scheme="jacobi"). Split beam: the same trajectory to round-off and the
    same failing step (added-mass instability, t = 0.044 s at H = 2 ms); motor case: the same
    trajectory to round-off over 0.3 s."""
    lc = split.libcosim(0.002, 0.06, tmp_path / "split")
    ours = split.run(0.002, "jacobi", duration=0.06)
    assert lc.stopped_early and ours.stopped_early and lc.t[-1] == pytest.approx(ours.t[-1])
    n = len(lc.t)
    assert np.allclose(lc.deflection, ours.deflection[1:n + 1], rtol=1e-9, atol=1e-12)
    lc = motor.libcosim(0.004, 0.3, tmp_path / "motor")
    ours = motor.run(0.004, "jacobi", duration=0.3)
    assert lc.stopped_early == "" and ours.stopped_early == ""
    n = len(lc.t)
    assert n == len(ours.t) - 1
    assert np.max(np.abs(lc.deflection - ours.deflection[1:])) <= 1e-9 * np.max(ours.deflection)
    assert np.max(np.abs(lc.torque - ours.torque[1:])) <= 1e-9 * np.max(np.abs(ours.torque))


@pytest.fixture(scope="module")
def motor_monolithic():
    """B5's monolithic run over its first 3 s at h = 2 ms (monolithic.b5_monolithic: beam, shaft,
    hub and PI drive integrated together, no FMUs, no master). The map's reference takes h = 1 ms;
    over these 3 s the two differ by 6.1e-7 of the peak deflection (7.4e-7 of the peak root rate),
    measured, far below every error checked against it."""
    from ffrf_fmu.studies.stability.monolithic import b5_monolithic

    run = b5_monolithic(HAUG, st.CosimSettings(), 0.002, duration=3.0)
    assert run.stopped_early == "" and run.t[-1] == pytest.approx(3.0)
    return run


def test_b5_monolithic_run_is_the_coupled_system_solved_together(motor, motor_monolithic):
    """The monolithic run and the two FMUs under implicit coupling (rollback, IQN-ILS to 1e-6) at
    H = h = 2 ms solve the same system by different means (the drive FMU: RK4 substeps of 0.5 ms,
    inputs extrapolated over the step; the monolithic run: generalized-alpha for the hub too, the
    hub equation solved with the body's step): measured 7.1e-7 of the peak deflection and 1.3e-6 of
    the peak root rate over 3 s; over this 1 s bound 1e-5 (a wrong shaft sign, stiffness or PI law
    is off by orders more). Each step takes about 3 body steps (secant on the hub equation)."""
    imp = motor.run(0.002, "gauss-seidel", iterations=50, duration=1.0)
    ref = motor_monolithic
    assert imp.stopped_early == ""
    inside = ref.t <= 1.0 + 1e-12
    for a, b in ((imp.deflection, ref.deflection), (imp.speed, ref.speed), (imp.torque, ref.torque)):
        assert np.max(np.abs(np.interp(ref.t[inside], imp.t, a) - b[inside])) <= 1e-5 * np.max(np.abs(b[inside]))
    assert 2.0 <= ref.sweeps <= 4.0


def test_motor_plain_gauss_seidel_is_stable_at_2_ms_and_inaccurate_at_10_ms(motor, motor_monolithic):
    """Plain Gauss-Seidel on B5, both sides of its accuracy boundary, judged by the map's own
    verdict (cosim.compare: stable = completes AND errors <= cosim.ACCURACY_BOUND = 1 % of the
    monolithic peaks). Over 3 s: at 2 ms 5.3e-4 (deflection) / 2.7e-4 (root rate), stable; at 10 ms
    the run completes but the root rate is off by 2.0 % of its peak (measured), inaccurate; over the
    whole 10 s scene it fails (docs/stability.md)."""
    from ffrf_fmu.studies.stability.cosim import ACCURACY_BOUND, compare

    peak = float(np.max(np.abs(motor_monolithic.torque)))
    ok = compare(motor.run(0.002, "gauss-seidel", duration=3.0), motor_monolithic, 8.0, peak)
    assert ok["verdict"] == "stable" and max(ok["rel_error"], ok["speed_rel_error"]) < 1e-3, ok
    bad = compare(motor.run(0.01, "gauss-seidel", duration=3.0), motor_monolithic, 8.0, peak)
    assert bad["verdict"] == "inaccurate" and not bad["unstable"], bad
    assert bad["speed_rel_error"] > 1.5 * ACCURACY_BOUND, bad


def _deflection_error(run, ref) -> float:
    """max |d - d_ref| / max |d_ref| over the reference's time span (the run may be longer)."""
    inside = run.t <= ref.t[-1] * (1 + 1e-12)
    assert run.t[inside][-1] == pytest.approx(ref.t[-1])  # the run covers the whole reference: no held values
    return float(np.max(np.abs(run.deflection[inside] - np.interp(run.t[inside], ref.t, ref.deflection)))
                 / np.max(np.abs(ref.deflection)))


def test_motor_gauss_seidel_with_extrapolation_boundary_between_2_and_10_ms(motor, motor_monolithic):
    """Beam FMU + hub drive FMU (undamped shaft k = 300 N m/rad on the beam root): explicit
    Gauss-Seidel with extrapolated torque is stable at H = 2 ms and diverges at H = 10 ms once the
    beam spins fast (the body refuses a step at 4.9 s: Newton, or the guard against a rotation
    increment beyond pi). 6.5 s: past the failure at 10 ms. The 2 ms run agrees
    with the monolithic run: map 3.2e-4 of the peak deflection over 10 s, measured 2.66e-4 over
    the first 3 s; bound 4e-4 (the map's figure with a margin; a coupling error of first order in H
    that grows would exceed it)."""
    ok = motor.run(0.002, "gauss-seidel", extrapolation=True, duration=6.5)
    assert ok.stopped_early == "" and ok.t[-1] == pytest.approx(6.5)
    assert np.max(motor_monolithic.deflection) > 1.0  # the beam bends (1.15 m by 3 s): the error means something
    assert _deflection_error(ok, motor_monolithic) < 4e-4
    bad = motor.run(0.01, "gauss-seidel", extrapolation=True, duration=6.5)
    assert ("Newton" in bad.stopped_early or "rotation increment" in bad.stopped_early) and 4.5 < bad.t[-1] < 6.5


def test_motor_implicit_coupling_is_stable_where_explicit_jacobi_is_not(motor, motor_monolithic):
    """At H = 40 ms explicit Jacobi with extrapolation diverges within 2.4 s; implicit
    Gauss-Seidel (rollback, IQN-ILS) runs through. 3 s: past the explicit failure. Its error is
    the 40 ms sampling of the coupled signals: map 0.95 % from the monolithic run over 10 s,
    measured 0.945 % over these 3 s; bound 1.1 %."""
    bad = motor.run(0.04, "jacobi", extrapolation=True, duration=3.0)  # the body's step fails: Newton, or
    assert ("Newton" in bad.stopped_early or "exceeds pi" in bad.stopped_early) and bad.t[-1] < 3.0  # an alias root
    ok = motor.run(0.04, "gauss-seidel", iterations=50, duration=3.0)
    assert ok.stopped_early == ""
    assert _deflection_error(ok, motor_monolithic) < 0.011


def test_motor_interface_jacobian_at_10_ms_is_close_to_implicit_coupling(motor, motor_monolithic):
    """Linearly implicit coupling (one Newton step on the interface equations, no iteration) at
    H = 10 ms, where explicit Jacobi and Gauss-Seidel with extrapolation diverge (map): stable, and
    its error is the 10 ms sampling of the coupled signals as for converged implicit coupling (map
    1.5e-3 over 10 s). Measured 1.25e-3 of the peak deflection over these 3 s (1.5e-3 over 10 s,
    peak hub speed +0.24 %); bound 2e-3. The coupling Jacobian comes from the beam's directional
    derivatives and a finite difference of the drive's own step (the drive FMU provides none):
    2 sweeps a step, and the run of the finite-difference Jacobian of the sweep to 1e-8 (measured
    1.8e-10 of the peak deflection over 1 s)."""
    run = motor.run(0.01, "gauss-seidel", duration=3.0, interface_jacobian=True)
    assert run.stopped_early == "" and run.sweeps == 2.0
    assert _deflection_error(run, motor_monolithic) < 2e-3
    fd = motor.run(0.01, "gauss-seidel", duration=0.5, interface_jacobian=True, jacobian="fd")
    n = len(fd.t)
    # by construction (round-off cannot change it): 2 sweeps a step plus the finite-difference re-runs
    # of the Jacobian, one per coupled input (the torque's 3 components); passes .ci/run's round-off check
    assert fd.sweeps == 5.0
    assert np.max(np.abs(run.deflection[:n] - fd.deflection)) < 1e-8 * np.max(np.abs(fd.deflection))


def test_split_beam_compliant_cut_fails_under_plain_jacobi(tmp_path):
    """The split beam with A's cut compliant (the rule of docs/cosim.md for H_c = H = 10 ms:
    omega_c = 50 rad/s) and B's cut force-driven, under plain Jacobi (the discrete map libcosim and
    ecos run): B, whose apparent mass at the cut is far below the rule's m_P once its free-free modes
    are excited, refuses a step at 0.21 s (measured); a 16x softer cut lives to 0.76 s with 6.5 % of
    error already (docs/cosim.md table). 0.4 s: past the failure."""
    from ffrf_fmu.studies.stability import cut

    s = st.CosimSettings()
    c = cut.build(HAUG, tmp_path, s)
    k = cut.coefficients(c, 0.01)
    assert k["A.cut.coupling.k[1]"] == pytest.approx(0.25 / 0.01 ** 2 * 0.804, rel=1e-9)  # omega_c^2 m_P, m_P = 4 m x 0.201 kg/m
    run = cut.run(c, s, 0.01, 0.01, duration=0.4)
    assert run.stopped_early.startswith("B: doStep") and 0.15 < run.t[-1] < 0.3, run.stopped_early
    # acceleration links (B's cut accelerations into the spring's far end) do not rescue it: the stale
    # acceleration carries B's overcorrection, and the run fails sooner (measured 0.17 s, in A)
    fast = cut.run(c, s, 0.01, 0.01, duration=0.4, accelerations=True)
    assert fast.stopped_early and fast.t[-1] < run.t[-1], fast.stopped_early
