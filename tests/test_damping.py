"""Structural damping (runtime/damping.py, docs/equations.md "Structural damping"): D q_bar_dot in the
elastic force (78), on the co-rotated rates of (91).

- the C runtime against the oracle field by field with damping on, and the damping seen there;
- the iteration matrix against central differences with damping on;
- a free vibration of one free-free superelement (models/free_beam.toml in 1 superelement): its modal
  coordinates decay with the ratio asked, modal or Rayleigh's alpha / (2 omega) + beta omega / 2;
- a rigid spin is not damped; the energy lost equals the work of the damping force;
- the model file: [body.damping] read, refused when both kinds, negative or of the wrong length.

Integrator tolerance of the decay: at rho_inf = 1 the generalized-alpha step is the trapezoidal rule,
which has no numerical damping (measured on the undamped beam: |zeta| < 2e-9) but shifts the discrete
damping ratio of a mode by about -(omega h)^2 / 6 relative (measured: -5.7e-5 at omega h = 0.0186,
-9.2e-4 at omega h = 0.074, the (omega h)^2 scaling); the tests allow (omega h)^2 / 3.
"""
from __future__ import annotations

import ctypes
import dataclasses

import numpy as np
import pytest

from ffrf_fmu.checked_toml import ModelError
from ffrf_fmu.model import Body, Port, load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime import equations
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.runtime.damping import Damping, modal_basis
from ffrf_fmu.runtime.data import BodyData
from ffrf_fmu.runtime.native.binding import NativeBody
from ffrf_fmu.runtime.native.image import body_image
from ffrf_fmu.runtime.ports import PortValues
from test_native_equations import TOL, _differences, _Native, _near, _stage

FREE = {n: PortValues(f=np.zeros(3), t=np.zeros(3)) for n in ("a", "b")}


def _b1_data(b1, damping):
    """Two superelements of B1 (4 elements, 3 modes each: n = 15 reduced dofs), hub motion-driven."""
    section, length = b1
    body = Body("b", length, (0, 0, 0), (1, 0, 0), section, 2, 4, 3,
                (Port("hub", 0, "motion", "force"), Port("tip", 2, "force", "force")), damping=damping)
    return reduce_body(body).data


# modal (one ratio, and one per mode), Rayleigh, and both added (an FMU's parameters may add them)
DAMPINGS = {
    "modal": Damping((0.05,)),
    "modal-list": Damping(tuple(np.linspace(0.01, 0.2, 15))),
    "rayleigh": Damping((), 0.3, 1e-3),
    "both": Damping((0.02,), 0.3, 1e-3),
}


@pytest.mark.parametrize("terms", ["linear", "gyroscopic"])
@pytest.mark.parametrize("kind", list(DAMPINGS))
def test_c_runtime_matches_the_oracle_with_damping(kind, terms, b1):
    """Rows F and blocks F_ydot, F_y of every superelement, C against the oracle, to the 1e-12 of
    tests/test_native_equations.py (measured: 1.8e-15); against the oracle of the undamped body the same
    comparison fails by orders (measured: 3e7 of a block's scale): the damping is compared."""
    data = _b1_data(b1, DAMPINGS[kind])
    for seed in (3, 4):
        s = BodySystem(data, terms=terms)
        _near(s, seed)
        yd = np.random.default_rng(100 + seed).normal(size=s.yd.shape)
        body, (p, R) = _Native(s), _stage(s)
        for e in range(s.layout.n_se):
            c = body.superelement(e, p, yd, R)
            args = (s.layout, terms, s.gravity, e, s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd)
            oracle = equations.superelement_residual_and_jacobian(data, *args)
            undamped = equations.superelement_residual_and_jacobian(dataclasses.replace(data, damping=None), *args)
            assert max(d for d, _ in _differences(s, c, oracle)) <= TOL
            assert max(d for d, _ in _differences(s, c, undamped)) > 1e3 * TOL


def test_a_damped_solid_matches_the_oracle(b1):
    """A solid (conftest's stiffened bar of quadratic hexahedra, one superelement on two frames, with
    its membrane strain) damped by Rayleigh's alpha, beta: C against the oracle as above, the damping seen."""
    from conftest import solid_bar_body

    data = dataclasses.replace(solid_bar_body(True, False)[0], damping=Damping((), 2.0, 1e-5))
    s = BodySystem(data, terms="gyroscopic")
    _near(s, 5)
    yd = np.random.default_rng(105).normal(size=s.yd.shape)
    p, R = _stage(s)
    c = _Native(s).superelement(0, p, yd, R)
    args = (s.layout, "gyroscopic", s.gravity, 0, s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd)
    assert max(d for d, _ in _differences(s, c, equations.superelement_residual_and_jacobian(data, *args))) <= TOL
    undamped = equations.superelement_residual_and_jacobian(dataclasses.replace(data, damping=None), *args)
    assert max(d for d, _ in _differences(s, c, undamped)) > 1e3 * TOL


@pytest.mark.parametrize("terms", ["linear", "gyroscopic"])
def test_iteration_matrix_with_damping_matches_finite_differences(terms, b1, far_from_reference,
                                                                   iteration_matrix_error):
    """The numpy path's iteration matrix with D q_bar_dot (its derivatives through Dq on the rates and
    Dqdot on the configuration) against central differences (accurate to ~1e-8; 1e-6 allowed, as
    tests/test_dynamics.py)."""
    s = BodySystem(_b1_data(b1, Damping((), 0.3, 1e-3)), terms=terms, rho_inf=0.7, backend="numpy")
    assert iteration_matrix_error(s, far_from_reference(s)) <= 1e-6


def test_rayleigh_is_alpha_m_plus_beta_k(b1):
    """Every mode of a reduced superelement is elastic (q_bar is measured from the CM frame), so the
    modal construction with c_i = alpha + beta omega_i^2 is alpha M_bar + beta K_bar to round-off."""
    data = _b1_data(b1, Damping((), 0.3, 1e-3))
    s = BodySystem(data, backend="numpy")
    for e, se in enumerate(data.superelements):
        D = 0.3 * se.M + 1e-3 * se.K
        assert np.abs(s.D[e] - D).max() <= 1e-10 * np.abs(D).max()


def _free_beam(damping, superelements=1):
    model = load_model("models/free_beam.toml", [f"superelements={superelements}", "modes=4"])
    return reduce_body(dataclasses.replace(model.body, damping=damping)).data


def _decay(damping, modes, h=1e-3, periods=8.0):
    """The damping ratio of each of `modes` (indices of the superelement's modes) measured from the
    decrement of successive peaks of its modal coordinate x_i = phi_i^T M_bar q_bar, after the end b of
    the free beam (one superelement, linear set, rho_inf = 1) was pulled 5 cm sideways and let go;
    returns (ratios, omega of the modes)."""
    s = BodySystem(_free_beam(damping), terms="linear", rho_inf=1.0)
    s.initialize(0.0, lambda t: FREE, port_displacements={"b": np.array([0.0, 0.05, 0.0])})
    MPhi, w = modal_basis(s.K, s.M).MPhi[0], modal_basis(s.K, s.M).omega[0]
    x = []
    for _ in range(int(periods * 2 * np.pi / w[modes[0]] / h)):
        s.step(h, lambda t: FREE)
        x.append(MPhi.T @ s.elastic_coordinates()[0])
    x = np.array(x)
    out = []
    for i in modes:
        xi = x[:, i]
        k = np.flatnonzero((xi[1:-1] > xi[:-2]) & (xi[1:-1] >= xi[2:])) + 1
        a, b, c = xi[k - 1], xi[k], xi[k + 1]  # each peak refined by the parabola through its 3 samples
        peaks = b - 0.125 * (a - c) ** 2 / (a - 2 * b + c)
        delta = np.log(peaks[:-1] / peaks[1:]).mean()  # logarithmic decrement
        out.append(delta / np.hypot(2 * np.pi, delta))
    return np.array(out), w[list(modes)]


def test_modal_ratio_from_the_logarithmic_decrement():
    """zeta = 0.02 on every mode: the first bending mode (18.55 rad/s; of the degenerate pair, the one the
    pull in y excites) decays with 0.02 (measured: 0.0199989, -5.7e-5 relative at omega h = 0.0186),
    within (omega h)^2 / 3; undamped, its decrement is zero to 1e-8 (measured 3e-10)."""
    h = 1e-3
    zeta, w = _decay(Damping((0.02,)), [1], h)
    assert abs(zeta[0] / 0.02 - 1) <= (w[0] * h) ** 2 / 3
    zeta0, _ = _decay(None, [1], h, periods=3.0)
    assert abs(zeta0[0]) <= 1e-8


def test_rayleigh_ratio_of_two_modes():
    """alpha = 0.5 /s, beta = 4e-4 s: the first two bending modes in y (18.55 and 51.16 rad/s) decay with
    alpha / (2 omega) + beta omega / 2 = 0.01719 and 0.01512 (measured within 2e-4 relative), within
    (omega h)^2 / 3 each."""
    h = 1e-3
    zeta, w = _decay(Damping((), 0.5, 4e-4), [1, 3], h)
    expected = 0.5 / (2 * w) + 4e-4 * w / 2
    assert np.all(np.abs(zeta / expected - 1) <= (w * h) ** 2 / 3), (zeta, expected)
    assert abs(zeta[0] - zeta[1]) > 0.1 * zeta[1]  # two different ratios: both terms are seen


@pytest.mark.parametrize("superelements", [1, 2])
def test_a_rigid_spin_is_not_damped(superelements):
    """The free beam spun about its transverse principal axis z at 2 rad/s from its undeformed state,
    linear set, 2 s (1000 steps): with zeta = 0.05 on every mode its angular momentum and rigid kinetic
    energy keep their values to round-off (1 superelement: q_bar_dot = 0, measured 2.8e-14 and 0) or, for
    the chain of 2 (whose superelement CM frames see a centrifugal load and ring, 7.7e-6 J of strain), to
    the undamped run's own drift (measured 6.0e-7 undamped, 6.7e-7 damped): damping acts on the
    elastic rates, never on the rigid motion. The power the damping takes (BodySystem.damping_power) of
    the single superelement stays at round-off, at most 1.1e-11 of K0 omega (measured; 1.3e-5 for the
    ringing chain of 2); allowed 1e-10."""
    runs, power = {}, 0.0
    for name, damping in (("undamped", None), ("damped", Damping((0.05,)))):
        s = BodySystem(_free_beam(damping, superelements), terms="linear", rho_inf=1.0)
        s.initialize(0.0, lambda t: FREE, angular_velocity=(0.0, 0.0, 2.0))
        L0, K0 = s.momenta()[1], s.energies()["kinetic_rigid"]
        for _ in range(1000):
            s.step(2e-3, lambda t: FREE)
            power = max(power, s.damping_power() / (K0 * 2.0))
        runs[name] = (np.linalg.norm(s.momenta()[1] - L0) / np.linalg.norm(L0),
                      abs(s.energies()["kinetic_rigid"] / K0 - 1))
    if superelements == 1:
        assert max(runs["damped"]) <= 1e-12
        assert power <= 1e-10
    else:
        assert runs["damped"][0] <= 2 * max(runs["undamped"][0], 1e-12)
        assert runs["damped"][1] <= 2 * max(runs["undamped"][1], 1e-12)


def test_energy_lost_is_the_work_of_the_damping_force():
    """The free beam (1 superelement, at rest, end b pulled 5 cm and let go), zeta = 0.05, 2 s at h = 2 ms:
    the energy E = kinetic + strain falls by the work of the damping force, sum h q_m^T D q_m with q_m the
    mean co-rotated rate of each step (the trapezoidal rule's own energy identity at rho_inf = 1).
    Measured: 98.8 % of E0 dissipated, the balance closed to 1.2e-5 of it (4.6e-6 at 1 ms: the rest of
    the step's Lie-group update and Newton tolerance); allowed 1e-4. The undamped balance closes to 2e-8."""
    h = 2e-3
    s = BodySystem(_free_beam(Damping((0.05,))), terms="linear", rho_inf=1.0)
    s.initialize(0.0, lambda t: FREE, port_displacements={"b": np.array([0.0, 0.05, 0.0])})
    energy = lambda: sum(s.energies()[k] for k in ("kinetic_rigid", "kinetic_elastic", "strain"))
    E0, work = energy(), 0.0
    qd = s.elastic_rates()
    for _ in range(1000):
        s.step(h, lambda t: FREE)
        qd_next = s.elastic_rates()
        qm = 0.5 * (qd + qd_next)
        work += h * float(np.einsum("ei,eij,ej->", qm, s.D, qm))
        qd = qd_next
    assert work > 0.9 * E0
    assert abs(energy() - E0 + work) <= 1e-4 * work


# ------------------------------------------------------------------ the model file and the image

DAMPED = """
[body.damping]
{damping}
"""


def _model(tmp_path, beam_toml, damping):
    text = beam_toml("[scenes.s]\nduration = 0.01\nstep = 0.001\n")
    path = tmp_path / "m.toml"
    path.write_text(text + DAMPED.format(damping=damping))
    return path


@pytest.mark.parametrize("damping, expected", [
    ("ratio = 0.02", Damping((0.02,))),
    ("ratio = [0.01, 0.02]", Damping((0.01, 0.02))),
    ("alpha = 0.5\nbeta = 1e-4", Damping((), 0.5, 1e-4)),
    ("beta = 1e-4", Damping((), 0.0, 1e-4)),
])
def test_model_file_damping_is_read(tmp_path, beam_toml, damping, expected):
    assert load_model(_model(tmp_path, beam_toml, damping)).body.damping == expected


@pytest.mark.parametrize("damping, message", [
    ("ratio = 0.02\nalpha = 0.5", "either ratio (modal damping) or alpha and beta (Rayleigh damping), not both"),
    ("ratio = -0.02", "body.damping.ratio: expected a damping ratio >= 0"),
    ("ratio = [0.01, -0.02]", "body.damping.ratio: expected a damping ratio >= 0"),
    ("ratio = []", "body.damping.ratio: expected"),
    ("alpha = -1.0", "body.damping.alpha: expected a Rayleigh coefficient >= 0"),
    ("beta = true", "body.damping.beta: expected a Rayleigh coefficient >= 0"),
    ("zeta = 0.1", "body.damping"),
    ("", "expected ratio = ZETA (modal damping) or alpha, beta (Rayleigh damping)"),
])
def test_model_file_damping_is_refused(tmp_path, beam_toml, damping, message):
    with pytest.raises(ModelError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_model(_model(tmp_path, beam_toml, damping))


def test_a_list_of_the_wrong_length_names_the_count(tmp_path, beam_toml):
    """A list of ratios needs one per mode of a superelement's reduced model: 6 x 2 frames + its modes."""
    model = load_model(_model(tmp_path, beam_toml, "ratio = [0.01, 0.02]"))
    n = 12 + model.body.modes
    with pytest.raises(ModelError, match=rf"body.damping.ratio: .*\({n} = 6 x its boundary frames \+ its modes\), got 2"):
        reduce_body(model.body)


def test_the_full_order_reference_refuses_a_damped_body(tmp_path, beam_toml):
    """The reference beam has no structural damping: a damped body's reference run (simulate --solver
    reference, chart, advise --check) is refused naming the key, not run undamped against a damped product."""
    from ffrf_fmu.simulate import run_reference

    model = load_model(_model(tmp_path, beam_toml, "ratio = 0.02"))
    with pytest.raises(ModelError, match="body.damping: the full-order reference beam has no structural damping"):
        run_reference(model, model.scene())


def test_damping_survives_save_and_load(tmp_path, b1):
    data = _b1_data(b1, Damping((0.01,), 0.2, 3e-4))
    data.save(tmp_path / "b.npz")
    assert BodyData.load(tmp_path / "b.npz").damping == data.damping
    assert BodyData.load(tmp_path / "b.npz").superelements[0].n == 15


def test_c_runtime_refuses_a_negative_ratio_and_rebuilds_d(b1):
    """ffrf_damping_update: a negative ratio or coefficient is refused (-1, D unchanged); new values rebuild D,
    which then equals the Python construction to round-off."""
    s = BodySystem(_b1_data(b1, Damping((0.05,))), backend="numpy")
    body = NativeBody(body_image(s))
    update = body.lib.ffrf_damping_update
    update.restype, update.argtypes = ctypes.c_int, [ctypes.c_void_p]
    zeta, ab, D = body.array("damp_zeta"), body.array("damp_ab"), body.array("damp_D")
    assert np.abs(D.reshape(s.D.shape) - s.D).max() <= 1e-12 * np.abs(s.D).max()
    before = D.copy()
    zeta[3] = -0.01
    assert update(body.ptr) == -1 and np.array_equal(D, before)
    zeta[:] = 0.0
    ab[:] = (0.3, 1e-3)
    assert update(body.ptr) == 0
    expected = BodySystem(_b1_data(b1, Damping((), 0.3, 1e-3)), backend="numpy").D
    assert np.abs(D.reshape(expected.shape) - expected).max() <= 1e-12 * np.abs(expected).max()


# ------------------------------------------------------------------ the FMUs' damping parameters

@pytest.fixture(scope="module")
def beam_models(tmp_path_factory, small_toml):
    """The small B1-like beam of conftest (2 superelements, hub driven at a constant rate, a constant tip
    load: scene `spin`): undamped, and with [body.damping] ratio = 0.05."""
    d = tmp_path_factory.mktemp("damped")
    plain, damped = d / "plain.toml", d / "damped.toml"
    plain.write_text(small_toml())
    damped.write_text(small_toml() + "\n[body.damping]\nratio = 0.05\n")
    return plain, damped


def _worst(run, ref) -> float:
    """The largest difference of an output column of two runs, relative to the column's scale."""
    names = [n for n in ref.columns if n in run.columns and not n.startswith("solver.")]
    assert "energy.strain" in names and "tip.r[3]" in names
    return max(np.abs(run.columns[n] - ref.columns[n]).max() / max(np.abs(ref.columns[n]).max(), 1e-300)
               for n in names)


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmu_damping_parameter_equals_the_standalone_damped_run(beam_models, fmi):
    """The native FMU built from the undamped model, run under fmpy at H = h with the parameter
    damping.ratio = 0.05, equals the FMU built from the model file with [body.damping] ratio = 0.05 bit for
    bit (the same modes in the image, the same D from ffrf_damping_update), and the standalone run of that
    model as closely as the undamped FMU equals its own standalone run (the motion inputs, extrapolated
    by the FMU's rule and scheduled by the standalone run, differ by round-off, which the hub reactions
    show: measured 1.8e-9 undamped, 1.4e-9 damped; allowed twice the undamped, at least 1e-12). Without the
    parameter the outputs differ from the damped run by far more: the damping is what is compared."""
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.fmu.run import run_fmu
    from ffrf_fmu.simulate import run_scene

    plain, damped = beam_models
    sc = load_model(plain).scene("spin")
    fmu = build_fmu(plain, plain.parent / f"plain{fmi}.fmu", scene="spin", platforms=("linux64",), fmi=fmi)
    fmu_damped = build_fmu(damped, damped.parent / f"damped{fmi}.fmu", scene="spin", platforms=("linux64",),
                                  fmi=fmi)
    run = run_fmu(fmu, sc, start_values={"damping.ratio": 0.05})
    built_damped = run_fmu(fmu_damped, sc)
    assert run.reached and all(np.array_equal(run.columns[n], built_damped.columns[n]) for n in run.columns)
    ref, ref_plain = run_scene(load_model(damped), "spin"), run_scene(load_model(plain), "spin")
    undamped = run_fmu(fmu, sc)
    assert np.allclose(run.t, ref.t, rtol=0, atol=1e-12)
    assert _worst(run, ref) <= 2 * max(_worst(undamped, ref_plain), 1e-12)
    assert _worst(undamped, ref) > 1e-4


@pytest.mark.parametrize("name", ["damping.ratio", "damping.alpha", "damping.beta"])
def test_fmu_refuses_a_negative_damping_parameter(beam_models, name):
    """A negative ratio or coefficient set by the host: fmi2ExitInitializationMode returns fmi2Error and the
    log names the parameter and its value."""
    import fmpy

    from ffrf_fmu.fmu.builder import build_fmu

    plain, _ = beam_models
    fmu = build_fmu(plain, plain.parent / "plain2.fmu", scene="spin", platforms=("linux64",))
    log = []
    with pytest.raises(Exception, match="fmi2ExitInitializationMode failed with status 3"):
        fmpy.simulate_fmu(str(fmu), stop_time=0.01, output_interval=2e-3, start_values={name: -0.01},
                          debug_logging=True, logger=lambda c, i, s, cat, msg: log.append(msg.decode()))
    assert any(f"parameter {name} must be finite and >= 0" in m and "got -0.01" in m for m in log), log


def test_python_fmu_takes_the_damping_parameter(beam_models):
    """The pythonfmu FMU (--runtime python, numpy path): damping.ratio = 0.05 set by the host gives the run of
    the damped model file (its own standalone run on numpy, to the same 2x of the undamped pair's
    difference), and a negative ratio is refused at initialization."""
    import fmpy

    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.fmu.run import run_fmu
    from ffrf_fmu.simulate import run_scene

    plain, damped = beam_models
    sc = load_model(plain).scene("spin")
    fmu = build_fmu(plain, plain.parent / "plain_py.fmu", scene="spin", runtime="python")
    run, undamped = run_fmu(fmu, sc, start_values={"damping.ratio": 0.05}), run_fmu(fmu, sc)
    ref = run_scene(load_model(damped), "spin", backend="numpy")
    ref_plain = run_scene(load_model(plain), "spin", backend="numpy")
    assert _worst(run, ref) <= 2 * max(_worst(undamped, ref_plain), 1e-12)
    assert _worst(undamped, ref) > 1e-4
    log = []
    with pytest.raises(Exception, match="fmi2ExitInitializationMode failed with status 3"):
        fmpy.simulate_fmu(str(fmu), stop_time=0.02, output_interval=0.01, start_values={"damping.ratio": -0.01},
                          debug_logging=True, logger=lambda c, i, s, cat, msg: log.append(msg.decode()))
    assert any("parameter damping.ratio must be finite and >= 0" in m for m in log), log


def test_info_reports_each_modes_ratio():
    """`ffrf-fmu info --json` with Rayleigh damping on the free beam in 1 superelement: the ratio of each
    mode is alpha / (2 omega) + beta omega / 2 at the mode's frequency (the first bending pair: 2.95 Hz,
    0.0172)."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "ffrf_fmu", "info", "models/free_beam.toml", "--json", "--set",
                          "superelements=1", "--set", "modes=4", "--set", "body.damping.alpha=0.5", "--set",
                          "body.damping.beta=4e-4"], capture_output=True, text=True, check=True)
    d = json.loads(out.stdout)["damping"]
    w = 2 * np.pi * np.array(d["mode_frequencies_hz"])
    assert d["kind"] == "rayleigh" and len(w) == 16
    assert np.allclose(d["mode_ratios"], 0.5 / (2 * w) + 4e-4 * w / 2, rtol=1e-12)
    assert abs(d["mode_ratios"][0] - 0.0172) < 1e-4


def test_fmu_ratios_per_mode_are_parameters(beam_models, small_toml):
    """A model file listing one ratio per mode (the small beam: 2 boundary frames x 6 + 2 modes = 14) gives
    the FMU the parameters damping.ratio[1..14] with those start values; set to another list under fmpy, the
    run equals, bit for bit, the FMU built from the model file with that other list."""
    from fmpy import read_model_description

    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.fmu.run import run_fmu

    d = beam_models[0].parent
    first, second = np.linspace(0.01, 0.1, 14), np.linspace(0.1, 0.01, 14)
    fmus = []
    for name, z in (("first", first), ("second", second)):
        path = d / f"{name}.toml"
        path.write_text(small_toml() + f"\n[body.damping]\nratio = {[float(x) for x in z]}\n")
        fmus.append(build_fmu(path, d / f"{name}.fmu", scene="spin", platforms=("linux64",)))
    starts = {v.name: float(v.start) for v in read_model_description(str(fmus[0])).modelVariables
              if v.name.startswith("damping.ratio")}
    assert starts == {f"damping.ratio[{i + 1}]": float(z) for i, z in enumerate(first)}
    sc = load_model(beam_models[0]).scene("spin")
    run = run_fmu(fmus[0], sc, start_values={f"damping.ratio[{i + 1}]": float(z) for i, z in enumerate(second)})
    ref, plain = run_fmu(fmus[1], sc), run_fmu(fmus[0], sc)
    assert all(np.array_equal(run.columns[n], ref.columns[n]) for n in ref.columns)
    assert not np.array_equal(plain.columns["energy.strain"], ref.columns["energy.strain"])


def test_a_damped_tumbling_free_beam_fmu_equals_its_standalone_run(tmp_path):
    """B4 (models/free_beam.toml, 1 superelement, 0.2 s) with ratio = 0.05: tumbling from end b pulled by
    (0, 0.05, 0.02) m, its ringing decays (strain 4.8e-3 J -> 1.4e-3 J). The native FMU under fmpy at H = h
    equals the standalone run: every output column within 1e-8 of its scale (measured 1.2e-9, the port
    accelerations). This needs the FMU's start to be the standalone one: end a, whose displacement parameter
    is zero, keeps its rotation in the initial relaxation as a port the scene does not displace (before, the
    FMU freed it, and the beam turned rigidly about a instead of bending: strain 0, b at y = 0.27 m)."""
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.fmu.run import run_fmu
    from ffrf_fmu.simulate import run_scene

    overrides = ["superelements=1", "scenes.tumble.duration=0.2", "body.damping.ratio=0.05"]
    fmu = build_fmu("models/free_beam.toml", tmp_path / "b4.fmu", scene="tumble", platforms=("linux64",),
                    overrides=overrides)
    model = load_model("models/free_beam.toml", overrides)
    run, ref = run_fmu(fmu, model.scene("tumble")), run_scene(model, "tumble")
    strain = ref.columns["energy.strain"]
    assert strain[0] > 4e-3 and strain[-1] < 0.5 * strain[0]
    names = [n for n in ref.columns if n in run.columns and not n.startswith("solver.")]
    assert len(names) > 60 and "energy.strain" in names
    worst = max(np.abs(run.columns[n] - ref.columns[n]).max() / max(np.abs(ref.columns[n]).max(), 1e-300)
                for n in names)
    assert worst <= 1e-8, worst


def test_an_undamped_run_makes_no_basis_and_steps_the_same(monkeypatch):
    """An undamped body computes no modal basis in its set-up and its C body's image carries none
    (BodySystem.damping_basis on first use; an FMU's image, body_image's default, has it, for its damping
    parameters); its run is that of a C body from the image with the basis, bit for bit (no damping:
    D = 0 either way). B1 (models/haug_beam.toml) 1 SE x 2 modes, stiffened, 40 ms."""
    from pathlib import Path

    from ffrf_fmu.body_cache import scene_body_data
    from ffrf_fmu.runtime.native import binding, image
    from ffrf_fmu.simulate import loop

    model = load_model(str(Path(__file__).resolve().parents[1] / "models" / "haug_beam.toml"),
                       ["superelements=1", "modes=2", "stiffening=true", "step=0.04"])
    scene = model.scene("spinup")
    data = scene_body_data(model.body, scene)
    runs = []
    for with_basis in (False, True):
        if with_basis:
            monkeypatch.setattr(binding, "body_image", lambda s, basis, checksum_of: image.body_image(s, True, checksum_of))
        s, _ = loop.build_system(data, scene)
        assert s.backend == "native" and ("damping_basis" in vars(s)) == with_basis
        runs.append(loop.run(data, scene, progress=False))
    assert runs[0].columns.keys() == runs[1].columns.keys()
    assert all(np.array_equal(runs[0].columns[k], runs[1].columns[k]) for k in runs[0].columns)
    monkeypatch.undo()
    s, _ = loop.build_system(data, scene)
    assert image.unpack(image.body_image(s, basis=False))["damp_omega"].shape == (1, 0)
    assert "damping_basis" not in vars(s)
    assert image.unpack(image.body_image(s))["damp_omega"].shape == (1, data.superelements[0].n)  # made now
    assert "damping_basis" in vars(s)
