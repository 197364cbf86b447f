"""Laminated plates read from generated Nastran decks (PCOMP of MAT8 and MAT1 plies, CQUAD4 = MITC4):
(1) a simply supported symmetric cross-ply [0/90]s square against the exact Navier frequencies
(classical laminate theory and first-order shear deformation), (2) a free unsymmetric mixed laminate
[0 (MAT8) / aluminium (MAT1) / 45 (MAT8)] against CalculiX's composite S8R on the same cells
(docs/shells.md, "Laminates"). python benchmarks/laminate_plate.py [navier|ccx] [MESHES] [A/H]"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import eigsh

from ffrf_fmu.solid.laminate_plate import navier_clt, navier_fsdt, navier_table, plate_deck
from ffrf_fmu.solid.mesh import Material
from ffrf_fmu.solid.nastran import read_nastran
from ffrf_fmu.solid.shell import plate_mesh
from ffrf_fmu.solid.shell_calculix import run_calculix
from ffrf_fmu.solid.shell_section import Laminate, Orthotropic, Ply, isotropic_ply

# graphite-epoxy T300/5208 (Tsai & Hahn; G2z = G23 = E2 / (2 (1 + 0.8)))
PLY = Orthotropic(E1=181e9, E2=10.3e9, nu12=0.28, G12=7.17e9, G1z=7.17e9, G2z=2.87e9, rho=1600.0)
ALUMINIUM = Material(E=70e9, nu=0.33, rho=2700.0)
MAT8 = f"MAT8,8,{PLY.E1!r},{PLY.E2!r},{PLY.nu12},{PLY.G12!r},{PLY.G1z!r},{PLY.G2z!r},{PLY.rho}"
MAT1 = f"MAT1,1,{ALUMINIUM.E!r},,{ALUMINIUM.nu},{ALUMINIUM.rho}"


def cross_ply(h: float):
    """[0/90]s of total thickness h: the PCOMP (LAM = SYM) lines and the Laminate."""
    pcomp = ["PCOMP,1,,,,,,,SYM", f",8,{h / 4!r},0.", f",8,{h / 4!r},90."]
    plies = (Ply(PLY, h / 4, 0.0), Ply(PLY, h / 4, 90.0))
    return pcomp, Laminate(plies + plies[::-1], -h / 2)


def mixed(h: float):
    """[0 (0.4 h) / aluminium (0.2 h) / 45 (0.4 h)], unsymmetric (B != 0, D16, D26 != 0)."""
    t = (0.4 * h, 0.2 * h, 0.4 * h)
    pcomp = ["PCOMP,1,,,,,,,", f",8,{t[0]!r},0.", f",1,{t[1]!r},0.", f",8,{t[2]!r},45."]
    return pcomp, Laminate((Ply(PLY, t[0], 0.0), Ply(isotropic_ply(ALUMINIUM), t[1], 0.0), Ply(PLY, t[2], 45.0)), -h / 2)


def deck_omegas(text: str, count: int, free: bool) -> np.ndarray:
    """omega [rad/s] of the deck: the lowest `count` of the constrained model (free = False) or the
    `count` after the 6 rigid modes (free = True)."""
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "plate.bdf").write_text(text)
        fe = read_nastran(str(Path(tmp, "plate.bdf")))
    f = fe.free_dofs
    K, M = fe.K[f][:, f].tocsc(), fe.M[f][:, f].tocsc()
    k = count + (6 if free else 0)
    w2 = np.sort(eigsh(K, k, M, sigma=-1.0, which="LM", return_eigenvectors=False))
    return np.sqrt(np.abs(w2[6:] if free else w2))


def navier(meshes=(8, 16, 32), ratios=(100, 1000), a: float = 1.0, count: int = 8):
    for aoh in ratios:
        h = a / aoh
        pcomp, lam = cross_ply(h)
        sec = lam.section()
        clt, fsdt = navier_table(sec, a, a, count, navier_clt), navier_table(sec, a, a, count, navier_fsdt)
        scale = a**2 / h * np.sqrt(PLY.rho / PLY.E2)  # omega a^2 / h sqrt(rho / E2)
        print(f"| CLT (Navier) | {aoh} | " + " | ".join(f"{v * scale:.4f}" for v in clt) + " |")
        print(f"| FSDT (Navier) | {aoh} | " + " | ".join(f"{v * scale:.4f}" for v in fsdt) + " |")
        ours = {}
        for n in meshes:
            t0 = time.process_time()
            ours[n] = deck_omegas(plate_deck(a, a, n, n, pcomp, [MAT8], spc="hard"), count, free=False)
            print(f"| MITC4 {n}x{n} | {aoh} | " + " | ".join(f"{v * scale:.4f}" for v in ours[n])
                  + f" |  ({time.process_time() - t0:.1f} s)")
        for n in meshes[1:]:
            r = (4 * ours[n] - ours[n // 2]) / 3 if n // 2 in ours else None
            if r is not None:
                print(f"| Richardson {n // 2}, {n} | {aoh} | " + " | ".join(f"{v * scale:.4f}" for v in r) + " |")
                print(f"    rel. to FSDT: {np.array2string(r / fsdt - 1, precision=5)}; CLT: "
                      f"{np.array2string(r / clt - 1, precision=5)}; FSDT/CLT - 1: {np.array2string(fsdt / clt - 1, precision=5)}")


def ccx(meshes=(8, 16, 32), aoh: float = 100, a: float = 1.0, b: float = 0.75, count: int = 10, ccx_up_to: int = 16):
    h = a / aoh
    pcomp, lam = mixed(h)
    ours = {}
    for n in meshes:
        ny = int(round(n * b / a))
        t0 = time.process_time()
        ours[n] = deck_omegas(plate_deck(a, b, n, ny, pcomp, [MAT8, MAT1]), count, free=True) / (2 * np.pi)
        print(f"| MITC4 {n}x{ny} | " + " | ".join(f"{v:.3f}" for v in ours[n]) + f" |  ({time.process_time() - t0:.1f} s)")
        if n // 2 in ours:
            r = (4 * ours[n] - ours[n // 2]) / 3
            print(f"| MITC4 Richardson {n // 2}, {n} | " + " | ".join(f"{v:.3f}" for v in r) + " |")
        if n <= ccx_up_to:
            t0 = time.perf_counter()
            nodes, quads = plate_mesh(a, b, n, ny)
            fc = np.sort(run_calculix(nodes, quads, h, None, count + 6, "S8R", laminate=lam))[6:]
            print(f"| ccx S8R {n}x{ny} | " + " | ".join(f"{v:.3f}" for v in fc) + f" |  ({time.perf_counter() - t0:.1f} s wall)")
            print(f"    MITC4 / S8R - 1: {np.array2string(ours[n] / fc - 1, precision=4)}")
            if n // 2 in ours:
                print(f"    Richardson / S8R - 1: {np.array2string(r / fc - 1, precision=4)}")


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "both"
    meshes = tuple(int(v) for v in sys.argv[2].split(",")) if len(sys.argv) > 2 else (8, 16, 32)
    if what in ("navier", "both"):
        navier(meshes, tuple(int(v) for v in sys.argv[3].split(",")) if len(sys.argv) > 3 else (100, 1000))
    if what in ("ccx", "both"):
        ccx(meshes, float(sys.argv[3]) if len(sys.argv) > 3 and what == "ccx" else 100)
