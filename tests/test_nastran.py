"""Nastran decks read and assembled (ffrf_fmu/solid/nastran.py) against the eigenvalues Nastran
printed (models/data/nastran/beam_modes, docs/nastran.md)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.solid.nastran import NastranError, read_nastran

DATA = Path(__file__).resolve().parents[1] / "models" / "data" / "nastran" / "beam_modes"
DECK = DATA / "beam_modes.dat"


def _nastran_hz():
    return np.loadtxt(DATA / "nastran_eigenvalues.csv", delimiter=",", skiprows=2)[:, 4]


def test_beam_modes_frequencies_match_nastran():
    """Same element theory as Nastran's CBAR/CBEAM (Timoshenko bending with the ROD shear factor
    0.9, lumped mass): the 10 frequencies agree to Nastran's 7 printed digits (5e-7 rounding);
    2e-6 allows that rounding and the eigensolver, while the shear-rigid (Euler-Bernoulli) beam is
    1.4e-2 .. 2e-1 off and a shear factor of 0.886 is 2e-4 .. 3e-3 off (docs/nastran.md)."""
    fe = read_nastran(DECK)
    assert fe.mass_form == "lumped" and fe.wtmass == 1.0
    np.testing.assert_array_equal(fe.spc_dofs, np.arange(6))  # SPC 123456 on grid 1
    np.testing.assert_array_equal(fe.autospc_dofs, fe.dof(12, 1) + np.arange(6))  # unconnected
    f = fe.frequencies(10)
    ref = _nastran_hz()
    assert np.max(np.abs(f / ref - 1.0)) < 2e-6, f / ref - 1.0


def test_wtmass_scales_mass(tmp_path):
    """PARAM WTMASS w multiplies M (elements and CONM2): frequencies scale by 1 / sqrt(w)."""
    shutil.copy(DATA / "cbar_cbeam.blk", tmp_path)
    text = DECK.read_text().replace("PARAM   POST", "PARAM   WTMASS  0.25\nPARAM   POST")
    (tmp_path / "beam_modes.dat").write_text(text)
    fe = read_nastran(tmp_path / "beam_modes.dat")
    base = read_nastran(DECK)
    assert fe.wtmass == 0.25
    np.testing.assert_allclose(fe.M.toarray(), 0.25 * base.M.toarray(), rtol=1e-14)
    np.testing.assert_allclose(fe.frequencies(4), 2.0 * base.frequencies(4), rtol=1e-9)


@pytest.mark.parametrize("card", ["RBAR          99      11      12  123456",
                                  "RBE3          99              11  123456     1.0     123       2       3"])
def test_unsupported_card_named_with_file_and_line(tmp_path, card):
    """A card not implemented (RBAR) and an RBE3 whose independent grids lie on one line (they fix
    no rigid motion): refused, named with file and line, never dropped."""
    shutil.copy(DECK, tmp_path)
    blk = (DATA / "cbar_cbeam.blk").read_text()
    blk += card + "\n"
    (tmp_path / "cbar_cbeam.blk").write_text(blk)
    with pytest.raises(NastranError) as err:
        read_nastran(tmp_path / "beam_modes.dat")
    n = len(blk.splitlines())
    assert card[:4] in str(err.value) and f"cbar_cbeam.blk:{n}:" in str(err.value)


def test_broken_grid_named_with_file_and_line(tmp_path):
    shutil.copy(DECK, tmp_path)
    blk = (DATA / "cbar_cbeam.blk").read_text()
    bad = blk.replace("GRID           5       0 4.00000", "GRID           5       0 4.0x000")
    (tmp_path / "cbar_cbeam.blk").write_text(bad)
    with pytest.raises(NastranError) as err:
        read_nastran(tmp_path / "beam_modes.dat")
    line = 1 + bad.splitlines().index(next(ln for ln in bad.splitlines() if "4.0x000" in ln))
    assert f"cbar_cbeam.blk:{line}: GRID           5" in str(err.value)


def test_pin_flags_refused(tmp_path):
    shutil.copy(DECK, tmp_path)
    blk = (DATA / "cbar_cbeam.blk").read_text()
    blk = blk.replace("CBAR           3       1       3       4     0.01.000000     0.0",
                      "CBAR           3       1       3       4     0.01.000000     0.0\n"
                      "                    456")
    (tmp_path / "cbar_cbeam.blk").write_text(blk)
    with pytest.raises(NastranError, match=r"cbar_cbeam.blk:\d+: CBAR +3 .*pin flags PA=0 PB=456"):
        read_nastran(tmp_path / "beam_modes.dat")


def test_conm2_offset_mass_matrix(tmp_path):
    """CONM2 with offset r: M = [[m I, -m [r]x], [m [r]x, J - m [r]x^2]] (rigid-body kinematics):
    its kinetic energy for rotation w about the grid equals that of the offset point mass."""
    shutil.copy(DECK, tmp_path)
    blk = (DATA / "cbar_cbeam.blk").read_text().replace(
        "CONM2         21      11       02.5900-3     0.0     0.0     0.0",
        "CONM2         21      11       02.5900-3     0.5    -0.2     0.3")
    (tmp_path / "cbar_cbeam.blk").write_text(blk)
    fe = read_nastran(tmp_path / "beam_modes.dat")
    base = read_nastran(DECK)
    d = fe.dof(11, 1) + np.arange(6)
    dM = (fe.M - base.M)[d][:, d].toarray()
    m, r, w = 2.59e-3, np.array([0.5, -0.2, 0.3]), np.array([0.3, -1.1, 0.7])
    v = np.cross(w, r)
    np.testing.assert_allclose(np.r_[0, 0, 0, w] @ dM @ np.r_[0, 0, 0, w], m * v @ v, rtol=1e-12)
    np.testing.assert_allclose(dM[:3, 3:] @ w, m * v, rtol=1e-12)


def test_missing_pynastran_names_the_extra(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pyNastran.bdf.bdf", None)  # import fails as if not installed
    with pytest.raises(ImportError, match=r"ffrf-fmu\[nastran\]"):
        read_nastran(DECK)


def test_grids_in_a_cord2r_frame(tmp_path):
    """The GRIDs of beam_modes given in a shifted, rotated CORD2R frame (local x = basic x, local
    z = basic y, origin (5, 5, 5)): same basic positions, same K, M and frequencies."""
    shutil.copy(DECK, tmp_path)
    lines = []
    for ln in (DATA / "cbar_cbeam.blk").read_text().splitlines():
        if ln.startswith("GRID"):
            nid, x = int(ln[8:16]), float(ln[24:32])
            ln = f"GRID,{nid},1,{x - 5.0},5.0,-5.0"
        lines.append(ln)
    lines.append("CORD2R,1,0,5.0,5.0,5.0,5.0,6.0,5.0")  # origin A, z-axis point B
    lines.append(",6.0,5.0,5.0")  # point C in the local x-z plane
    (tmp_path / "cbar_cbeam.blk").write_text("\n".join(lines) + "\n")
    fe, base = read_nastran(tmp_path / "beam_modes.dat"), read_nastran(DECK)
    np.testing.assert_allclose(fe.coords, base.coords, atol=1e-12)
    assert abs(fe.K - base.K).max() <= 1e-10 * abs(base.K).max()
    np.testing.assert_allclose(fe.frequencies(10), base.frequencies(10), rtol=1e-10)


@pytest.mark.parametrize("coupmass", [-1, 1])
def test_crod_chain_against_the_discrete_solution(tmp_path, coupmass):
    """Fixed-free CROD chain, n elements, c = sqrt(E / rho), theta_j = (2 j - 1) pi / (2 n): the
    exact eigenvalues of the discrete chain are, with Nastran's lumped mass (m h / 2 per end),
    omega_j = (2 c / h) sin(theta_j / 2); with the coupled mass (PARAM COUPMASS 1, m h / 6 [2 1; 1 2])
    omega_j^2 = (6 c^2 / h^2) (1 - cos theta_j) / (2 + cos theta_j); only the axial dofs are left free (SPC1 23456 everywhere: the lumped rod has
    no torsional mass, no lateral or bending stiffness)."""
    n, h, E, rho = 6, 0.5, 2.1e11, 7800.0
    deck = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK", f"PARAM,COUPMASS,{coupmass}",
            f"MAT1,1,{E},,0.3,{rho}", "PROD,2,1,3.0e-4,1.0e-8"]
    deck += [f"GRID,{i + 1},,{i * h},0.0,0.0" for i in range(n + 1)]
    deck += [f"CROD,{i + 1},2,{i + 1},{i + 2}" for i in range(n)]
    deck += ["SPC1,1,123456,1", f"SPC1,1,23456,2,THRU,{n + 1}", "ENDDATA"]
    (tmp_path / "rod.bdf").write_text("\n".join(deck) + "\n")
    fe = read_nastran(tmp_path / "rod.bdf")
    assert len(fe.free_dofs) == n
    assert fe.mass_form == ("coupled" if coupmass > 0 else "lumped")
    c, th = np.sqrt(E / rho), (2 * np.arange(1, n + 1) - 1) * np.pi / (2 * n)
    if coupmass > 0:
        omega = np.sqrt(6 * c**2 / h**2 * (1 - np.cos(th)) / (2 + np.cos(th)))
    else:
        omega = 2 * c / h * np.sin(th / 2)
    exact = omega / (2 * np.pi)
    np.testing.assert_allclose(fe.frequencies(n), exact, rtol=1e-10)
