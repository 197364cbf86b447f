"""The `bump` time function (runtime/drives.py; its C twin in runtime/native/advance.c): value
sin^4(pi tau) over [t_start, t_start + duration), a road bump smooth to its acceleration."""
import math
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.runtime.drives import evaluate

MODELS = Path(__file__).resolve().parents[1] / "models"
P = {"value": 0.02, "t_start": 0.1, "duration": 0.2}


def test_bump_values_and_derivatives():
    """Peak `value` at the middle, 0 outside; s' and s'' against central differences of s and s' (h = 1e-6:
    truncation 1e-12 of the peak rates, bound 1e-6 relative); s, s', s'' continuous at both ends (their
    limits from inside are 0 to 1e-9 of the peaks: sin^4 has a double zero of s'' there)."""
    assert evaluate("bump", P, 0.2)[0] == pytest.approx(0.02, rel=1e-15)
    assert evaluate("bump", P, 0.0999) == (0.0, 0.0, 0.0) and evaluate("bump", P, 0.3001) == (0.0, 0.0, 0.0)
    h = 1e-6
    peak_v, peak_a = 4 * 0.02 * math.pi / 0.2, 4 * 0.02 * (math.pi / 0.2) ** 2
    for t in np.linspace(0.1 + 2 * h, 0.3 - 2 * h, 37):
        s, ds, dds = evaluate("bump", P, t)
        fd1 = (evaluate("bump", P, t + h)[0] - evaluate("bump", P, t - h)[0]) / (2 * h)
        fd2 = (evaluate("bump", P, t + h)[1] - evaluate("bump", P, t - h)[1]) / (2 * h)
        assert abs(ds - fd1) < 1e-6 * peak_v and abs(dds - fd2) < 1e-6 * peak_a
    for t in (0.1 + 1e-7, 0.3 - 1e-7):
        s, ds, dds = evaluate("bump", P, t)
        assert abs(s) < 1e-9 * 0.02 and abs(ds) < 1e-9 * peak_v and abs(dds) < 1e-9 * peak_a


def test_bump_drive_native_equals_numpy(tmp_path):
    """A hub rotation driven by a bump (1 rad over 2 s) on B1: the C runtime's twin of the time function
    gives the numpy run's tip deflection to 1e-8 (both Newton-converged to 1e-10)."""
    from ffrf_fmu.model import load_model
    from ffrf_fmu.simulate import run_scene

    text = (MODELS / "haug_beam.toml").read_text().replace(
        'angle = { kind = "haug_spinup", omega = 4.0, T = 15.0 }',
        'angle = { kind = "bump", value = 1.0, t_start = 0.5, duration = 2.0 }', 1)
    f = tmp_path / "bump.toml"
    f.write_text(text)
    short = ["duration=3", "step=0.02", "superelements=1"]
    assert 'kind = "bump"' in text

    a = run_scene(load_model(f, short), "spinup", backend="native").summary["metrics"]["tip_deflection_max_m"]
    b = run_scene(load_model(f, short), "spinup", backend="numpy").summary["metrics"]["tip_deflection_max_m"]
    assert a > 1e-4 and a == pytest.approx(b, rel=1e-8)
