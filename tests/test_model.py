"""Model files: the bundled models load, overrides apply, and every class of mistake gets a
message that names the file, the dotted key and what was expected."""
import dataclasses
from pathlib import Path

import pytest

from ffrf_fmu.checked_toml import toml_text
from ffrf_fmu.model import Metrics, ModelError, load_model, scene_body

MODELS = Path(__file__).resolve().parent.parent / "models"

@pytest.fixture
def minimal(beam_toml) -> str:
    """The smallest model file: no name, Euler-Bernoulli, one scene with its required keys only."""
    return beam_toml("[scenes.run]\nduration = 1.0\nstep = 1e-3\n", name=None, modes=6, shear=False)


def write(tmp_path, text, name="beam.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def error(tmp_path, text, overrides=()):
    path = write(tmp_path, text)
    with pytest.raises(ModelError) as info:
        load_model(path, overrides)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    return message


def test_bundled_models_load():
    b1 = load_model(MODELS / "haug_beam.toml")
    assert (b1.body.superelements, b1.body.elements_per_superelement, b1.body.modes) == (4, 8, 6)
    assert [p.node for p in b1.body.ports] == [0, 4]
    assert [s.name for s in b1.scenes] == ["spinup", "spinup_fast", "hub_free"]
    spin = b1.scene("spinup")
    assert spin.drives[0].rotation.angle.params == (("T", 15.0), ("omega", 4.0))
    assert dict(b1.scene("spinup_fast").drives[0].rotation.angle.params)["omega"] == 8.0
    hub = scene_body(b1.body, b1.scene("hub_free")).ports[0]
    assert (hub.translation, hub.rotation) == ("motion", "force")
    assert scene_body(b1.body, spin).ports == b1.body.ports
    with pytest.raises(ModelError, match=r"scene 'spinup' sets the causality of unknown port\(s\) \['nope'\]"):
        scene_body(b1.body, dataclasses.replace(spin, causality=(("nope", "motion", "force"),)))

    b2 = load_model(MODELS / "spherical_beam.toml")
    assert b2.body.section.GA2 is None  # Euler-Bernoulli
    tq, tip = b2.scene().loads
    assert (tq.port, tq.moment, tq.t_start, tq.t_end) == ("root", (0.0, 0.0, 200.0), 0.0, 10.0)
    assert (tip.port, tip.force, tip.t_start, tip.t_end) == ("tip", (0.0, 0.0, 100.0), 15.0, 15.2)

    b4 = load_model(MODELS / "free_beam.toml")
    assert b4.scene().initial.port_displacements == (("b", (0.0, 0.05, 0.02)),)
    assert b4.scene().rho_inf == 1.0


def test_overrides():
    m = load_model(
        MODELS / "haug_beam.toml",
        ["superelements=2", "modes=4", "elements_per_superelement=6", "rotary_inertia=22.7e-3", "step=1e-3",
         "rho_inf=0.5", "terms=gyroscopic", 'terms="gyroscopic"', "duration=5",
         "scenes.spinup.drives.hub.rotation.angle.omega=6"],
    )
    b = m.body
    assert (b.superelements, b.modes, b.elements_per_superelement) == (2, 4, 6)
    assert b.section.m22 == b.section.m33 == 22.7e-3
    assert b.port("tip").node == 2  # node -1 follows the new superelement count
    for s in m.scenes:  # scene keys apply to every scene
        assert (s.step, s.rho_inf, s.terms, s.duration) == (1e-3, 0.5, "gyroscopic", 5.0)
    assert dict(m.scene("spinup").drives[0].rotation.angle.params)["omega"] == 6.0


def test_ambiguous_elements_key_is_refused_naming_both_meanings():
    """`--set elements=N` meant elements per superelement, while [scenes.NAME.reference] elements and the
    peers' `elements` count the whole beam: the short key is refused with the two spellings to use."""
    with pytest.raises(ModelError, match=r"elements_per_superelement=N .* scenes\.NAME\.reference\.elements=N"):
        load_model(MODELS / "haug_beam.toml", ["elements=6"])


def test_bad_override_names_the_key():
    with pytest.raises(ModelError, match=r"body\.modes: expected an integer >= 0.*--set modes=many"):
        load_model(MODELS / "haug_beam.toml", ["modes=many"])
    with pytest.raises(ModelError, match=r"unknown key 'stpe'; did you mean step\?"):
        load_model(MODELS / "haug_beam.toml", ["stpe=1e-3"])
    with pytest.raises(ModelError, match=r"expected key=value"):
        load_model(MODELS / "haug_beam.toml", ["step"])


def test_minimal_model_defaults(tmp_path, minimal):
    m = load_model(write(tmp_path, minimal))
    s = m.scene()
    assert (s.rho_inf, s.terms, s.gravity, s.metrics) == (0.8, "linear", (0.0, 0.0, 0.0), Metrics())
    assert m.body.name == "beam" and m.body.direction == (1.0, 0.0, 0.0)
    assert (m.body.ports[1].translation, m.body.ports[1].rotation) == ("force", "force")


def test_metrics_table(tmp_path, minimal):
    """[scenes.NAME.metrics]: the table, a kind alone, and a clear error for each mistake."""
    table = minimal + '[scenes.run.metrics]\nkind = "hub_rates"\nprimary = "omega_z_at_15s"\ncoast_end_s = 15.0\n' \
        'band_hz = [0.5, 5.0]\nmin_window_s = 1.0\n'
    assert load_model(write(tmp_path, table)).scene().metrics == Metrics("hub_rates", "omega_z_at_15s", (0.5, 5.0), 1.0,
                                                                          15.0)
    alone = load_model(write(tmp_path, minimal + 'metrics = "tip_deflection"\n')).scene().metrics
    assert alone == Metrics("tip_deflection", "tip_deflection_max_m")
    assert "scenes.run.metrics: 'haug' was a benchmark's name; write the table [scenes.run.metrics] with kind = " \
           "'tip_deflection'" in error(tmp_path, minimal + 'metrics = "haug"\n')
    assert "scenes.run.metrics.primary: expected one of the kind's metrics" in error(
        tmp_path, table.replace('primary = "omega_z_at_15s"', 'primary = "tip_deflection_max_m"'))
    assert "scenes.run.metrics.band_hz: expected 2 frequencies 0 < low < high" in error(
        tmp_path, table.replace("[0.5, 5.0]", "[5.0, 0.5]"))
    assert "scenes.run.metrics.kind" in error(tmp_path, table.replace('"hub_rates"', '"rates"'))
    assert "scenes.run.metrics.window" in error(tmp_path, table + "window = 2.0\n")


def test_toml_text_round_trips(tmp_path, minimal):
    """checked_toml.toml_text writes the raw tables load_model reads: the same model back."""
    from ffrf_fmu.model import tomllib  # the standard library's, or tomli on Python 3.10

    raw = tomllib.loads(minimal + '[scenes.run.metrics]\nkind = "tip_deflection"\nband_hz = [0.1, 2.0]\n'
                        '[[scenes.run.loads]]\nport = "tip"\nforce = [0.0, 1.0, 0.0]\nt_end = 0.5\n')
    text = toml_text(raw, "generated")
    assert tomllib.loads(text) == raw and text.startswith("# generated\n")
    assert load_model(write(tmp_path, text, "again.toml")).scene() == load_model(write(tmp_path, minimal + \
        '[scenes.run.metrics]\nkind = "tip_deflection"\nband_hz = [0.1, 2.0]\n[[scenes.run.loads]]\nport = "tip"\n'
        'force = [0.0, 1.0, 0.0]\nt_end = 0.5\n')).scene()


def test_unreadable_file(tmp_path, minimal):
    with pytest.raises(ModelError, match="cannot read"):
        load_model(tmp_path / "missing.toml")
    assert "not valid TOML" in error(tmp_path, minimal + "[[[")


def test_unknown_key_suggests_nearest(tmp_path, minimal):
    msg = error(tmp_path, minimal.replace("EI2 = 566.0", "EJ2 = 566.0"))
    assert "body.section.EJ2: unknown key; did you mean body.section.EI2?" in msg


def test_wrong_type(tmp_path, minimal):
    msg = error(tmp_path, minimal.replace("length = 8.0", 'length = "8 m"'))
    assert "body.length: expected a positive length [m], got '8 m' (string)" in msg


@pytest.mark.parametrize("old, new, key", [
    ("length = 8.0", "length = 0.0", "body.length"),
    ("EI2 = 566.0", "EI2 = -566.0", "body.section.EI2"),
    ("m = 0.201", "m = 0", "body.section.m"),
])
def test_non_positive_length_stiffness_mass(tmp_path, old, new, key, minimal):
    assert f"{key}: expected a positive" in error(tmp_path, minimal.replace(old, new))


def test_too_few_elements(tmp_path, minimal):
    msg = error(tmp_path, minimal.replace("elements_per_superelement = 4", "elements_per_superelement = 1"))
    assert "body.elements_per_superelement: expected an integer >= 2 (F_BB must be invertible" in msg


@pytest.mark.parametrize("node", [3, -4])
def test_port_on_missing_node(tmp_path, node, minimal):
    msg = error(tmp_path, minimal.replace("node = -1", f"node = {node}"))
    assert f"body.ports.tip.node: expected a boundary node in 0..2 (or -3..-1 from the end)" in msg


@pytest.mark.parametrize("section, key", [
    ('[scenes.run.drives.hubb.rotation]\naxis = [0, 0, 1]\nangle = 1.0\n', "scenes.run.drives.hubb"),
    ('[[scenes.run.loads]]\nport = "tpi"\nforce = [0, 0, 1]\n', "scenes.run.loads[0].port"),
    ('[scenes.run.causality.tpi]\nrotation = "motion"\n', "scenes.run.causality.tpi"),
    ('[scenes.run.initial]\nport_displacements = { tpi = [0, 0.1, 0] }\n', "scenes.run.initial.port_displacements.tpi"),
])
def test_scene_names_missing_port(tmp_path, section, key, minimal):
    msg = error(tmp_path, minimal + section)
    assert f"{key}: expected the name of a body port, got" in msg and "did you mean '" in msg and "(ports: hub, tip)" in msg


def test_load_on_motion_driven_part(tmp_path, minimal):
    msg = error(tmp_path, minimal + '[[scenes.run.loads]]\nport = "hub"\nmoment = [0, 0, 1]\n')
    assert "scenes.run.loads[0].moment: expected a force-driven rotation: port 'hub' rotation is motion-driven" in msg
    # a causality override in the scene makes the same load valid
    ok = minimal + '[scenes.run.causality.hub]\nrotation = "force"\n[[scenes.run.loads]]\nport = "hub"\nmoment = [0, 0, 1]\n'
    assert load_model(write(tmp_path, ok, "ok.toml")).scene().loads[0].moment == (0.0, 0.0, 1.0)


def test_drive_on_force_driven_part(tmp_path, minimal):
    msg = error(tmp_path, minimal + '[scenes.run.drives.tip.rotation]\naxis = [0, 0, 1]\nangle = 1.0\n')
    assert "scenes.run.drives.tip.rotation: expected a motion-driven rotation" in msg


@pytest.mark.parametrize("angle, key, expected", [
    ('{ kind = "spin", omega = 4.0 }', "angle.kind", "expected one of constant, haug_spinup"),
    ('{ kind = "haug_spinup", omega = 4.0 }', "angle.T", "missing; expected a number (parameters of haug_spinup"),
    ('{ kind = "haug_spinup", omega = 4.0, T = 15.0, phase = 0.0 }', "angle.phase", "unknown key"),
    ('{ omega = 4.0 }', "angle.kind", "missing; expected one of constant"),
])
def test_bad_time_function(tmp_path, angle, key, expected, minimal):
    msg = error(tmp_path, minimal + f"[scenes.run.drives.hub.rotation]\naxis = [0, 0, 1]\nangle = {angle}\n")
    assert f"scenes.run.drives.hub.rotation.{key}: {expected}" in msg


@pytest.mark.parametrize("rho", ["-0.1", "1.5"])
def test_rho_inf_outside_unit_interval(tmp_path, rho, minimal):
    msg = error(tmp_path, minimal + f"rho_inf = {rho}\n")
    assert "scenes.run.rho_inf: expected a spectral radius in [0, 1]" in msg


def test_unknown_term_set(tmp_path, minimal):
    msg = error(tmp_path, minimal + 'terms = "nonlinear"\n')
    assert "scenes.run.terms: expected one of linear, gyroscopic" in msg


def test_scene_reference_table_is_read_and_checked(tmp_path):
    """[scenes.NAME.reference] names the reference that resolves the primary metric (B4: 32 elements,
    2 ms); the study runners take it as their default, an explicit value wins; a bad value is an error
    naming the key."""
    from ffrf_fmu.studies.runners import reference_elements

    b4 = load_model(MODELS / "free_beam.toml")
    sc = b4.scene("tumble")
    assert (sc.reference.elements, sc.reference.step) == (32, 2e-3)
    assert reference_elements(b4, sc, None) == 32 and reference_elements(b4, sc, 64) == 64
    b1 = load_model(MODELS / "haug_beam.toml")
    assert b1.scene().reference.elements is None and reference_elements(b1, b1.scene(), None) == 16
    bad = tmp_path / "bad.toml"
    bad.write_text((MODELS / "free_beam.toml").read_text().replace("elements = 32\nstep = 2e-3", "elements = 32\nstep = -1"))
    with pytest.raises(ModelError, match=r"scenes\.tumble\.reference\.step: expected a positive time step"):
        load_model(bad)
