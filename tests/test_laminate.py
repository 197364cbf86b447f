"""Laminated shells from Nastran PCOMP decks (classical laminate theory in solid/shell_section.py,
MITC4 through solid/nastran_continuum.py; docs/shells.md, "Laminates"): a simply supported cross-ply
plate against the exact Navier frequencies, an unsymmetric mixed MAT8/MAT1 laminate against
CalculiX's composite S8R, the material axis (THETA, MCID), LAM = SYM, the laminate's mass and
inertia, and the refusals named by file and line."""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.reduction_sparse import mass_properties
from ffrf_fmu.solid.laminate_plate import navier_clt, navier_fsdt, navier_table, plate_deck
from ffrf_fmu.solid.nastran import NastranError, read_nastran
from ffrf_fmu.solid.nastran_body import nastran_body
from ffrf_fmu.solid.shell import plate_mesh
from ffrf_fmu.solid.shell_calculix import run_calculix

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from laminate_plate import MAT1, MAT8, PLY, cross_ply, deck_omegas, mixed  # noqa: E402


def _write(tmp_path, text, name="plate.bdf"):
    (tmp_path / name).write_text(text)
    return tmp_path / name


@pytest.mark.parametrize("aoh", [100, 1000])
def test_cross_ply_simply_supported_against_navier(aoh):
    """[0/90]s (LAM = SYM, MAT8 graphite-epoxy, E1/E2 = 17.6, E1/G2z = 63), square, hard simple
    support: the Richardson extrapolation of 16 x 16 and 32 x 32 MITC4 (O(h^2); the meshes converge
    from above) against the exact Navier frequencies, modes 1-6. Measured (benchmarks/laminate_plate.py
    navier): within 3.5e-4 of first-order shear deformation (FSDT, the element's theory) at both
    thickness ratios; the remainder is the O(h^4) left after extrapolation (8/16 -> 16/32 shrinks it
    about 13 times on mode 4). Bound 1e-3 against FSDT. Against classical laminate theory
    (Kirchhoff): FSDT is below CLT by 1.6e-5 .. 7.4e-5 at a/h = 1000 (the bound 1e-3 holds for CLT
    too) and by 1.6e-3 .. 6.4e-3 at a/h = 100, where a shear-rigid section would fail the FSDT bound
    (asserted: the test can tell)."""
    a, h = 1.0, 1.0 / aoh
    pcomp, lam = cross_ply(h)
    sec = lam.section()
    fsdt, clt = navier_table(sec, a, a, 6, navier_fsdt), navier_table(sec, a, a, 6, navier_clt)
    w = {n: deck_omegas(plate_deck(a, a, n, n, pcomp, [MAT8], spc="hard"), 6, free=False) for n in (16, 32)}
    assert np.all(w[16] > w[32]) and np.all(w[32] > fsdt)
    rich = (4 * w[32] - w[16]) / 3
    assert np.abs(rich / fsdt - 1).max() < 1e-3, rich / fsdt - 1
    if aoh == 1000:
        assert np.abs(rich / clt - 1).max() < 1e-3, rich / clt - 1
    else:
        assert np.abs(fsdt / clt - 1).max() > 3e-3


def test_unsymmetric_mixed_laminate_against_calculix_s8r():
    """[0 MAT8 (0.4 h) / aluminium MAT1 (0.2 h) / 45 MAT8 (0.4 h)] from Z0 = -h/2 (B != 0, D16 != 0),
    1 x 0.75 m, a/h = 100, free-free, first 10 elastic frequencies: the Richardson extrapolation of
    MITC4 on 16 x 12 and 32 x 24 against ccx's composite S8R (C3D20R bricks through the thickness)
    on the 16 x 12 cells. Measured: within -0.03 .. +0.29 % (benchmarks/laminate_plate.py ccx); the
    parts of it: MITC4's extrapolation remainder (16/32 against 32/64: up to 0.13 %), ccx's E3, nu13,
    nu23, which the plate theory does not have (E3 = 2 E2 moves ccx by 0.01-0.06 %), and ccx's own
    discretization (8 x 6 -> 16 x 12 moves S8R by 0.01-1.3 %; 16 x 13 -> 24 x 19 on a 1 x 0.8 plate by
    < 0.05 %). Bound
    0.5 %. Raw 16 x 12 MITC4 is 0.5-3.7 % above S8R (its O(h^2) error, larger for the laminate's
    short waves across the stiff fibre). Fails if `ccx` is not on PATH (as tests/test_shells.py)."""
    a, b, h = 1.0, 0.75, 0.01
    pcomp, lam = mixed(h)
    f = {n: deck_omegas(plate_deck(a, b, n, 3 * n // 4, pcomp, [MAT8, MAT1]), 10, free=True) / (2 * np.pi)
         for n in (16, 32)}
    nodes, quads = plate_mesh(a, b, 16, 12)
    fc = np.sort(run_calculix(nodes, quads, h, None, 16, "S8R", laminate=lam))[6:16]
    rich = (4 * f[32] - f[16]) / 3
    assert np.abs(rich / fc - 1).max() < 5e-3, rich / fc - 1
    assert np.all(f[16] > fc)


def _perturbed(text, seed=3, amount=0.02):
    """The deck with its interior GRIDs moved in x and y (a distorted mesh: e1 of MITC4 no longer
    along G1 -> G2)."""
    rng = np.random.default_rng(seed)

    def move(m):
        x, y = float(m.group(2)), float(m.group(3))
        if 0 < x < 1 and 0 < y < 1:
            x, y = x + amount * rng.uniform(-1, 1), y + amount * rng.uniform(-1, 1)
        return f"GRID,{m.group(1)},,{x!r},{y!r},0.0"

    return re.sub(r"GRID,(\d+),,([^,]+),([^,]+),0\.0", move, text)


def test_theta_and_mcid_turn_the_material_axis(tmp_path):
    """On a distorted 4 x 4 mesh: plies at 30 and -60 deg with THETA blank and the same plies at 0 and
    -90 with every CQUAD4's THETA = 30 give one K and one M (1e-12): the element's material axis is
    the side G1 -> G2 turned by THETA (MSC QRG), whatever MITC4's own frame; with THETA = 0 instead K
    differs (the test can tell). On the regular mesh MCID of a CORD2R turned 30 deg about z (its x axis
    projected) gives THETA = 30's K and M."""
    h = 0.002
    mats = [MAT8]
    plies = lambda t1, t2: ["PCOMP,1,,,,,,,", f",8,{h / 2!r},{t1}", f",8,{h / 2!r},{t2}"]
    c, s = float(np.cos(np.radians(30))), float(np.sin(np.radians(30)))
    cord = [f"CORD2R,5,,0.,0.,0.,0.,0.,1.", f",{c!r},{s!r},0."]
    decks = {"ply": plate_deck(1, 1, 4, 4, plies(30.0, -60.0), mats),
             "theta": plate_deck(1, 1, 4, 4, plies(0.0, -90.0), mats, theta=30.0),
             "mcid": plate_deck(1, 1, 4, 4, plies(0.0, -90.0), mats, extra=cord),
             "zero": plate_deck(1, 1, 4, 4, plies(0.0, -90.0), mats)}
    decks["mcid"] = re.sub(r"(CQUAD4,\d+,1,\d+,\d+,\d+,\d+)\n", r"\1,5\n", decks["mcid"])
    fe = {k: read_nastran(_write(tmp_path, _perturbed(v), f"{k}.bdf")) for k, v in decks.items() if k != "mcid"}
    for A, B in ((fe["ply"].K, fe["theta"].K), (fe["ply"].M, fe["theta"].M)):
        assert abs(A - B).max() <= 1e-12 * abs(A).max()
    assert abs(fe["zero"].K - fe["ply"].K).max() > 1e-3 * abs(fe["ply"].K).max()
    # MCID: one axis for all elements, = THETA 30 where every G1 -> G2 is along x (the regular mesh)
    regular = {k: read_nastran(_write(tmp_path, decks[k], f"r{k}.bdf")) for k in ("theta", "mcid")}
    for A, B in ((regular["theta"].K, regular["mcid"].K), (regular["theta"].M, regular["mcid"].M)):
        assert abs(A - B).max() <= 1e-12 * abs(A).max()


def test_lam_sym_is_the_mirrored_stack(tmp_path):
    """PCOMP LAM = SYM of [0/90] = the listed [0/90/90/0] (K, M to 1e-12, coupled mass)."""
    h = 0.004
    sym = ["PCOMP,1,,,,,,,SYM", f",8,{h / 4!r},0.", f",8,{h / 4!r},90."]
    full = ["PCOMP,1,,,,,,,", f",8,{h / 4!r},0.", f",8,{h / 4!r},90.", f",8,{h / 4!r},90.", f",8,{h / 4!r},0."]
    a = read_nastran(_write(tmp_path, plate_deck(1, 1, 3, 3, sym, [MAT8]), "a.bdf"))
    b = read_nastran(_write(tmp_path, plate_deck(1, 1, 3, 3, full, [MAT8]), "b.bdf"))
    for A, B in ((a.K, b.K), (a.M, b.M)):
        assert abs(A - B).max() <= 1e-12 * abs(A).max()


@pytest.mark.parametrize("coupmass", [-1, 1])
def test_laminate_body_mass_centre_and_inertia(tmp_path, coupmass):
    """An unsymmetric laminate (MAT8 1600 kg/m^3 0.6 h at 0 deg, MAT1 2700 kg/m^3 0.4 h), Z0 = -0.3 h
    off the mid-plane, NSM 0.5 kg/m^2, on a 0.6 x 0.4 m plate: the body's mass m0 a b and centre of mass
    (a/2, b/2, m1/m0) exactly, m0 = sum rho_k t_k + NSM, m1 = sum rho_k (z_k^2 - z_(k-1)^2)/2 (the NSM
    on the reference plane); coupled mass: its rotational inertia about the origin through M, with
    int rho z^2 = m2 (1e-12 relative). Lumped mass (Nastran's default, no rotary inertia): mass only,
    centre of mass on the reference plane."""
    a, b, h, nsm = 0.6, 0.4, 0.01, 0.5
    t = np.array([0.6 * h, 0.4 * h])
    rho = np.array([PLY.rho, 2700.0])
    z = -0.3 * h + np.concatenate([[0.0], np.cumsum(t)])
    pcomp = [f"PCOMP,1,{float(z[0])!r},{nsm},,,,,", f",8,{float(t[0])!r},0.", f",1,{float(t[1])!r},0."]
    deck = _write(tmp_path, plate_deck(a, b, 3, 2, pcomp, [MAT8, MAT1], coupmass=coupmass))
    body = nastran_body(deck)
    m0 = rho @ t + nsm
    m1 = rho @ np.diff(z**2) / 2
    m2 = rho @ np.diff(z**3) / 3
    mass, c = mass_properties(body)
    zc = m1 / m0 if coupmass > 0 else 0.0
    assert abs(mass / (m0 * a * b) - 1) < 1e-13
    np.testing.assert_allclose(c, [a / 2, b / 2, zc], rtol=0, atol=1e-13)
    if coupmass > 0:
        A = a * b
        Ixx = m0 * A * b**2 / 3 + A * m2  # int (y^2 + z^2) dm about the origin (corner at 0)
        Iyy = m0 * A * a**2 / 3 + A * m2
        Izz = m0 * A * (a**2 + b**2) / 3
        Ixz, Iyz = -A * m1 * a / 2, -A * m1 * b / 2  # - int x z dm, - int y z dm
        J = np.array([[Ixx, -m0 * A * a * b / 4, Ixz], [-m0 * A * a * b / 4, Iyy, Iyz], [Ixz, Iyz, Izz]])
        R = np.zeros((body.n_dof, 3))
        for k in range(3):
            R[0::6, k], R[1::6, k], R[2::6, k] = np.cross(np.eye(3)[k], body.coords).T
            R[3 + k::6, k] = 1.0
        np.testing.assert_allclose(R.T @ (body.M @ R), J, rtol=0, atol=1e-12 * abs(J).max())


LAM_BAD = {  # name -> (PCOMP lines, material lines, extra, card named, message)
    "MAT8-G12": (["PCOMP,1,,,,,,,", ",8,0.001,0."], ["MAT8,8,1.0+11,1.0+10,.3,,,,1600."], [], "MAT8",
                 "not positive definite"),
    "MAT8-nu": (["PCOMP,1,,,,,,,", ",8,0.001,0."], ["MAT8,8,1.0+11,1.0+10,3.5,5.0+9,,,1600."], [], "MAT8",
                "NU12"),
    "PCOMP-LAM": (["PCOMP,1,,,,,,,MEM", ",8,0.001,0."], [MAT8], [], "PCOMP", "LAM = MEM not supported"),
    "CQUAD4-MCID": (["PCOMP,1,,,,,,,", ",8,0.001,0."], [MAT8], ["CORD2C,5,,0.,0.,0.,0.,0.,1.", ",1.,0.,0."],
                    "CQUAD4", "MCID = 5: a rectangular frame"),
    "PSHELL-MAT8": (["PSHELL,1,8,0.001,8,,8"], [MAT8], [], "PSHELL", "material MAT8 8 not supported"),
}


@pytest.mark.parametrize("case", sorted(LAM_BAD))
def test_malformed_laminate_named_with_file_and_line(tmp_path, case):
    pcomp, mats, extra, card, why = LAM_BAD[case]
    text = plate_deck(1, 1, 2, 2, pcomp, mats, extra=extra)
    if case == "CQUAD4-MCID":
        text = re.sub(r"(CQUAD4,\d+,1,\d+,\d+,\d+,\d+)\n", r"\1,5\n", text)
    deck = _write(tmp_path, text)
    with pytest.raises(NastranError) as err:
        read_nastran(deck)
    msg = str(err.value)
    m = re.search(rf"plate\.bdf:(\d+): ({card}\b[^\n]*)", msg)
    assert m, msg
    assert m.group(2).startswith(text.splitlines()[int(m.group(1)) - 1].rstrip()), msg
    assert why in msg, msg
