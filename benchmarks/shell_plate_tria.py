"""The free-free square plate (nu = 0.3) with the triangles of ffrf_fmu/solid/shell_tri.py (each
square of an n x n grid cut along one diagonal) against Leissa's frequency parameters and CalculiX
on the same triangles (S3, and S6 with a node added at each edge midpoint); prints the tables of
docs/shells.md.

    python benchmarks/shell_plate_tria.py                 # DKT, meshes 8, 16, 32; a/h 100, 1000, 2000
    python benchmarks/shell_plate_tria.py 8,16,32 100,1000,2000 mitc3
    python benchmarks/shell_plate_tria.py 16,32 10,100,1000 ccx
"""
import sys
import time

import numpy as np

from ffrf_fmu.solid.shell import assemble_shells, plate_mesh, rigid_modes
from ffrf_fmu.solid.shell_calculix import run_calculix, with_midsides
from ffrf_fmu.solid.shell_tri import split_quads

from _plate import STEEL, elastic_lambdas, frequency_parameter, header


def main(meshes=(8, 16, 32), ratios=(100, 1000, 2000), what="dkt", modes=10):
    print(header(modes))
    for n in meshes:
        nodes, quads = plate_mesh(1.0, 1.0, n, n)
        for r in ratios:
            h = 1.0 / r
            for diagonal in (("02", "13") if what != "ccx" else ("02",)):
                trias = split_quads(quads, diagonal)
                t0 = time.process_time()
                fe = assemble_shells(nodes, None, h, STEEL, trias=trias, tria_bending="mitc3" if what == "mitc3" else "dkt")
                lam = elastic_lambdas(fe, h, modes)
                rigid = np.abs(fe.K @ rigid_modes(nodes)).max() / abs(fe.K).max()
                name = "MITC3" if what == "mitc3" else "DKT"
                print(f"{name:5s} {n:3d}x{n:<3d} /{diagonal} a/h={r:<5d} " + " ".join(f"{x:7.3f}" for x in lam)
                      + f"   (|K R| / max|K| {rigid:.0e}, {time.process_time() - t0:.1f} s CPU)")
                if what != "ccx":
                    continue
                for element, mesh in (("S3", (nodes, trias)), ("S6", with_midsides(nodes, trias))):
                    t0 = time.time()
                    f = run_calculix(*mesh, h, STEEL, 6 + modes, element=element)[6:6 + modes]
                    lam_c = frequency_parameter(2 * np.pi * f, h)
                    print(f"ccx {element} {n:3d}x{n:<3d} /{diagonal} a/h={r:<5d}" + " ".join(f"{x:7.3f}" for x in lam_c)
                          + f"   ({time.time() - t0:.1f} s wall); max |DKT/ccx - 1| modes 1-5 "
                          f"{np.max(np.abs(lam[:5] / lam_c[:5] - 1)):.2%}, 6-{modes} "
                          f"{np.max(np.abs(lam[5:] / lam_c[5:] - 1)):.2%}")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(*(tuple(int(v) for v in a.split(",")) for a in args[:2]), *args[2:3])
