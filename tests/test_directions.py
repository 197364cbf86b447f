"""Directions relative to the spin (ffrf_fmu/directions.py): the plane of rotation, what a load excites,
and the tip_deflection metrics split in and out of that plane, checked on synthetic histories and on the
bundled 3D blade against the body linearized about its steady spin."""
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.directions import directional_tip_metrics, excites, exciting_events, spin_plane
from ffrf_fmu.model import load_model

ROOT = Path(__file__).resolve().parent.parent
BLADE = str(ROOT / "models" / "blade.toml")


def test_spin_plane_and_what_loads_excite():
    plane = spin_plane([0, 0, 2.0], [1.0, 0, 0])
    assert np.allclose(plane.in_plane, [0, 1, 0]) and np.allclose(plane.out_of_plane, [0, 0, 1])
    # a coned beam (axis not normal to it): out-of-plane is the part of the axis normal to the beam
    beta = np.radians(10.0)
    coned = spin_plane([0, 0, 1.0], [np.cos(beta), 0, np.sin(beta)])
    assert np.allclose(coned.out_of_plane, [-np.sin(beta), 0, np.cos(beta)])
    assert excites([0, 0, 3.0], plane) == {"out-of-plane"}
    assert excites([0, 1.0, 1.0], plane) == {"in-plane", "out-of-plane"}
    assert excites([1.0, 0, 0], plane) == set()  # axial
    assert excites([0, 1.0, 0], plane, moment=True) == {"out-of-plane"}  # about the in-plane normal: flap
    assert excites([0, 0, 1.0], plane, moment=True) == {"in-plane"}


def test_directional_metrics_on_a_synthetic_history():
    """The blade scene's events: spin-up to T = 6 s (in the plane), a tip load along Z ending at 8.513 s
    (out of it). A history with a 1.7 Hz in-plane and a 1.45 Hz out-of-plane vibration, each starting
    with its event: maxima and frequencies come back per direction (the fit is exact on a pure sinusoid)."""
    scene = load_model(BLADE).scene("flap_kick")
    plane = spin_plane([0, 0, 1.0], [1.0, 0, 0])
    assert exciting_events(scene, plane) == {"in-plane": 6.0, "out-of-plane": 8.513}
    t = np.arange(0.0, 14.0, 0.002)
    d = np.zeros((len(t), 3))
    d[:, 1] = np.where(t > 6.0, 0.1 * np.sin(2 * np.pi * 1.7 * t), 0.2 * t / 6.0)
    d[:, 2] = np.where(t > 8.013, 0.3 * np.sin(2 * np.pi * 1.45 * (t - 8.013)), 0.0)
    from ffrf_fmu.simulate import dominant_frequency

    m = directional_tip_metrics(t, d, scene, [1.0, 0, 0], dominant_frequency)
    assert m["tip_in_plane_max_m"] == pytest.approx(0.2, rel=1e-3)
    assert m["tip_out_of_plane_max_m"] == pytest.approx(0.3, rel=1e-4)
    assert m["in_plane_frequency_hz"] == pytest.approx(1.7, rel=1e-6)
    assert m["out_of_plane_frequency_hz"] == pytest.approx(1.45, rel=1e-6)


def test_blade_vibrates_at_the_linearized_frequency_of_each_direction():
    """The bundled blade (2 SE, stiffening on): after the spin-up the tip vibrates in the plane of rotation
    at the first lead-lag frequency of the blade linearized about its steady spin at 7 rad/s (fitted up to
    the kick), and after the out-of-plane kick out of the plane at the first flap frequency (measured
    1.67586 against 1.67574 Hz, 1.44774 against 1.44802 Hz). 1e-3: the fits see the higher modes too; a
    wrong direction would be off by 14 % (1.68 against 1.45 Hz)."""
    from ffrf_fmu.model import scene_body
    from ffrf_fmu.simulate import run_scene
    from ffrf_fmu.studies.indicators import stiffened_frequencies

    model = load_model(BLADE, ["stiffening=true"])
    scene = model.scene("flap_kick")
    lin = stiffened_frequencies(scene_body(model.body, scene), scene, 7.0, np.array([0, 0, 1.0]))
    assert lin["out-of-plane"] < lin["in-plane"]  # this blade is stiffer in the plane, even spun
    m = run_scene(BLADE, "flap_kick", ["stiffening=true"]).summary["metrics"]
    assert m["in_plane_frequency_hz"] == pytest.approx(lin["in-plane"], rel=1e-3)
    assert m["out_of_plane_frequency_hz"] == pytest.approx(lin["out-of-plane"], rel=1e-3)
    assert m["tip_out_of_plane_max_m"] > 1.5 * m["tip_in_plane_max_m"]
    assert m["tip_deflection_max_m"] >= max(m["tip_out_of_plane_max_m"], m["tip_in_plane_max_m"])
