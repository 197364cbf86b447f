"""`ffrf-fmu advise`: the physics behind each rule, and its promise checked out of sample.

Which scene calibrated which constant (studies/calibration.py, derivations in docs/accuracy.md section 4):
STIFFENED_ERROR one B1 run (spinup, 1 SE at 4 rad/s); STEP_ERROR_FACTOR the B1 chart; FMU_INPUT_FACTOR B1
through its FMU (5 SE); NONLINEAR_ERROR coned_beam's steady spin (docs/inertia-terms.md); the cost
constants benchmarks/term_cost.py on disk_rotor. No assertion below is made on the point a constant was
fitted to: the promise (the pick reaches the tolerance) is checked on scenes that set no constant, B3 at
other spins, generated bodies of other length, stiffness and spin profile, and the two bundled 3D scenes
(models/blade.toml, models/sagging_rotor.toml) against their converged references stored beside them."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.studies import advise as ad
from ffrf_fmu.studies.check import check, format_check
from ffrf_fmu.studies import chart as ch
from ffrf_fmu.model import load_model

ROOT = Path(__file__).resolve().parent.parent
B1 = str(ROOT / "models" / "haug_beam.toml")
CHART_B1 = ROOT / "docs" / "chart_b1.csv"


def test_southwell_coefficient():
    # Southwell coefficient of the first mode of a uniform cantilever spun about its root (no hub
    # offset): 1.193 in the rotating-beam literature (e.g. Wright et al. 1982; Hodges & Rutkowski 1981)
    assert ad.southwell_coefficient() == pytest.approx(1.1933, abs=2e-4)


def test_period_error_of_the_integrator():
    # generalized-alpha is second-order accurate: the relative period error ~ c (omega h)^2; for
    # rho_inf = 0.8, c = 0.086 (about the trapezoidal rule's 1/12)
    e1, e2 = ad.period_error(0.05, 0.8), ad.period_error(0.1, 0.8)
    assert e1 < 0 and e2 / e1 == pytest.approx(4.0, rel=0.01)
    assert -e2 / 0.1**2 == pytest.approx(0.086, rel=0.02)
    # rho_inf = 1 is the trapezoidal rule: period error (omega h)^2 / 12 to leading order
    assert -ad.period_error(0.01, 1.0) / 1e-4 == pytest.approx(1 / 12, rel=1e-3)
    h = ad.largest_step(4.0, 0.8, 1e-3)
    assert abs(ad.period_error(4.0 * h, 0.8)) == pytest.approx(1e-3, rel=1e-6)


# docs/background.md, B1 data (80 Euler-Bernoulli elements): Omega [rad/s] -> (flap, in-plane) [Hz]
STIFFENING_TABLE = {4.0: (0.8305, 0.5334), 8.0: (1.4329, 0.6573), 12.0: (2.0611, 0.7748)}


@pytest.mark.parametrize("omega", sorted(STIFFENING_TABLE))
def test_stiffened_frequencies_per_direction_from_the_body(omega):
    """The advisor's (and info's) stiffened frequencies are the body's own, linearized about the steady
    spin, each with its direction: out of the plane of rotation the Southwell coefficient is S1, in it
    S1 - 1, so the two differ by 1.6 x at 4 rad/s and 2.7 x at 12 rad/s (the in-plane value for an
    out-of-plane mode, the old rule, states less than half the flap frequency at 8 rad/s). B1's model
    (4 SE x 8 elements, Timoshenko) against the table's Euler-Bernoulli mesh: measured within 2e-4;
    3e-3 is 10 x below the smallest difference of a wrong direction or coefficient (S1 for in-plane:
    +8 % at 4 rad/s)."""
    from ffrf_fmu.model import scene_body
    from ffrf_fmu.studies.indicators import stiffened_frequencies

    model = load_model(B1, [f"scenes.spinup_fast.drives.hub.rotation.angle.omega={omega}"])
    scene = model.scene("spinup_fast")
    f = stiffened_frequencies(scene_body(model.body, scene), scene, omega, np.array([0.0, 0.0, 1.0]))
    flap, inplane = STIFFENING_TABLE[omega]
    assert "linearized" in f["source"]
    assert f["out-of-plane"] == pytest.approx(flap, rel=3e-3)
    assert f["in-plane"] == pytest.approx(inplane, rel=3e-3)


def test_step_follows_the_stiffened_frequency_of_the_excited_direction(beam_toml, tmp_path):
    """A spin-up alone excites the plane of rotation; a tip load along the spin axis excites the flap,
    whose stiffened frequency is higher (1.43 against 0.66 Hz at 8 rad/s): the advisor's relevant
    frequency, and so its step, follows the flap frequency then (the load window's own band kept low)."""
    base = """
[scenes.s]
duration = 20.0
step = 0.002
rho_inf = 0.8
[scenes.s.metrics]
kind = "tip_deflection"
primary = "tip_deflection_max_m"
[scenes.s.drives.hub.rotation]
axis = [0.0, 0.0, 1.0]
angle = { kind = "haug_spinup", omega = 8.0, T = 15.0 }
"""
    load = """[[scenes.s.loads]]
port = "tip"
force = [0.0, 0.0, 1.0]
t_start = 16.0
t_end = 19.0
"""
    inplane, flap = tmp_path / "inplane.toml", tmp_path / "flap.toml"
    inplane.write_text(beam_toml(base, superelements=1, elements=8))
    flap.write_text(beam_toml(base + load, superelements=1, elements=8))
    a_in, a_flap = ad.advise(str(inplane), "s", 0.01), ad.advise(str(flap), "s", 0.01)
    assert a_in.indicators["excited_directions"] == ["in-plane"]
    assert a_flap.indicators["excited_directions"] == ["in-plane", "out-of-plane"]
    f = a_flap.indicators["stiffened_frequencies_hz"]
    assert f["out-of-plane"] > 2.0 * f["in-plane"]
    assert a_in.indicators["relevant_frequency_hz"] == pytest.approx(1.2732, rel=1e-3)  # the spin rate 8 rad/s
    assert a_flap.indicators["relevant_frequency_hz"] == pytest.approx(f["out-of-plane"])
    # the same chain and budget: the step the accuracy allows scales with 1 / the relevant frequency
    assert a_flap.indicators["step_budget"] == pytest.approx(a_in.indicators["step_budget"])
    assert a_flap.indicators["step_accuracy_s"] / a_in.indicators["step_accuracy_s"] == pytest.approx(
        1.2732 / f["out-of-plane"], rel=1e-3)


def test_no_spin_one_superelement_linear_terms():
    # B1's beam with the hub free (co-simulation scene): nothing spins, nothing to stiffen
    a = ad.advise(B1, "hub_free", 0.01)
    assert a.superelements == 1 and a.terms == "linear" and a.modes == 2 and not a.stiffening
    assert a.predicted["chain"] == 0.0


def test_free_axial_rotation_needs_the_inertia_coupling():
    """B2 (spherical joint, free tip): no port holds the beam's rotation about its own axis, whose only
    inertia is the polar one. A symmetric body under loads through its axis keeps its axial spin (Euler):
    0. One superelement with the linear terms spins the beam about its axis after the tip load (the elastic
    whirl's axial angular momentum goes nowhere else); the inertia coupling S(q) (gyroscopic) keeps it at 0.
    The advisor asks for it there, and not where nothing moves (hub_free: the hub's rotation is free too)."""
    from ffrf_fmu.simulate import run_scene

    b2 = str(ROOT / "models" / "spherical_beam.toml")
    a = ad.advise(b2, "torque_then_tip", 0.01)
    assert a.terms == "gyroscopic" and "rotation about its own axis" in a.reasons["terms"]
    assert ad.advise(B1, "hub_free", 0.01).terms == "linear"
    spin = {}
    for terms in ("linear", "gyroscopic"):  # shortened: 3 s after the tip load, 20 ms steps
        m = load_model(b2, ["body.superelements=1", "body.modes=2", f"scenes.torque_then_tip.terms={terms}",
                            "scenes.torque_then_tip.duration=18", "scenes.torque_then_tip.step=0.02"])
        res = run_scene(m, "torque_then_tip")
        R, w = res.port("root", "R"), res.port("root", "w")
        axial = np.einsum("ni,ni->n", w, R[:, :, 0])  # about the root section's axis
        after = res.t >= 15.2
        spin[terms] = float(np.mean(axial[after]))
        swing = float(np.mean(np.linalg.norm(w[after] - axial[after, None] * R[after, :, 0], axis=1)))
    assert abs(spin["gyroscopic"]) < 1e-3 * swing  # measured 9e-6 against 0.095 rad/s
    assert abs(spin["linear"]) > 1e-2 * swing  # measured -0.0031 rad/s: what the rule is for


def test_stiffened_rule_structure():
    """B1: the spin (sigma = 1.88) turns stiffening on; the predicted error of a stiffened chain falls as
    (Omega/omega_se)^2 ~ N^-4 (omega_se of a free-free superelement of length L/N ~ N^2); a tolerance
    tighter than one superelement's prediction takes more of them."""
    a = ad.advise(B1, "spinup", 0.01)
    assert a.stiffening and a.superelements == 1 and a.terms == "linear"
    assert set(a.reasons) == {"stiffening", "superelements", "modes", "terms", "step"}
    assert "stiffening=true" in a.overrides
    e1 = a.predicted["chain"]  # (its size on B1 is the calibration point itself: not asserted here)
    b = ad.advise(B1, "spinup", 0.002)
    assert b.superelements == 2 and b.predicted["chain"] == pytest.approx(e1 / 16, rel=0.02)
    assert a.predicted["total_estimate"] <= ad.RESERVE * a.tolerance


# Out of sample: (model overrides, scene) none of which set a constant of the advisor.
OUT_OF_SAMPLE = {
    "B3 12 rad/s": (["scenes.spinup_fast.drives.hub.rotation.angle.omega=12"], "spinup_fast"),
    "4 m soft beam, 6 rad/s": (["length=4", "EI2=100", "EI3=100", "scenes.spinup_fast.drives.hub.rotation.angle.omega=6",
                                "scenes.spinup_fast.drives.hub.rotation.angle.T=8", "duration=12"], "spinup_fast"),
    "12 m stiff beam, 5 rad/s": (["length=12", "EI2=3000", "EI3=3000", "scenes.spinup.drives.hub.rotation.angle.omega=5",
                            "scenes.spinup.drives.hub.rotation.angle.T=10", "duration=14"], "spinup"),
}


@pytest.mark.parametrize("case", [
    "B3 12 rad/s",
    "4 m soft beam, 6 rad/s",
    pytest.param("12 m stiff beam, 5 rad/s", marks=pytest.mark.xfail(strict=True, reason=(
        "the advisor's law under-predicts here: measured 1.21 % (1 SE, 25 ms) against 0.28 % + step. The error "
        "follows the deflection, not the spin: 1 SE +1.04 %, 2 SE +0.46 %, 8 linear SE +0.34 % at a peak "
        "deflection of 12 % of the length (B3: 0.36 (delta/L)^2 fits 8, 12, 14 rad/s); not modelled yet"))),
])
def test_advice_holds_out_of_sample(case):
    """The advised configuration (tolerance 1 %) run against the full-order beam (16 elements, 10 ms):
    its peak-deflection error is within the tolerance and below the advisor's own estimate (the rule is
    an upper bound: measured 1.7-2.2 x below on B3), and the estimate is not vacuous (within 4 x of
    the achieved error or below 0.25 %)."""
    from ffrf_fmu import simulate as sim
    from ffrf_fmu.reference import simulate_reference, tip_from_hub

    overrides, scene = OUT_OF_SAMPLE[case]
    a = ad.advise(B1, scene, 0.01, overrides=overrides)
    model = load_model(B1, overrides)
    ref = simulate_reference(model.body, model.scene(scene), n_elements=16, step=0.01)
    run = sim.run_scene(B1, scene, overrides + a.overrides)
    assert run.summary["completed"]
    hub, tip = sim.end_ports(run.body)
    peak = np.abs(sim.elastic_tip(run, hub, tip)[:, 1]).max()
    peak_ref = np.abs(tip_from_hub(ref)[:, 1]).max()
    err = abs(peak / peak_ref - 1.0)
    est = a.predicted["total_estimate"]
    assert err <= a.tolerance
    assert err <= est
    assert est <= max(4.0 * err, 0.0025)


def test_cli_advise_json():
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    res = subprocess.run([sys.executable, "-m", "ffrf_fmu", "advise", B1, "--scene", "spinup", "--tolerance", "5%",
                          "--json"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["tolerance"] == 0.05 and out["configuration"]["superelements"] == 1
    assert out["configuration"]["stiffening"] is True
    bad = subprocess.run([sys.executable, "-m", "ffrf_fmu", "advise", B1, "--tolerance", "abc"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "percentage" in bad.stderr


def test_check_runs_on_the_sweep_layer_and_reuses_the_charts_reference(tmp_path):
    """`advise --check` is two tasks of the sweep layer kept in DIR's store: in a chart's directory
    the chart's reference run is taken from the store (not run again), and the achieved error is
    the chart's error measure of the advised run against it. The first 1.5 s of B1 (the hub barely
    turns: 1 SE suffices), reference 8 elements; checked at 5 %."""
    from ffrf_fmu.studies.runners import run_configuration

    ov = ["duration=1.5"]
    chart = ch.chart(B1, "spinup", {"superelements": ["1"], "modes": ["2"]}, overrides=ov, reference_elements=8,
                     workers=1, out_dir=tmp_path, progress=False, plot=False)
    a = ad.advise(B1, "spinup", 0.05, overrides=ov)
    res = check(B1, "spinup", a, overrides=ov, reference_elements=8, out_dir=tmp_path, refine=False)
    assert res["reference"]["cached"] and res["completed"] and res["within_tolerance"]
    assert res["metric_reference"] == chart["reference"]["metrics"]["tip_deflection_max_m"]
    # refined (the default): the chart's reference is the refinement's base, 16 elements and 1 ms its
    # refinements; measured moves 0.060 % (mesh) and 0.0002 % (step), both < 0.5 % = a tenth of 5 %:
    # resolved, judged against the finer mesh
    refined = check(B1, "spinup", a, overrides=ov, reference_elements=8, out_dir=tmp_path)
    table = refined["reference_resolution"]
    assert table["resolved"] and [(r["n_elements"], r["step"], r["refines"]) for r in table["rows"]] == [
        (8, 0.002, "base"), (16, 0.002, "mesh"), (8, 0.001, "step")]
    assert table["rows"][0]["metric"] == chart["reference"]["metrics"]["tip_deflection_max_m"]
    assert refined["reference"]["n_elements"] == 16 and refined["within_tolerance"]
    assert refined["metric_reference"] == table["rows"][1]["metric"]
    # the verdict is stored: a second check reads it (and runs nothing but the stored runs)
    again = check(B1, "spinup", a, overrides=ov, reference_elements=8, out_dir=tmp_path)
    assert again["reference_resolution"] == table and again["reference"]["cached"]
    run = run_configuration(B1, "spinup", ov, {"superelements": str(a.superelements), "modes": str(a.modes),
                                               "terms": a.terms, "step": f"{a.step:g}",
                                               "stiffening": "true" if a.stiffening else "false"},
                            backend=a.backend)
    assert res["metric"] == run["metrics"]["tip_deflection_max_m"]  # the same run, here and through the sweep


def test_chart_resolves_its_reference(tmp_path):
    """`chart --resolve TOL` refines the reference as the check does and measures against the refined one:
    the first 1.5 s of B1 from 8 elements at 5 %: resolved, judged against 16 elements (the moves of
    test_check_runs_on_the_sweep_layer...); the rows say so and chart.json keeps the table."""
    ov = ["duration=1.5"]
    out = ch.chart(B1, "spinup", {"superelements": ["1"], "modes": ["2"]}, overrides=ov, reference_elements=8,
                   workers=1, out_dir=tmp_path, progress=False, plot=False, resolve=0.05)
    table = out["meta"]["reference_resolution"]
    assert table["resolved"] and table["n_elements"] == 16
    assert out["reference"]["n_elements"] == 16 and all(r["reference_resolved"] for r in out["rows"])
    assert out["rows"][0]["metric_reference"] == table["rows"][1]["metric"]
    assert json.loads((tmp_path / "chart.json").read_text())["reference_resolution"] == table


def test_check_gives_no_verdict_on_an_unresolved_reference(tmp_path, monkeypatch):
    """A reference whose metric still moves by a tenth of the tolerance or more when refined does not judge:
    within_tolerance None, the refinement table in the report, exit code 3. The first 1.5 s of B1 at
    0.2 %: 8 -> 16 elements moves the peak by 0.060 % (measured), above 0.02 %; one round allowed."""
    from ffrf_fmu.cli import main
    from ffrf_fmu.studies import resolve

    monkeypatch.setattr(resolve, "MAX_ROUNDS", 1)
    ov = ["duration=1.5"]
    a = ad.advise(B1, "spinup", 0.002, overrides=ov)
    res = check(B1, "spinup", a, overrides=ov, reference_elements=8, out_dir=tmp_path)
    table = res["reference_resolution"]
    assert not table["resolved"] and res["within_tolerance"] is None
    assert table["rows"][1]["move"] == pytest.approx(6.0e-4, rel=0.05)
    text = format_check(res, a.tolerance)
    assert "NOT resolved" in text and "no verdict" in text
    argv = ["advise", B1, "--scene", "spinup", "--tolerance", "0.2%", "--check", "--reference-elements", "8",
            "-o", str(tmp_path), *[x for o in ov for x in ("--set", o)]]
    assert main(argv) == 3  # the stored verdict: nothing runs again


def test_b4_free_tumble_check_holds_for_the_right_reason(tmp_path):
    """B4 (free beam released from a bent start to tumble): the primary metric is the frequency of the tip's
    vibration seen from the body's CM frame (out of the plane the axis sweeps). The advised configuration
    runs through (its Newton failed at 0.52 s while the start was taut) and `advise --check` holds at 1 %
    against the full-order beam the scene names ([scenes.tumble.reference]: 32 elements, 2 ms), refined until
    the metric moves by less than a tenth of the tolerance (studies/resolve.py); for the right
    reason: the same run without stiffening is off by the tumble's stiffening (measured on these 3 s: advised
    -0.40 %, unstiffened -2.2 %; on the full 10 s 0.41 %)."""
    from ffrf_fmu.studies.runners import run_configuration

    b4 = str(ROOT / "models" / "free_beam.toml")
    ov = ["scenes.tumble.duration=3"]
    a = ad.advise(b4, "tumble", 0.01, overrides=ov)
    assert a.stiffening and a.terms == "gyroscopic" and not any("primary metric" in w for w in a.warnings)
    assert any("FMU does not output" in w for w in ad.advise(b4, "tumble", 0.01, overrides=ov, fmu=True).warnings)
    res = check(b4, "tumble", a, overrides=ov, out_dir=tmp_path)  # from the reference the scene names
    # refined (resolve.py): 32 -> 64 elements moves the metric by 0.111 % (> 0.1 %), 64 -> 128 by 0.027 %, the
    # steps by <= 0.01 % (measured): judged against 128 elements at 2 ms, where the advice is 0.25 % off
    # (0.40 % against the unrefined 32 elements)
    table = res["reference_resolution"]
    assert (table["rows"][0]["n_elements"], table["rows"][0]["step"]) == (32, 0.002) and table["resolved"]
    assert res["reference"]["n_elements"] == 128 and res["reference"]["step"] == 0.002
    assert res["metric_name"] == "tip_from_cm_frequency_hz" and res["completed"]
    assert res["within_tolerance"] and res["metric_error_rel"] <= 0.0075
    values = {"superelements": str(a.superelements), "modes": str(a.modes), "terms": a.terms, "step": f"{a.step:g}",
              "stiffening": "false"}
    plain = run_configuration(b4, "tumble", ov, values, backend=a.backend)["metrics"]["tip_from_cm_frequency_hz"]
    assert plain / res["metric_reference"] - 1 < -0.015


# the bundled 3D scenes no advisor constant was fitted to, with their converged references stored beside them
# (docs/accuracy.md "Out of sample"): the blade, spun up past its first flap frequency and kicked out of its
# plane; the sagging rotor, spinning steadily from the start under gravity along its axis, kicked in its plane
# (in sample for the term rule's gravity along the spin axis, which was added after its 0.5 % advice missed);
# the tilted rotor, committed before the advisor first ran on it and held out of every rule change since: a
# coned arm on a horizontal shaft, spun up from its static sag under gravity across the axis, kicked along it
STORED_SCENES = {"blade": ("flap_kick", "tip_out_of_plane_max_m"), "sagging_rotor": ("lag_kick", "tip_in_plane_max_m"),
                 "tilted_rotor": ("shaft_kick", "tip_out_of_plane_max_m")}


@pytest.mark.parametrize("name", sorted(STORED_SCENES))
@pytest.mark.parametrize("tolerance", [0.05, 0.01, 0.005])
def test_advice_reaches_the_tolerance_on_the_3d_scenes_out_of_sample(name, tolerance):
    """The advised configuration's primary metric is within the tolerance of the scene's converged
    full-order reference (models/NAME.reference.json: the refinement table of studies/resolve.py and the
    value judged against, resolved at a tenth of the smallest tolerance tested; written by
    benchmarks/stored_reference.py), and within the advice's own predicted error. Measured (docs/accuracy.md):
    blade +0.34 / +0.13 / +0.12 %, sagging rotor -1.68 / -0.47 / -0.31 %, tilted rotor +0.27 / +0.14 / +0.05 %
    at 5 / 1 / 0.5 %."""
    from ffrf_fmu.studies.runners import run_configuration

    scene, metric = STORED_SCENES[name]
    model = str(ROOT / "models" / f"{name}.toml")
    stored = json.loads((ROOT / "models" / f"{name}.reference.json").read_text())
    assert stored["scene"] == scene and stored["metric"] == metric
    assert stored["resolved_to"] <= 0.1 * 0.005  # resolved at a tenth of the smallest tolerance tested
    a = ad.advise(model, scene, tolerance)
    assert a.stiffening  # blade: 7 rad/s against its first flap 5.0 rad/s; rotors: 2 against 5.45, 10 against 13.2
    run = run_configuration(model, scene, [], {"superelements": str(a.superelements), "modes": str(a.modes),
                                               "terms": a.terms, "step": f"{a.step:g}", "stiffening": "true"},
                            backend=a.backend)
    error = abs(run["metrics"][metric] / stored["value"] - 1)
    assert error <= tolerance
    assert error <= a.predicted["total_estimate"] + 0.1 * tolerance
