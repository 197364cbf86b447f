"""An FMU built from a scene that starts at its static equilibrium or steady spin starts there too: the start
state is made at build time from the scene (fmu/builder.py start_states: initial_state.settle, as the
standalone run) and stored in the FMU (the native FMU's resources/body.bin start sections, the pythonfmu
FMU's ffrf_fmu.json); the FMU takes it at its initialization (runtime/start.py, fmu/native/initialize.c
fmu_start_body) after checking that its parameters and motion inputs at t0 are those it was made for."""
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
ROTOR = ROOT / "models" / "sagging_rotor.toml"  # 2 rad/s steady from before t = 0, gravity along the axis
SHORT = ["scenes.lag_kick.duration=1.5", "step=0.01"]  # the start, then the in-plane kick from 0.503 s
STILL = ["scenes.lag_kick.duration=1.0", "step=0.005", "scenes.lag_kick.loads=[]"]  # the start alone


def _build(tmp_path, name, overrides, **kw):
    from ffrf_fmu.fmu.builder import build_fmu

    return build_fmu(ROTOR, tmp_path / f"{name}.fmu", scene="lag_kick", overrides=overrides, platforms=("linux64",),
                     **kw)


@pytest.mark.parametrize("kind", ["native2", "native3", "python"])
def test_fmu_starts_where_the_standalone_run_starts(kind, tmp_path):
    """validate (fmpy, H = h = 10 ms): the FMU's outputs equal the standalone run's started the same way, at
    t = 0 (the sagged, spinning arm: tip 0.1227 m below its reference) and through the kick (measured with the
    native FMI 2.0 FMU: root force within 3.8e-9 N, tip position 1.5e-14 m, metrics within 3e-13; started from
    rest the tip would be at 0 at t = 0)."""
    from ffrf_fmu.validate import validate

    kw = {"native2": {}, "native3": {"fmi": 3}, "python": {"runtime": "python"}}[kind]
    fmu = _build(tmp_path, kind, SHORT, **kw)
    rep = validate(fmu, model=ROTOR, scene="lag_kick", overrides=SHORT, plots=False, rtol=1e-9, atol=1e-12)
    assert rep["passed"], {k: g["max_abs_diff"] for k, g in rep["groups"].items()}
    assert rep["metrics"]["tip_in_plane_max_m"]["rel_diff"] < 1e-9


def test_steady_spin_fmu_stays_steady(tmp_path):
    """The native FMU of the start alone (no kick), H = h = 5 ms over 1 s: the tip seen from the hub (eq. 92)
    starts at the standalone run's steady sag and stays there up to the integrator's O(h^2) transient of a
    circular motion in world coordinates (docs/accuracy.md 4.7: 2.9e-5 m in the plane over 4 s at 5 ms,
    1 SE; measured here 3.6e-5 m, 2 SE over 1 s, the standalone run's to 1e-14), against the arm's swing by about its sag when the
    same FMU is built from a scene that starts at rest (the hub spinning, the arm undeformed)."""
    from ffrf_fmu.fmu.run import fmu_body, run_fmu
    from ffrf_fmu.model import load_model
    from ffrf_fmu.simulate import elastic_tip, run_scene

    sc = load_model(ROTOR, STILL).scene("lag_kick")
    standalone = elastic_tip(run_scene(ROTOR, "lag_kick", STILL), "root", "tip")
    tips = {}
    for state in ("steady_spin", "rest"):
        ov = [*STILL, f'scenes.lag_kick.initial.state="{state}"']
        fmu = _build(tmp_path, state, ov)
        run = run_fmu(fmu, load_model(ROTOR, ov).scene("lag_kick"))
        assert run.reached
        tips[state] = elastic_tip(run.result(fmu_body(fmu)), "root", "tip")
    d = tips["steady_spin"]
    assert np.abs(d[0] - standalone[0]).max() < 1e-12 and d[0, 2] == pytest.approx(-0.1227, abs=5e-4)
    assert np.ptp(d, axis=0).max() < 5e-5
    assert np.ptp(tips["rest"][:, 2]) > 0.1  # from rest: the arm falls into its sag and swings about it
    assert sc.initial.state == "steady_spin"


def test_start_state_refuses_other_parameters_and_inputs(tmp_path):
    """The start holds for the scene's gravity and for the motion the scene's drive gives the hub at t0: another
    gravity, or a hub held still at the same angle, makes the initialization an error naming the cause."""
    import fmpy

    from ffrf_fmu.fmu.run import fmu_body, fmu_input_table, scene_start_values
    from ffrf_fmu.model import load_model
    from ffrf_fmu.simulate import scene_inputs

    fmu = _build(tmp_path, "checks", SHORT)
    body = fmu_body(fmu)
    cases = {"gravity": (SHORT, {"gravity[3]": -9.0}, "parameter gravity = [0.0, 0.0, -9.0] is not the [0.0, 0.0, -9.81]"),
             # the inputs of a scene whose hub stands still (a scene that cannot start steady: it starts at rest)
             "held hub": ([*SHORT, 'scenes.lag_kick.drives.root.rotation.angle={kind = "constant", value = 2.0}',
                           'scenes.lag_kick.initial.state="rest"'], {},
                          "port root's rotation rate element 2 = 2, the inputs at t0 give 0")}
    for name, (ov, values, cause) in cases.items():
        sc = load_model(ROTOR, ov).scene("lag_kick")
        table = fmu_input_table(fmu, scene_inputs(body, sc), np.arange(3) * sc.step)
        log = []
        with pytest.raises(Exception):
            fmpy.simulate_fmu(str(fmu), stop_time=2 * sc.step, output_interval=sc.step, input=table,
                              start_values={**scene_start_values(sc, fmu), **values},
                              logger=lambda c, i, s, cat, msg: log.append(msg.decode() if isinstance(msg, bytes) else msg))
        assert any(cause in m for m in log), (name, log)


def test_static_start_fmu_holds_still(tmp_path, beam_toml):
    """A B1-like beam started "static" under gravity along -Z and a 0.05 N tip load (tests/test_initial_state.py
    scene sag): the native FMU equals the standalone run (validate, H = h = 10 ms; at rest the tip's rates are
    round-off, 1e-12 m/s and 2e-9 m/s^2 against g = 9.81, and the hub reaction agrees to 8e-9 of its 15.8 N,
    measured: rtol 1e-7, atol 1e-8) and its tip does not move (to 1e-10 m, as the standalone run's: the
    integrator starts in equilibrium; from rest it would swing by about twice its 1.77 m sag)."""
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.fmu.run import fmu_body, run_fmu
    from ffrf_fmu.model import load_model
    from ffrf_fmu.simulate import elastic_tip
    from ffrf_fmu.validate import validate
    from test_initial_state import SCENES

    model = tmp_path / "b.toml"
    model.write_text(beam_toml(SCENES, superelements=2, elements=8))
    fmu = build_fmu(model, tmp_path / "sag.fmu", scene="sag", platforms=("linux64",))
    rep = validate(fmu, model=model, scene="sag", plots=False, rtol=1e-7, atol=1e-8)
    assert rep["passed"], {k: g["max_abs_diff"] for k, g in rep["groups"].items()}
    d = elastic_tip(run_fmu(fmu, load_model(model).scene("sag")).result(fmu_body(fmu)), "hub", "tip")
    assert d[0, 2] == pytest.approx(-1.7676, abs=1e-3) and np.ptp(d, axis=0).max() < 1e-10
