"""The ports' accelerations a, dw of a run's rows (runtime/accelerations.py, accel.c) are the true
accelerations at the end of each step: physics checks on B1's spin-up (models/haug_beam.toml, 2
superelements, the gyroscopic set so that the Coriolis part of q_bar'' acts, 6 s of the 15 s spin-up).

- The hub is driven rigidly: its dw equals the drive's prescribed angular acceleration
  alpha(t) = omega/T (1 - cos(2 pi t/T)) about Z to the integrator's order (measured, h = 20/10/5 ms:
  5.3e-6, 1.3e-6, 3.3e-7 rad/s2 against a peak of 0.48: the O(h^2) of the scheme).
- Central differences of the reported velocities v, w over the run match a, dw to O(h^2): the
  difference of the two falls 4x when h halves (measured on tip.a: 2.75e-3, 6.90e-4, 1.73e-4 m/s2 against
  a peak of 12.4 m/s2). An acceleration that were the integrator's acceleration-like variable, or that
  missed a term of the kinematics (the Coriolis part, 2 W0 x d', H'), would stay O(h) or O(1) apart.
The C runtime against its numpy twin, field by field: tests/test_native_runs.py.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_scene_body

HAUG = Path(__file__).resolve().parent.parent / "models" / "haug_beam.toml"
OMEGA, T_SPIN = 4.0, 15.0  # the spinup scene's drive (haug_beam.toml)
SPAN = 6.0


def _rows(h: float):
    model = load_model(HAUG, ["superelements=2", f"step={h}", f"duration={SPAN}", "terms=gyroscopic"])
    sc = model.scene("spinup")
    body = reduce_scene_body(model.body, sc).data
    s, inputs = sim.build_system(body, sc, model.body.origin, "native")
    rows = [sim.record(s)]
    for _ in range(int(round(SPAN / h))):
        s.step(h, inputs)
        rows.append(sim.record(s))
    names = sim.column_names(body)
    return np.array(rows), (lambda port, f: [names.index(f"{port}.{f}[{i}]") for i in (1, 2, 3)])


@pytest.fixture(scope="module")
def runs():
    return {h: _rows(h) for h in (0.02, 0.01)}


def test_the_rigidly_driven_hub_has_the_drives_angular_acceleration(runs):
    errs = {}
    for h, (rows, col) in runs.items():
        t = h * np.arange(len(rows))
        alpha = OMEGA / T_SPIN * (1.0 - np.cos(2.0 * np.pi * t / T_SPIN))
        dw = rows[:, col("hub", "dw")]
        errs[h] = np.abs(dw - alpha[:, None] * [0.0, 0.0, 1.0]).max()
        assert alpha.max() > 0.45  # the comparison spans most of the drive's acceleration
    assert errs[0.01] < 2e-6 and errs[0.02] / errs[0.01] > 3.5, errs  # 5.3e-6 -> 1.3e-6: O(h^2)


@pytest.mark.parametrize("port, vel, acc", [("tip", "v", "a"), ("tip", "w", "dw"), ("hub", "w", "dw")])
def test_differences_of_the_velocities_match_the_accelerations_to_second_order(runs, port, vel, acc):
    errs, peak = {}, 0.0
    for h, (rows, col) in runs.items():
        fd = (rows[2:, col(port, vel)] - rows[:-2, col(port, vel)]) / (2.0 * h)
        skip = int(round(1.0 / h))  # past the start-up of the scheme's rates
        errs[h] = np.abs(fd[skip:] - rows[1:-1, col(port, acc)][skip:]).max()
        peak = max(peak, np.abs(rows[:, col(port, acc)]).max())
    assert peak > 0.1  # tip.a 12.4 m/s2 (centripetal), dw 0.48 rad/s2
    assert errs[0.01] < 1e-4 * peak and errs[0.02] / errs[0.01] > 3.5, (errs, peak)

