"""Witteveen's Jeffcott rotor (models/jeffcott_rotor.toml, models/jeffcott_runup.toml; docs/inertia-terms.md,
"The Jeffcott rotor"): his Table 1 mass and extent, the first bending frequency on the bearings against the
Jeffcott value sqrt(k / m), the run-up peak against the Jeffcott equation run up the same way (an independent
ODE solver), and the rotating unbalance load of the model format."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

from ffrf_fmu.body_cache import scene_body_data
from ffrf_fmu.checked_toml import ModelError
from ffrf_fmu.linear import chain_matrices
from ffrf_fmu.model import load_model

MODELS = Path(__file__).resolve().parents[1] / "models"
spec = importlib.util.spec_from_file_location("jeffcott_runup_script", MODELS / "data" / "jeffcott" / "runup.py")
runup = importlib.util.module_from_spec(spec)
spec.loader.exec_module(runup)


def body_of(name):
    m = load_model(MODELS / name)
    return m, scene_body_data(m.body, m.scenes[0])


def bearing_frequencies(body) -> np.ndarray:
    """Circular frequencies [rad/s] of the reduced chain at rest on its compliant ports' springs."""
    K, M, nd = chain_matrices(body)
    for p in body.ports:  # compliance: (k[3], c[3], k_rot[3], c_rot[3]), the file's coupling tables
        if p.translation == "compliant":
            K[nd[p.node][:3], nd[p.node][:3]] += np.asarray(p.compliance[0:3])
        if p.rotation == "compliant":
            K[nd[p.node][3:], nd[p.node][3:]] += np.asarray(p.compliance[6:9])
    return np.sqrt(np.abs(sla.eigh(K, M, eigvals_only=True)))


@pytest.mark.parametrize("name", ["jeffcott_rotor.toml", "jeffcott_runup.toml"])
def test_mass_and_extent_of_his_table_1(name):
    """Table 1: 7.4 kg, 300 x 300 x 750 mm. The mass is the shaft's rho A L plus the disc's (the file's
    derivation), exact in the consistent mass: 1e-5. The disc's radius from its polar inertia m R^2 / 2:
    0.15 m (the 300 mm extent) to the 4 digits the inertia is given with."""
    m, body = body_of(name)
    assert sum(se.mass for se in body.superelements) == pytest.approx(7.4, rel=1e-5)
    assert m.body.length == 0.75
    (disc,) = m.body.masses
    assert np.sqrt(2 * disc.inertia[0] / disc.mass) == pytest.approx(0.15, rel=1e-4)


def test_first_bending_frequency_against_jeffcott():
    """sqrt(k / m), k the shaft's 48 EI / L^3 in series with the bearings, m the disc plus 17/35 of the shaft
    (Rayleigh with the static deflection shape): 169.79 rad/s. Rayleigh's quotient is an upper bound,
    here within ~0.1 % (the static shape is close to the mode's for a shaft 1/3 of the disc's mass), and
    shear (12 EI / (kappa G A L^2) = 1.6e-3 of the deflection) lowers the frequency by ~0.08 %: 0.5 %.
    Both models (1 superelement with 10 modes, 2 of 5) give the same: the modes span the static shape."""
    k, m = runup.jeffcott_constants()
    for name in ("jeffcott_rotor.toml", "jeffcott_runup.toml"):
        w = bearing_frequencies(body_of(name)[1])
        assert w[0] == pytest.approx(w[1], rel=1e-8)  # the two lateral planes
        assert w[0] == pytest.approx(np.sqrt(k / m), rel=5e-3)
        assert w[0] < np.sqrt(k / m)  # Rayleigh's bound (plus shear) from above


def test_runup_peak_against_the_jeffcott_equation():
    """A faster run-up than the bundled one (T = 4 s: 170 rad/s^2 at the critical speed, eta = alpha / w_c^2 =
    5.9e-3) so the test is short, on the scene's terms (full, W1 + W2). An undamped run-up's peak lies above the
    critical speed by about 2.16 sqrt(alpha) (the first maximum of the Fresnel integral), here 28 rad/s = 17 %: the
    reduced body's peak must be above sqrt(k/m) by more than half of that. Its speed is the equation's moved by the
    difference of the crossings: the body's synchronous crossing with W1 + W2 is the rule's steady whirl pole,
    169.10 rad/s (term_rule.steady_term_effects(...)["critical_speed"]["full"] on the scene runup, asserted in
    test_term_rule_on_the_run_up_measures_the_whirl_and_picks_w1_w2; written out, as it takes 3.5 s to measure),
    7.5e-4 of it the secant's bias high (its points 3 % below the pole; docs/inertia-terms.md, "Which terms the
    run-up needs"; a steady measure, not fitted on a run-up), against sqrt(k/m) = 169.79. This run's peak is 0.14 %
    below that prediction (196.72 against 197.81 - 0.82 rad/s), the bundled run-up's (68 rad/s^2) 0.10 % (186.56
    against 187.57 - 0.82 rad/s, the peak flat-topped): 4e-3, which gyroscopic's crossing (171.84 rad/s: +1.2 %)
    does not meet. The amplitude A ~ e_eff w_c / sqrt(alpha): this run's is 1.2 % below the equation's, the bundled
    run-up's 0.93 % (the crossings differ by 0.4 %, the modal unbalance the rest): 3 %."""
    from ffrf_fmu.simulate import run_scene

    T = 4.0
    res = run_scene(str(MODELS / "jeffcott_runup.toml"),
                    overrides=[f"scenes.runup.drives.bearing_a.rotation.angle.T={T}", "duration=3.0"])
    assert res.summary["completed"], res.summary["failure"]
    t = res.t
    r = np.hypot(res.columns["disc.r[2]"], res.columns["disc.r[3]"])
    _, speed, _ = runup.haug_speed(t, 340.0, T)
    r_ode = runup.jeffcott_runup(340.0, T, t[-1], t)
    i, j = int(np.argmax(r)), int(np.argmax(r_ode))
    assert i < len(t) - 1 and j < len(t) - 1  # the peaks are inside the run
    k, m = runup.jeffcott_constants()
    wc = np.sqrt(k / m)
    alpha = 2 * 340.0 / T
    assert speed[j] - wc == pytest.approx(2.16 * np.sqrt(alpha), rel=0.25)  # the ODE against the Fresnel estimate
    assert speed[i] - wc > 0.5 * 2.16 * np.sqrt(alpha)
    crossing = 169.10 / (1 + 7.5e-4)  # the rule's full-terms whirl pole less the secant's bias (above)
    assert speed[i] == pytest.approx(speed[j] + crossing - wc, rel=4e-3)
    assert r[i] == pytest.approx(r_ode[j], rel=3e-2)  # peak amplitude (mm): the same resonance


def test_unbalance_force_rotates_with_the_drive():
    """The load m e (psi'^2 rho - psi'' tau) of [[scenes.NAME.unbalances]] at the drive's angle."""
    from ffrf_fmu.simulate.inputs import unbalance_force

    m = load_model(MODELS / "jeffcott_runup.toml")
    sc = m.scenes[0]
    (ub,), drive = sc.unbalances, sc.drives[0]
    for t in (1.0, 5.0, 12.0):
        psi, dpsi, ddpsi = runup.haug_speed(np.array(t), 340.0, 10.0)
        f = unbalance_force(ub, drive, t)
        expect = ub.mass_eccentricity * (dpsi**2 * np.array([0, np.cos(psi), np.sin(psi)])
                                         - ddpsi * np.array([0, -np.sin(psi), np.cos(psi)]))
        assert np.allclose(f, expect, rtol=0, atol=1e-12 * np.abs(expect).max())


@pytest.mark.parametrize("entry, message", [
    ("port = \"bearing_b\"", "force-driven translation"),
    ("drive = \"disc\"", "rotation drive"),
    ("reference = [2.0, 0.0, 0.0]", "along the spin axis"),
])
def test_unbalance_errors_name_the_key(tmp_path, entry, message):
    text = (MODELS / "jeffcott_runup.toml").read_text()
    key = entry.split(" = ")[0]
    lines = [ln for ln in text.splitlines()]
    start = lines.index("[[scenes.runup.unbalances]]        # docs/model-format.md: m e (psi'^2 rho - psi'' tau) on the disc")
    for n in range(start + 1, len(lines)):
        if lines[n].startswith(key + " "):
            lines[n] = entry
            break
    else:
        lines.insert(start + 1, entry)
    p = tmp_path / "bad.toml"
    p.write_text("\n".join(lines))
    with pytest.raises(ModelError, match=message) as e:
        load_model(p)
    assert "scenes.runup.unbalances[0]" in str(e.value)


def test_reference_refuses_the_unbalance():
    from ffrf_fmu.reference.solver import simulate_reference

    m = load_model(MODELS / "jeffcott_runup.toml")
    with pytest.raises(ValueError, match="unbalances"):
        simulate_reference(m.body, m.scenes[0])


def test_witteveen_jeffcott_row_in_his_units():
    """His Table 2 Jeffcott row (t, mm): |I0| 118.2, max |W1| 18.6, "norm" of W1 10.5. Ours in SI converted to
    t and mm: I0 [kg m^2] x 1e3; W1 = int rho x~ Phi with mass-normalized modes (Phi ~ 1 / sqrt(mass)) scales
    as sqrt(mass) x length: x sqrt(1e-3) x 1e3. |I0| is the diametral inertia (shaft m L^2 / 12 plus the disc's),
    set by his mass and extent and our shaft / disc split: 1 %. max |W1| is the shaft's stretch mode, set by its
    mass and length: 2 %. His "norm" is below his max entry (docs/inertia-terms.md, ambiguity 3): ours / 2, 2 %.
    His W2 (max 0.02) is not reproducible by mass-normalized modes (the trace of a mode's own block is 2)."""
    from ffrf_fmu.invariants import body_inertia_report

    m = load_model(MODELS / "jeffcott_rotor.toml")
    (se,) = body_inertia_report(m.body)["superelements"]
    t = se["table"]
    assert t["I0_norm"] * 1e3 == pytest.approx(118.2, rel=1e-2)
    w1 = np.sqrt(1e-3) * 1e3
    assert t["W1_max"] * w1 == pytest.approx(18.6, rel=2e-2)
    assert t["W1_norm"] * w1 / 2 == pytest.approx(10.5, rel=2e-2)
    assert t["W2_max"] >= 2 / 3 - 1e-9


def test_term_rule_on_the_run_up_measures_the_whirl_and_picks_w1_w2():
    """The run-up spins the rotor through a compliant drive spring on compliant bearings: the term rule measures
    the terms on the unbalance's synchronous whirl at the top rate (ffrf_fmu/spin_supports.py) and picks full
    with W1 and W2 at 1 % (the whirl moves by 3.6 % without W1, 0.41 % without W2, against 0.125 %). The
    physics behind it: the central disc does not tilt in the first whirl, so the synchronous crossing is the
    bearing-supported bending frequency at rest, 169.57 rad/s (test_first_bending_frequency_against_jeffcott).
    With W1 and W2 the crossing stays there (169.10 rad/s, -0.28 %; 7.5e-4 of it the secant's bias high, and
    shear and the disc's own inertia the rest); without them the half-shafts' frames tilt the disc with their
    chords and its polar inertia stiffens the whirl (linear: 172.22 rad/s, +1.6 %)."""
    from ffrf_fmu.model import load_model, scene_body
    from ffrf_fmu.term_rule import choose_full_terms, choose_term_set, steady_term_effects

    m = load_model(MODELS / "jeffcott_runup.toml")
    sc = m.scene("runup")
    eff = steady_term_effects(scene_body(m.body, sc), sc)
    assert eff["status"] == "ok" and "synchronous whirl" in eff["measure"]
    assert choose_term_set(eff, 0.01)[0] == "full"
    assert choose_full_terms(eff, 0.01)[0] == ("inertia_W1", "inertia_W2")
    crit = eff["critical_speed"]
    assert crit["full"] == pytest.approx(169.57, rel=5e-3)
    assert crit["linear"] > 1.01 * 169.57


@pytest.mark.parametrize("override, why", [
    ("body.ports.bearing_b.coupling.stiffness=[1e7, 1e7, 2e7]", "bearing_b: its spring is not isotropic across the spin axis"),
    ("scenes.runup.unbalances=[]", "without an unbalance"),
])
def test_term_rule_names_why_a_supported_spin_has_no_whirl(override, why):
    """An anisotropic bearing has no steady whirl in the spinning frame (its force turns with the frame), a balanced
    rotor no load there: the rule says which and falls back to its no-spin choice."""
    from ffrf_fmu.model import load_model, scene_body
    from ffrf_fmu.term_rule import choose_term_set, steady_term_effects

    m = load_model(MODELS / "jeffcott_runup.toml", [override])
    sc = m.scene("runup")
    eff = steady_term_effects(scene_body(m.body, sc), sc)
    assert eff["status"] != "ok" and why in eff["status"]
    assert choose_term_set(eff, 0.01)[0] == "linear"


def test_term_rule_on_the_balanced_spin_under_gravity_rejects_linear():
    """Scene spin (balanced, no unbalance, gravity across the spin axis) on the compliant bearings: the rule
    measures the terms on the steady response to the weight at 170 rad/s (spin_supports.gravity_whirl: the
    weight turns backward in the spinning frame at the spin rate). Measured: linear 5.62 % from full, gyroscopic
    0.0056 %, full without Coriolis 12.0 %; the budget at 1 % is 0.5 %. Asserted: linear more than 2.5 % (half
    the measured, five times the budget) off, gyroscopic within a tenth of the budget, and Coriolis (the modes'
    gyroscopic coupling G(w)) the switch that carries it (above its share 0.125 %). In the scene's time run
    linear's sideways bearing_a force is 32.8 N peak against 1.32 N of the converged full reference."""
    from ffrf_fmu.model import load_model, scene_body
    from ffrf_fmu.term_rule import choose_full_terms, choose_term_set, steady_term_effects

    m = load_model(MODELS / "jeffcott_rotor.toml")
    sc = m.scene("spin")
    eff = steady_term_effects(scene_body(m.body, sc), sc)
    assert eff["status"] == "ok" and "gravity across the axis" in eff["measure"]
    tf = eff["to_full"]
    assert tf["linear"] > 0.025
    assert tf["gyroscopic"] < 0.1 * 0.005
    assert tf["full-coriolis"] > 0.00125 and "coriolis" in choose_full_terms(eff, 0.01)[0]
    assert choose_term_set(eff, 0.01)[0] == "gyroscopic"
    from ffrf_fmu.studies.modal_advice import needs_modal_reference

    assert needs_modal_reference(m, sc)  # the full-order reference refuses the compliant drive spring
