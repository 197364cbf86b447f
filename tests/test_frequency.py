"""simulate/frequency.py: the dominant frequency (least-squares sinusoid with a linear trend) by a grid
of factored sums or chirp z-transforms and the zero of the misfit's derivative, against an analytic
sinusoid, the sums they stand for and the estimator it replaced (golden-section search of numpy lstsq
fits, kept here as the oracle) on a real run."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.simulate import frequency as fr

ROOT = Path(__file__).resolve().parents[1]

# The previous estimator's bracket (Hz): it returned the middle of a golden-section bracket this wide
# around the least misfit, so it lies within half of it of the minimum; the new one within half of
# fr.FREQUENCY_XTOL (1e-9 Hz). Two estimates of the same minimum then agree within OLD_XTOL.
OLD_XTOL = 1e-6


def previous_estimator(t, y, f_min, f_max):
    """The estimator before simulate/frequency.py (simulate/quantities.py up to 2026-12): the misfit of
    the fit [sin, cos, 1, t - t0] on 400 grid frequencies by batched normal equations, then a
    golden-section search of numpy lstsq fits in the bracket of the grid's best to OLD_XTOL."""
    tau = t - t[0]

    def misfit(f):
        w = 2 * np.pi * f
        A = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t), tau])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        return float(np.sum((A @ coef - y) ** 2))

    grid = np.linspace(f_min, f_max, 400)
    w = 2 * np.pi * grid[:, None]
    shape = (grid.size, t.size)
    cols = (np.sin(w * t), np.cos(w * t), np.broadcast_to(np.ones_like(t), shape), np.broadcast_to(tau, shape))
    dot = lambda u, v: np.einsum("gn,gn->g", u, np.broadcast_to(v, shape))  # noqa: E731
    AtA = np.stack([np.stack([dot(u, v) for v in cols], -1) for u in cols], -2)
    Aty = np.stack([dot(u, y) for u in cols], -1)
    coef = np.linalg.solve(AtA, Aty[..., None])[..., 0]
    i = int(np.argmax(np.einsum("gi,gi->g", coef, Aty)))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    g = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = misfit(a), misfit(b)
    while hi - lo > OLD_XTOL:
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = misfit(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = misfit(b)
    return float(0.5 * (lo + hi))


def window(h):
    """B1's window after the spin-up: 15 s to 20 s at the step h (simulate.metrics, band [0.1, 2] Hz)."""
    return 15.0 + h * np.arange(int(round(5.0 / h)) + 1)


@pytest.mark.parametrize("h", [0.04, 0.002])
@pytest.mark.parametrize("uneven", [False, True])
def test_analytic_sinusoid_with_trend(h, uneven):
    """y = A sin(2 pi f0 t + phi) + c + d t is fit exactly at f0 (zero misfit), so the estimate is f0
    to the refinement's bracket (half of FREQUENCY_XTOL = 5e-10 Hz) and the round-off of the zero of
    r' (about 1e-16 |y| / (A T) rad/s, far below): 1e-9 Hz. Uneven samples (each moved by up to 20 % of
    h) take the path of explicit sums and must give the same."""
    t = window(h)
    if uneven:
        t = t + np.random.default_rng(3).uniform(-0.2, 0.2, t.size) * h
    f0 = 0.5292
    y = 0.31 * np.sin(2 * np.pi * f0 * t + 0.7) + 0.02 - 0.004 * t
    assert abs(fr.dominant_frequency(t, y, 0.1, 2.0) - f0) < 1e-9


@pytest.mark.parametrize("sums", [fr.chirp_z_pair, fr.grid_sums])
@pytest.mark.parametrize("m", [57, 400, 401])
def test_grid_sums_are_the_sums(sums, m):
    """The chirp z-transform and the factored sums (grid_sums; m a square, one more, neither) of rows x
    against sum_n x_n exp(i a_k n) and sum_n exp(2 i a_k n) summed term by term: FFT round-off is about
    eps log2(size) of the largest term sum, the factored sums' eps sqrt(N) (the exponentials' angles
    rounded apart, a0 + q p da), 1e-12 of it is far above both."""
    x = np.random.default_rng(1).normal(size=(3, 301))
    n, a = np.arange(301), 0.013 + 0.0021 * np.arange(m)
    direct = x @ np.exp(1j * np.outer(n, a))
    direct2 = np.exp(2j * np.outer(a, n)).sum(axis=1)
    s1, s2 = sums(x, 0.013, 0.0021, m)
    assert s1.shape == direct.shape and s2.shape == direct2.shape
    assert np.max(np.abs(s1 - direct)) < 1e-12 * np.max(np.abs(direct))
    assert np.max(np.abs(s2 - direct2)) < 1e-12 * np.max(np.abs(direct2))


def test_both_routes_pick_the_same_grid_point(monkeypatch):
    """B1's window at 40 ms (126 samples, the factored sums) and at 2 ms (2501, the chirp z-transform):
    each route's grid scores agree to round-off with the other's and have their maximum at the same
    frequency, so the refined estimate (from that point's bracket only) is bit for bit the same."""
    for h in (0.04, 0.002):
        t = window(h)
        y = 0.3 * np.sin(2 * np.pi * 0.53 * t) + 0.1 * np.sin(2 * np.pi * 1.37 * t + 1) + 0.002 * t
        fit, grid = fr.TrendFit(t, y), np.linspace(0.1, 2.0, fr.GRID)
        scores = {}
        for limit in (0, 10**6):  # every sample count by chirp z, then every one by the sums
            monkeypatch.setattr(fr, "DIRECT_SUMS_MAX", limit)
            scores[limit] = fit.grid_scores(grid)
        assert np.max(np.abs(scores[0] - scores[10**6])) < 1e-9 * np.max(np.abs(scores[0]))
        assert np.argmax(scores[0]) == np.argmax(scores[10**6])


@pytest.mark.parametrize("h", [0.04, 0.002])
def test_two_modes_with_noise_against_the_previous_estimator(h):
    """A second mode, a trend and noise: the misfit's minimum is no longer the first mode's frequency,
    but both estimators look for the same minimum from the same grid, so they agree within OLD_XTOL;
    also where the minimum lies on the band's edge (a mode below the band, searched from 0.6 Hz)."""
    t = window(h)
    rng = np.random.default_rng(2)
    y = 0.3 * np.sin(2 * np.pi * 0.53 * t) + 0.1 * np.sin(2 * np.pi * 1.37 * t + 1) + 0.05 * rng.normal(size=t.size) \
        + 0.002 * t
    for band in ((0.1, 2.0), (0.6, 2.0)):
        assert abs(fr.dominant_frequency(t, y, *band) - previous_estimator(t, y, *band)) < OLD_XTOL


def test_b1_run_against_the_previous_estimator():
    """B1 (models/haug_beam.toml) 1 SE x 2 modes, stiffened, h = 40 ms: the tip's in-plane vibration
    after the spin-up, the series of the run's oscillation_frequency_hz, by both estimators within
    OLD_XTOL; the metric is the new estimator's."""
    from ffrf_fmu import simulate as sim

    r = sim.run_scene(str(ROOT / "models" / "haug_beam.toml"), "spinup",
                      ["superelements=1", "modes=2", "stiffening=true", "step=0.04"])
    hub, tip = sim.end_ports(r.body)
    d = sim.elastic_tip(r, hub, tip)
    after = r.t > 15.0
    f_old = previous_estimator(r.t[after], d[after, 1], 0.1, 2.0)
    f_new = fr.dominant_frequency(r.t[after], d[after, 1], 0.1, 2.0)
    assert abs(f_new - f_old) < OLD_XTOL
    assert r.summary["metrics"]["oscillation_frequency_hz"] == pytest.approx(f_new, abs=1e-12)
    assert r.summary["metrics"]["in_plane_frequency_hz"] == r.summary["metrics"]["oscillation_frequency_hz"]


@pytest.mark.parametrize("t, y, band, why", [
    (np.arange(4.0), np.zeros(4), (0.1, 1.0), "length >= 5"),
    (np.arange(10.0), np.zeros(9), (0.1, 1.0), "length >= 5"),
    (np.ones(10), np.zeros(10), (0.1, 1.0), "span no time"),
    (np.arange(10.0), np.zeros(10), (0.0, 1.0), "0 < f_min < f_max"),
    (np.arange(10.0), np.zeros(10), (1.0, 0.5), "0 < f_min < f_max"),
])
def test_bad_input_is_refused(t, y, band, why):
    with pytest.raises(ValueError, match=why):
        fr.dominant_frequency(t, y, *band)


def test_few_samples_do_not_import_numpy_fft():
    """Up to DIRECT_SUMS_MAX evenly spaced samples the grid takes the factored sums, and numpy.fft (about
    0.9 ms of a fresh process) is not imported: B1's window at 40 ms (126 samples) in a fresh process;
    at 2 ms (2501) the chirp z-transform imports it (the check sees an import)."""
    import os
    import subprocess
    import sys

    code = ("import sys\nimport numpy as np\nfrom ffrf_fmu.simulate import frequency as fr\n"
            "for h in (0.04, 0.002):\n"
            "    t = 15.0 + h * np.arange(int(round(5.0 / h)) + 1)\n"
            "    fr.dominant_frequency(t, np.sin(2 * np.pi * 0.53 * t), 0.1, 2.0)\n"
            "    print('numpy.fft' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.stdout.split() == ["False", "True"], done.stderr
