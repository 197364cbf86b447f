"""Loads between steps (docs/equations.md, "Loads between steps"): a load window's impulse is its load
times its length to round-off for any step, in the standalone run (both backends), the full-order
reference and an FMU's input table, whether or not the steps land on the window's ends."""
import numpy as np
import pytest

from ffrf_fmu.model import load_model
from ffrf_fmu.runtime.body import BACKENDS
from ffrf_fmu.runtime.drives import window_share

KICK = """
[scenes.kick]
duration = 1.0
step = 0.01
rho_inf = 0.8
terms = "linear"
gravity = [0.0, 0.0, 0.0]
[scenes.kick.metrics]
kind = "momentum"
[[scenes.kick.loads]]
port = "b"
force = [0.0, 0.0, 2.0]
moment = [0.0, 0.5, 0.0]
t_start = 0.013
t_end = 0.113
"""
FREE = '[body.ports.a]\nnode = 0\ntranslation = "force"\nrotation = "force"\n[body.ports.b]\nnode = -1\n'
# steps: 10 ms and 12.5 ms land on neither end of [0.013, 0.113) but hold the length a whole number of times;
# 3 ms (2.994 ms: 334 steps in 1 s) and 7 ms (6.993 ms) land on nothing. The former rule (the load at the
# step's end, on when t_start <= t < t_end) gave 33 steps of 2.994 ms: -1.2 % of the impulse
STEPS = (0.01, 0.0125, 0.003, 0.007)


def test_window_share():
    assert window_share(1.0, 2.0, 0.5, 1.5) == pytest.approx(0.5)
    assert window_share(1.0, 2.0, 1.2, 1.4) == 1.0 and window_share(1.0, 2.0, 2.0, 2.1) == 0.0
    assert window_share(1.0, 1.05, 0.9, 1.1) == pytest.approx(0.25)  # a window inside one step
    assert window_share(0.0, 1.0, -0.1, 0.0) == 0.0  # a window from t = 0 does not act before it
    assert window_share(1.0, 2.0, 1.0, 1.0) == 1.0 and window_share(1.0, 2.0, 2.0, 2.0) == 0.0  # at an instant


@pytest.fixture
def kick(tmp_path, beam_toml):
    path = tmp_path / "kick.toml"
    path.write_text(beam_toml(KICK, superelements=1, elements=8, ports=FREE))
    return str(path)


@pytest.mark.parametrize("h", STEPS)
def test_impulse_of_a_window_standalone(kick, h):
    """A free beam (both ends free, no gravity; a moment in the window too): its linear momentum after the
    window is force x 0.1 s to round-off (measured <= 9e-16 relative)."""
    import warnings

    from ffrf_fmu.simulate import free_body_series, run_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # 3 and 7 ms do not divide 1 s: the step is reduced
        warnings.simplefilter("error", RuntimeWarning)  # the metrics of a body started at rest: no 0/0
        r = run_scene(kick, "kick", [f"step={h}"], backend="numpy")
    p = free_body_series(r, "p")
    assert np.abs(p[-1] - [0.0, 0.0, 0.2]).max() < 1e-13
    assert np.abs(p[0]).max() < 1e-15
    # started at rest: no CM-frame roll, so no tip metrics and a note naming the cause; the drifts are over
    # the run's largest momentum (the kick's: all of it is change, 1.0), not over the start's 0
    metrics = r.summary["metrics"]
    assert "no angular momentum about its CM" in metrics["tip_from_cm"] and "tip_from_cm_max_m" not in metrics
    assert metrics["linear_momentum_drift_rel"] == pytest.approx(1.0)


@pytest.mark.parametrize("h", STEPS)
def test_impulse_of_a_window_reference(kick, h):
    """The full-order beam, same scene: the same impulse to round-off (measured <= 8e-16 relative)."""
    from ffrf_fmu.reference.solver import simulate_reference

    model = load_model(kick)
    r = simulate_reference(model.body, model.scene("kick"), n_elements=8, step=h)
    assert np.abs(r.mass["p"][-1] - [0.0, 0.0, 0.2]).max() < 1e-13


def test_compiled_backend_applies_the_window_mean_as_numpy_does(tmp_path, beam_toml):
    """The compiled step evaluates the scene's schedule itself (scene_schedule): a clamped beam with a tip
    load whose window falls between steps (h = 7 ms against [0.013, 0.113)) reports the same tip force
    (the window's mean over each step) as the numpy path, and the same motion to the backends' agreement."""
    from ffrf_fmu.simulate import run_scene

    scene = KICK.replace('kind = "momentum"', 'kind = "tip_deflection"').replace('port = "b"', 'port = "tip"')
    path = tmp_path / "clamped.toml"
    path.write_text(beam_toml(scene.replace("step = 0.01", "step = 0.007").replace("duration = 1.0", "duration = 0.35"),
                              superelements=1, elements=8))
    compiled = next(b for b in BACKENDS if b != "numpy")
    a = run_scene(str(path), "kick", backend="numpy")
    b = run_scene(str(path), "kick", backend=compiled)
    fz = a.port("tip", "f")[:, 2]
    assert np.sum(fz) * 0.007 == pytest.approx(0.2, rel=1e-12)  # the impulse the inputs carry
    assert fz[2] == pytest.approx(2.0 * (0.014 - 0.013) / 0.007)  # the step (7, 14] ms: 1 ms of the window
    assert np.allclose(b.port("tip", "f")[:, 2], fz, rtol=1e-12, atol=1e-12)  # times summed alike up to round-off
    assert np.abs(b.port("tip", "r") - a.port("tip", "r")).max() < 1e-9


@pytest.mark.parametrize("H", [0.01, 0.007, 0.03])
def test_fmu_input_table_carries_the_windows_impulse(kick, H):
    """Through an FMU the value set at a communication point t_k is held over (t_k, t_k + H] (docs/fmu.md):
    fmu/run.py samples each window's mean over that step (scene_inputs(..., load_interval=(0, H))), so the
    held force integrates to force x length for any H; the standalone inputs (the mean over the step ending
    at t) carry the same impulse on their own grid."""
    from ffrf_fmu.reduction import reduce_scene_body
    from ffrf_fmu.simulate import scene_inputs

    model = load_model(kick)
    scene = model.scene("kick")
    body = reduce_scene_body(model.body, scene).data
    window_mean = scene_inputs(body, scene, load_interval=(0.0, H))
    grid = np.arange(int(round(1.0 / H)) + 1) * H
    impulse = sum(window_mean(t)["b"].f[2] * H for t in grid[:-1])
    assert impulse == pytest.approx(0.2, rel=1e-12)
    ending = scene_inputs(body, scene, load_interval=(-H, 0.0))
    assert sum(ending(t)["b"].f[2] * H for t in grid[1:]) == pytest.approx(0.2, rel=1e-12)
