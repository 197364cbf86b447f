"""The conrod in a crank drive (models/conrod_crank.toml, ffrf_fmu/examples/crank_drive.py; docs/inertia-terms.md,
"The conrod in a crank drive"): the drive's frequencies against the excitation, the monolithic run against the
rigid slider-crank, and the SSP system of the conrod, crank and piston FMUs under our master, libcosim and ecos
against the monolithic run. A short run: the crank's run-up (one revolution in 2.5 ms) and two revolutions at
5000 rad/s with two firings, 5 ms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ffrf_fmu.examples import crank_drive as cd
from ffrf_fmu.examples.crank_monolithic import monolithic
from ffrf_fmu.master.ssp import write_ssp

DRIVE = cd.CrankDrive()
DURATION = 5e-3
H = 1e-5


@pytest.fixture(scope="module")
def body():
    return cd.reduced_body()


@pytest.fixture(scope="module")
def fmus(body, tmp_path_factory):
    return cd.build(tmp_path_factory.mktemp("crank_fmus"), body=body)


@pytest.fixture(scope="module")
def mono(body):
    return {h: monolithic(DRIVE, h, DURATION, body=body) for h in (H, 2 * H)}


@pytest.fixture(scope="module")
def runs(fmus, tmp_path_factory):
    """engine -> run at H; "master@2H": our master at 2 H."""
    d = tmp_path_factory.mktemp("crank_ssp")
    pkg = write_ssp(d / "crank.ssp", cd.system(fmus, DRIVE, H, DURATION))
    out = {e: cd.run_package(pkg, e) for e in ("master", "libcosim", "ecos")}
    out["master@2H"] = cd.run_package(write_ssp(d / "crank_2H.ssp", cd.system(fmus, DRIVE, 2 * H, DURATION)), "master")
    return out


def test_first_frequency_within_a_factor_3_of_the_crank(body):
    """The excitation is the crank's rotation, 5000 rad/s = 795.8 Hz (and its harmonics). The conrod's first
    free-free frequency (2364.35 Hz, tests/test_conrod.py) and its first elastic mode in the drive (big eye on
    the crank pin, small eye on the pin spring and the piston: in-plane bending, mid-shank along Z) are both
    within a factor 3 of it. The drive's lowest mode is the roll about the conrod's axis on the pin's
    100 N m/rad (mid-shank still, no piston motion; the planar drive does not excite it); the piston mode
    (piston and mid-shank along Y) is the axial one the coupling carries."""
    f_crank = DRIVE.omega / (2 * math.pi)
    assert body.superelements[0].frequencies_hz[0] / f_crank < 3.0
    modes = cd.drive_modes(body, DRIVE)
    roll, bend = modes[0], modes[1]
    assert max(map(abs, roll.mid_shank)) < 1e-3 and abs(roll.piston) < 1e-3
    assert abs(bend.mid_shank[2]) > 10 * max(abs(bend.mid_shank[0]), abs(bend.mid_shank[1]))
    assert 1.0 < bend.frequency_hz / f_crank < 3.0
    axial = next(m for m in modes if abs(m.piston) > 0.5)
    assert abs(axial.mid_shank[1]) > 10 * max(abs(axial.mid_shank[0]), abs(axial.mid_shank[2]))


def test_monolithic_follows_the_slider_crank(mono):
    """The piston of the monolithic run against the rigid slider-crank x(theta) = r cos theta +
    sqrt(L^2 - r^2 sin^2 theta) - r - L: they differ by the elastic shortening of the drive, the pin spring's
    f / k plus the conrod's own between the eyes (about twice the big-eye-to-mid-shank stretch `axial`, the
    shank being uniform and the eyes stiff) and nothing else: between 0.5 and 1.5 times the sum of their peaks
    (measured 0.75 mm against 0.80 mm, 0.94). The crank's inertia loads bend the rod most (bending peak 9.6
    times the axial one)."""
    r = mono[H]
    assert not r.stopped
    th = r.angle
    rigid = DRIVE.r * np.cos(th) + np.sqrt(cd.L_EYES**2 - (DRIVE.r * np.sin(th)) ** 2) - DRIVE.r - cd.L_EYES
    elastic = np.abs(r.pin_force).max() / 1e8 + 2 * np.abs(r.axial).max()  # k of models/conrod_crank.toml
    assert np.abs(rigid).max() > 0.9 * 2 * DRIVE.r  # the stroke is run (cos theta passes -1)
    assert 0.5 * elastic < np.abs(r.piston - rigid).max() < 1.5 * elastic
    assert np.abs(r.bending).max() > 3 * np.abs(r.axial).max() > 0  # the crank's inertia loads bend it most


def test_engines_agree_to_round_off(runs):
    """Our master, libcosim and ecos all run Jacobi with held inputs on the same package, so they agree to
    round-off (docs/cosim.md: 1e-9 of the peaks, as tests/test_ssp.py)."""
    ref = runs["master"]
    assert not ref.stopped and len(ref.t) == round(DURATION / H)
    for e in ("libcosim", "ecos"):
        r = runs[e]
        assert np.allclose(r.t, ref.t, rtol=0, atol=1e-12)
        for name in ("axial", "bending"):
            x, y = getattr(r, name), getattr(ref, name)
            assert np.abs(x - y).max() < 1e-9 * np.abs(y).max(), (e, name)


def test_cosimulation_against_the_monolithic_run(runs, mono, body):
    """Every engine against the monolithic run at the same step. The coupling's error is the piston's spring
    force held over H, a delay of H/2 on average: on a response of angular frequency w a phase error w H / 2,
    first order in H (docs/cosim.md). The fastest response the coupling carries is the drive's axial (piston)
    mode, so the bound is w_ax H / 2 (0.104 at 3311 Hz and H = 1e-5), on both outputs; and halving H must
    reduce the error at least as first order does, with a margin (factor 0.6 instead of 0.5). Measured over
    these 5 ms: 3.3e-2 axial, 5.1e-3 bending at 1e-5 s; 8.6e-2, 1.4e-2 at 2e-5 s (ratios 0.38, 0.36)."""
    w_ax = 2 * math.pi * next(m for m in cd.drive_modes(body, DRIVE) if abs(m.piston) > 0.5).frequency_hz
    bound = w_ax * H / 2
    e1 = cd.deviation(runs["master"], mono[H])
    for e in ("master", "libcosim", "ecos"):
        d = cd.deviation(runs[e], mono[H])
        assert d.axial < bound and d.bending < bound, (e, d)
    e2 = cd.deviation(runs["master@2H"], mono[2 * H])
    assert e1.axial < 0.6 * e2.axial and e1.bending < 0.6 * e2.bending, (e1, e2)


def test_partner_laws_are_the_runtime_run_up():
    """The crank's and the piston's copies of the crank angle (each slave script imports only the standard
    library) are the runtime's Wu-Haug law (runtime/drives.py `haug_spinup`) to round-off, with its rate and
    acceleration, so the gas force fires at the crank's top dead centres; the pin's acceleration is the
    second derivative of its position (central differences, step 1e-8 s: truncation r w^4 h^2 / 12 ~ 1e-4 m/s^2
    and round-off ~ 1e-18 m / h^2 ~ 1e-2 m/s^2, against the bound 1e-3 r w^2 = 250 m/s^2)."""
    from ffrf_fmu.runtime.drives import evaluate

    crank, piston = cd._laws()
    for t in np.linspace(0.0, 6e-3, 61):
        ref = evaluate("haug_spinup", {"omega": DRIVE.omega, "T": DRIVE.T}, t)
        assert np.allclose(crank.crank_motion(t, DRIVE.omega, DRIVE.T), ref, rtol=1e-12, atol=1e-12 * DRIVE.omega / DRIVE.T)
        assert piston.crank_angle(t, DRIVE.omega, DRIVE.T) == pytest.approx(ref[0], rel=1e-12, abs=1e-12)
        h = 1e-8
        r_m, r_0, r_p = (np.array(crank.pin_motion(s, DRIVE.r, DRIVE.omega, DRIVE.T)[0]) for s in (t - h, t, t + h))
        a = np.array(crank.pin_motion(t, DRIVE.r, DRIVE.omega, DRIVE.T)[2])
        if t > h:
            assert np.allclose((r_p - 2 * r_0 + r_m) / h**2, a, rtol=0, atol=1e-3 * DRIVE.r * DRIVE.omega**2)
    # the gas force: zero through the run-up, then a pulse after each TDC (peak F_max at 30 deg)
    t_fire = (2 * math.pi + DRIVE.omega * DRIVE.T / 2) / DRIVE.omega  # theta = 2 pi after the run-up
    assert piston.gas_force(0.5 * DRIVE.T, DRIVE.omega, DRIVE.T, DRIVE.F_max, DRIVE.width) == 0.0
    peak = piston.gas_force(t_fire + DRIVE.width / 2 / DRIVE.omega, DRIVE.omega, DRIVE.T, DRIVE.F_max, DRIVE.width)
    assert peak == pytest.approx(DRIVE.F_max, rel=1e-9)
