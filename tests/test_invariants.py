"""Witteveen's inertia invariants and indicators (ffrf_fmu/invariants.py, docs/inertia-terms.md).

Every invariant is an integral of polynomials of the beam interpolation that the 4-point Gauss
rule of fe.beam integrates exactly (degree <= 6), so the exact checks below hold to round-off:
1e-12 relative leaves ~1e4 eps for the sums over 8 elements and 18 modes.
"""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu import invariants as iv
from ffrf_fmu.runtime.rotation import skew
from ffrf_fmu.fe.beam import beam_model, local_frame, local_interpolation, tensor_kernel
from ffrf_fmu.model import Section, load_model
from ffrf_fmu.reduction import reduce_superelement

ROOT = Path(__file__).resolve().parent.parent
DIRECTIONS = [(1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (1.0, -2.0, 3.0)]


def unit(d):
    return np.asarray(d, dtype=float) / np.linalg.norm(d)


def segment(section, L, n_el=8, direction=(1.0, 0.0, 0.0), modes=6):
    fe = beam_model(section, (0.3, -0.2, 0.1), direction, L, n_el)
    red = reduce_superelement(fe, (0, n_el), modes, (0, 1))
    return fe, tensor_kernel(section, direction, L, n_el), red


@pytest.mark.parametrize("direction", DIRECTIONS)
def test_tensor_kernel_matches_fe_mass_and_kernel(beam, direction):
    # sum_a T_aa = M (m11 = m22 + m33 in both benchmarks) and -eps_kab T_ab = M_k: T is built from
    # the same interpolation as fe.beam, only its symmetric traceless part is new
    section, L = beam
    fe, T, _ = segment(section, L, direction=direction)
    assert np.abs(np.einsum("aaij->ij", T) - fe.M).max() < 1e-12 * np.abs(fe.M).max()
    eps = skew(np.eye(3))  # skew(e_k)[a, b] = -eps_kab
    assert np.abs(np.einsum("kab,abij->kij", eps, T) - fe.M_kernel).max() < 1e-12 * np.abs(fe.M_kernel).max()


@pytest.mark.parametrize("direction", DIRECTIONS)
def test_I0_is_the_rigid_inertia_of_a_uniform_segment(beam, direction):
    # about the CM in local axes: m11 L about the beam axis, m L^3 / 12 + m22 L (axis 2), m L^3 / 12 + m33 L
    # (axis 3); the axial mass distribution is linear in s, so the quadrature is exact
    section, L = beam
    fe, T, red = segment(section, L, direction=direction)
    inv = iv.superelement_invariants(fe, T, red)
    R = local_frame(direction)
    m, m22, m33 = section.m, section.m22, section.m33
    I0 = R @ np.diag([(m22 + m33) * L, m * L**3 / 12 + m22 * L, m * L**3 / 12 + m33 * L]) @ R.T
    assert np.abs(inv.I0 - I0).max() < 1e-12 * np.abs(I0).max()
    assert np.abs(inv.I0 - red.data.J0).max() < 1e-12 * np.abs(I0).max()
    assert inv.mass == pytest.approx(m * L, rel=1e-12) and inv.length == pytest.approx(L, rel=1e-12)


def test_modes_are_free_mass_normalized_and_contain_the_kept_vibration_modes(beam):
    # Phi = Y V: U^T M Phi = 0 is eq. (74) carried over (C0 is W3's constant part: relative to
    # sqrt|I0| x 1, the sizes of the two blocks it couples; measured 2e-13); Rayleigh-Ritz in span(Y)
    # returns the kept free-free modes exactly, their frequencies to the eigensolver's accuracy
    section, L = beam
    fe, T, red = segment(section, L)
    inv = iv.superelement_invariants(fe, T, red)
    assert np.abs(inv.Phi.T @ fe.M @ inv.Phi - np.eye(inv.Phi.shape[1])).max() < 1e-10
    assert np.abs(inv.C0).max() < 1e-10 * math.sqrt(np.linalg.norm(inv.I0, 2))
    assert inv.n_vibration == 6
    assert inv.omega[:6] / (2 * np.pi) == pytest.approx(red.data.frequencies_hz, rel=1e-9)


def section_points(section, L, n_el, direction):
    """Brute-force quadrature: 4 section points per Gauss point with the section's mass and second
    moments (y2 = +-sqrt(2 m33 / m), y3 = +-sqrt(2 m22 / m), m/4 each), positions and interpolation."""
    R = local_frame(direction)
    Le = np.full(n_el, L / n_el)
    Nc, Nt, _ = local_interpolation(section, Le)
    xg, wg = np.polynomial.legendre.leggauss(Nc.shape[1])
    Tq = np.kron(np.eye(4), R.T)
    Nc = np.einsum("ij,egjk,kl->egil", R, Nc, Tq)
    Nt = np.einsum("ij,egjk,kl->egil", R, Nt, Tq)
    s = (np.arange(n_el)[:, None] + 0.5 * (xg + 1.0)[None]) * L / n_el  # (n_el, ng)
    d2, d3 = math.sqrt(2 * section.m33 / section.m), math.sqrt(2 * section.m22 / section.m)
    Y = np.array([[0, d2, 0], [0, -d2, 0], [0, 0, d3], [0, 0, -d3]]) @ R.T  # (4, 3) model axes
    X = s[..., None, None] * R[:, 0] + Y  # (n_el, ng, 4, 3) from node 0
    w = np.broadcast_to((0.5 * wg * L / n_el * section.m / 4)[None, :, None], X.shape[:3])
    # displacement of point p: Nc q + theta x y = Nc q - skew(y) Nt q, dofs of elements e: 6e .. 6e + 11
    N = Nc[:, :, None] - np.einsum("pab,egbk->egpak", skew(Y), Nt)  # (n_el, ng, 4, 3, 12)
    return X, w, N


def test_deformed_inertia_is_exact_for_an_arbitrary_deformation(b1):
    # I0 + W1 q + q^T W2 q against a direct quadrature of int (X + u)~^T (X + u)~ rho over section
    # points: independent of the kernels M_k, T (only the interpolation is shared); every mode at
    # ~3x its characteristic amplitude, so that W1 q and q^T W2 q are far above round-off
    section, L = b1
    fe, T, red = segment(section, L)
    inv = iv.superelement_invariants(fe, T, red)
    q = np.random.default_rng(0).normal(size=inv.Phi.shape[1]) * inv.amplitude * 3
    X, w, N = section_points(section, L, 8, (1.0, 0.0, 0.0))
    X = X + fe.coords[0] - red.data.x_cm
    ue = (inv.Phi @ q)[(6 * np.arange(8)[:, None] + np.arange(12))]  # (n_el, 12)
    x = X + np.einsum("egpak,ek->egpa", N, ue)
    S = skew(x)
    I = np.einsum("egp,egpba,egpbc->ac", w, S, S)
    assert np.abs(inv.inertia(q) - I).max() < 1e-12 * np.abs(I).max()
    assert np.abs(inv.inertia(q) - inv.I0).max() > 1e-3 * np.abs(I).max()  # the test is not vacuous


def test_W1_of_rigid_rotations_rotates_I0(beam):
    # a small rigid rotation eps changes the inertia by eps~ I0 - I0 eps~ (I = R I0 R^T): checks the
    # sign and the section part of the kernel formula W1_j = C_j + C_j^T, C_j[:, k] = U_r^T M_k Phi_j
    section, L = beam
    fe, T, red = segment(section, L, direction=(1.0, -2.0, 3.0))
    inv = iv.modal_invariants(fe, T, red.U, red.U[:, 3:])
    eps = np.array([0.3, -0.7, 0.5])
    E = skew(eps)
    assert np.abs(np.einsum("j,jab->ab", eps, inv.W1) - (E @ inv.I0 - inv.I0 @ E)).max() < 1e-12 * np.abs(inv.I0).max()


def test_uniform_stretch_mode_by_hand(beam):
    # Phi = (x - x_cm) e_x / c, c = sqrt(m L^3 / 12): mass-normalized, free (orthogonal to all rigid
    # modes). By hand, I1 = int 2 (X.u) I - u X^T - X u^T rho = diag(0, 2c, 2c) (the section terms
    # int rho y u_x vanish), so W1 has no component about the beam axis and no product of inertia;
    # centrifugal load at w about Z: f0 = -int Phi^T w~ w~ X rho = w^2 int m x^2 / c = w^2 c, and 0
    # about the beam axis X (w x (w x X) is then normal to e_x). Linear fields: exact quadrature.
    section, L = beam
    fe, T, red = segment(section, L)
    c = math.sqrt(section.m * L**3 / 12)
    Phi = np.zeros((fe.n_dof, 1))
    Phi[0::6, 0] = (fe.coords[:, 0] - red.data.x_cm[0]) / c
    inv = iv.modal_invariants(fe, T, red.U, Phi)
    assert (Phi.T @ fe.M @ Phi)[0, 0] == pytest.approx(1.0, rel=1e-12)
    assert np.abs(inv.C0).max() < 1e-12 * c
    assert np.abs(inv.W1[0] - np.diag([0.0, 2 * c, 2 * c])).max() < 1e-12 * c
    w = 4.0
    assert inv.centrifugal([0.0, 0.0, w])[0][0] == pytest.approx(w**2 * c, rel=1e-12)
    assert abs(inv.centrifugal([w, 0.0, 0.0])[0][0]) < 1e-12 * w**2 * c
    # and the q part: Kc = w^2 (1 - int rho (n.Phi)^2) = w^2 for a stretch normal to the spin axis
    assert inv.centrifugal([0.0, 0.0, w])[1][0, 0] == pytest.approx(w**2, rel=1e-12)


def test_centrifugal_widening_of_a_spun_free_bar(b1):
    # a free-free bar spun at w about a normal axis through its CM elongates by m w^2 L^3 / (12 EA)
    # (N(x) = m w^2 (L^2/4 - x^2) / 2), each end moving half of it. Exact to round-off (measured
    # 4e-16): linear axial elements are nodally exact for a bar under a consistent load, and the
    # Ritz solution in span(Y) has exact boundary displacements, because its error is K-orthogonal
    # to the attachment modes, whose loads are (inertia-relieved) unit boundary loads
    section, L = b1
    fe, T, red = segment(section, L)
    w = 4.0
    out = iv.indicators(iv.superelement_invariants(fe, T, red), w, (0.0, 0.0, 1.0))
    assert out["widening"] * L == pytest.approx(section.m * w**2 * L**3 / (24 * section.EA), rel=1e-10)


def test_B1_spin_indicators_with_one_superelement():
    # B1 at 4 rad/s about Z, one 8 m superelement: the in-plane bending modes are normal to the spin
    # axis, so Kc = w^2 on them and the softening indicator is exactly (w / w_1)^2 (to round-off
    # of the eigensolver). w_1 is computed (the free-free first bending frequency of the FE model)
    # and checked against the Euler-Bernoulli closed form 4.7300^2 sqrt(EI / (m L^4)) = 18.5507 rad/s:
    # shear and rotary inertia lower it by ~(beta r / L)^2 (1 + EA/GA) ~ 1e-4, the 8-element mesh
    # raises it (measured +1.0e-5 net); 2e-4 bound.
    model = load_model(ROOT / "models" / "haug_beam.toml", ["superelements=1"])
    rate, axis, source = iv.scene_spin(model.scene("spinup"))
    assert rate == pytest.approx(4.0, rel=1e-12) and np.allclose(axis, [0, 0, 1]) and "hub" in source
    (inv,) = iv.body_invariants(model.body)
    sec = model.body.section
    w1 = inv.omega[0]
    assert w1 == pytest.approx(4.730040745**2 * math.sqrt(sec.EI3 / (sec.m * 8.0**4)), rel=2e-4)
    out = iv.indicators(inv, rate, axis)
    assert out["softening"] == pytest.approx((rate / w1) ** 2, rel=1e-9)
    assert out["spin_over_omega1"] == pytest.approx(rate / w1, rel=1e-12)
    # the `gyroscopic` term set softens by G^T G = Phi^T (w x .)^T P_Y (w x .) Phi, P_Y the M-projector
    # on the basis: never more than Kc (Bessel), here nearly all of it (measured 0.993)
    assert 0.9 * out["softening"] < out["softening_gyroscopic_set"] <= out["softening"] * (1 + 1e-10)
    # Coriolis: 2 w |G(n) Omega^-1| <= 2 w / w_1 (|G(n)| <= 1 for mass-normalized modes); G(e_z) maps
    # the in-plane bending mode to an axial field the reduced basis nearly spans (measured 0.996)
    assert 0.9 * 2 * rate / w1 < out["coriolis"] <= 2 * rate / w1 * (1 + 1e-12)


def test_scene_spin_sources():
    haug = load_model(ROOT / "models" / "haug_beam.toml")
    assert iv.scene_spin(haug.scene("spinup_fast"))[0] == pytest.approx(8.0, rel=1e-12)
    assert iv.scene_spin(haug.scene("hub_free")) == (None, None, "none")
    free = load_model(ROOT / "models" / "free_beam.toml")
    rate, axis, source = iv.scene_spin(free.scene("tumble"))
    assert rate == pytest.approx(np.linalg.norm([0.3, 0.5, 2.0])) and source == "initial angular_velocity"


def test_report_and_cli():
    model = load_model(ROOT / "models" / "haug_beam.toml")
    report = iv.body_inertia_report(model.body, 4.0, (0.0, 0.0, 1.0), first_frequency_hz=0.464)
    json.dumps(report)  # JSON-able
    assert len(report["superelements"]) == 4 and report["connected"]
    # hub rotation prescribed: deformed inertia and coupling not needed (his I-II); 4 rad/s is above the
    # first (cantilever) frequency 2.92 rad/s: Coriolis needed (his IV)
    assert report["needed"]["coriolis"] and not report["needed"]["deformed_inertia"]
    out = subprocess.run([sys.executable, "-m", "ffrf_fmu", "info", "models/free_beam.toml", "--json"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    inertia = json.loads(out.stdout)["inertia"]
    assert inertia["spin_source"] == "initial angular_velocity" and not inertia["connected"]
    assert inertia["needed"]["deformed_inertia"] and inertia["needed"]["inertia_coupling"]  # free beam: his III


def test_witteveen_beam_row_of_tables_2_and_3():
    # His "Beam": 750 x 20 x 20 mm, 1.8 kg, in t and mm (his units). The invariants depend on the mass
    # distribution and the mode shapes, not on the material (steel assumed for the modes). Published:
    # |I0| 85.7; max |W1| 18.4; max |W2| 1.0, |W2| 2.0; max |W3| 1.0, |W3| 1.4. Ours (6 modes):
    # |I0| = m (L^2 + h^2) / 12 = 84.4 (his 85.7 is 1.5 % above: the mass is printed rounded to 1.8 kg);
    # max |W1| = 2 sqrt(m L^3 / 12) from the uniform-stretch shape = 18.37; max |W2| = 1 (a
    # mass-normalized mode's own block), |W2| = 1.99, max |W3| = 0.997, |W3| = 1.41 (spectral norms of
    # W2 as 3n x 3n and W3 as 3n x n). Bounds: his printed digits. His norm of W1 (9.2) is not
    # reproduced: it is below his max entry in every row of Table 2, which no norm of the same
    # matrix can be (docs/inertia-terms.md).
    E, G, b, L = 2.1e5, 8.08e4, 20.0, 750.0
    A, I = b * b, b**4 / 12
    rho = 1.8e-3 / (A * L)
    sec = Section(EA=E * A, GJ=G * 0.1406 * b**4, EI2=E * I, EI3=E * I, m=rho * A, m22=rho * I, m33=rho * I,
                  GA2=G * A * 5 / 6, GA3=G * A * 5 / 6)
    fe, T, red = segment(sec, L)
    table = iv.indicators(iv.superelement_invariants(fe, T, red))["table"]
    assert table["I0_norm"] == pytest.approx(85.7, rel=2e-2)
    assert table["W1_max"] == pytest.approx(18.4, abs=0.05)
    assert table["W2_max"] == pytest.approx(1.0, abs=0.05) and table["W2_norm"] == pytest.approx(2.0, abs=0.05)
    assert table["W3_max"] == pytest.approx(1.0, abs=0.05) and table["W3_norm"] == pytest.approx(1.4, abs=0.05)
