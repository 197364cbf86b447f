"""The free-free square plate (nu = 0.3) with the MITC4 shell (ffrf_fmu/solid/shell.py) against
Leissa's frequency parameters and CalculiX S4 on the same mesh; prints the tables of docs/shells.md.

    python benchmarks/shell_plate.py            # meshes 8, 16, 32; a/h 100, 1000, 2000; ccx if on PATH
"""
import shutil
import sys
import time

import numpy as np

from ffrf_fmu.solid.shell import assemble_shells, plate_mesh
from ffrf_fmu.solid.shell_calculix import run_calculix

from _plate import STEEL, elastic_lambdas, frequency_parameter, header


def main(meshes=(8, 16, 32), ratios=(100, 1000, 2000), modes=10):
    a = 1.0
    print(header(modes))
    for n in meshes:
        nodes, quads = plate_mesh(a, a, n, n)
        for r in ratios:
            h = a / r
            t0 = time.process_time()
            fe = assemble_shells(nodes, quads, h, STEEL)
            lam = elastic_lambdas(fe, h, modes, a)
            row = f"MITC4 {n:3d}x{n:<3d} a/h={r:<5d} " + " ".join(f"{x:7.3f}" for x in lam)
            print(row + f"   ({time.process_time() - t0:.1f} s CPU)")
            if shutil.which("ccx") and r <= 1000:
                t0 = time.time()
                f = run_calculix(nodes, quads, h, STEEL, 6 + modes)[6:6 + modes]
                lam_c = frequency_parameter(2 * np.pi * f, h, a)
                print(f"ccx S4 {n:3d}x{n:<3d} a/h={r:<5d}" + " ".join(f"{x:7.3f}" for x in lam_c)
                      + f"   ({time.time() - t0:.1f} s wall); max |ours/ccx - 1| modes 1-5 "
                      f"{np.max(np.abs(lam[:5] / lam_c[:5] - 1)):.2%}, 6-{modes} {np.max(np.abs(lam[5:] / lam_c[5:] - 1)):.2%}")


if __name__ == "__main__":
    main(*(tuple(int(v) for v in arg.split(",")) for arg in sys.argv[1:3]))
