"""The free-free square plate (nu = 0.3) with the MITC9 quad (ffrf_fmu/solid/shell_mitc9.py)
against Leissa's frequency parameters and CalculiX S8 on the same cells (centre nodes left out);
prints the table of docs/shells.md.

    python benchmarks/shell_plate_mitc9.py            # meshes 4, 8, 16; a/h 100, 1000, 2000; ccx if on PATH
"""
import shutil
import sys
import time

import numpy as np

from ffrf_fmu.solid.shell import assemble_shells
from ffrf_fmu.solid.shell_calculix import run_calculix, used_nodes
from ffrf_fmu.solid.shell_mitc9 import plate_mesh9

from _plate import STEEL, elastic_lambdas, frequency_parameter, header


def main(meshes=(4, 8, 16), ratios=(100, 1000, 2000), modes=10):
    print(header(modes))
    for n in meshes:
        nodes, q9 = plate_mesh9(1.0, 1.0, n, n)
        for r in ratios:
            h = 1.0 / r
            t0 = time.process_time()
            fe = assemble_shells(nodes, None, h, STEEL, quads9=q9)
            lam = elastic_lambdas(fe, h, modes)
            print(f"MITC9 {n:3d}x{n:<3d} a/h={r:<5d} " + " ".join(f"{x:7.3f}" for x in lam)
                  + f"   ({time.process_time() - t0:.1f} s CPU)")
            if shutil.which("ccx") and r <= 1000:
                f = run_calculix(*used_nodes(nodes, q9[:, :8]), h, STEEL, 6 + modes, element="S8")[6:6 + modes]
                lam_c = frequency_parameter(2 * np.pi * f, h)
                print(f"ccx S8 {n:3d}x{n:<3d} a/h={r:<5d}" + " ".join(f"{x:7.3f}" for x in lam_c)
                      + f"   max |MITC9/ccx - 1| modes 1-5 {np.max(np.abs(lam[:5] / lam_c[:5] - 1)):.2%}, "
                      f"6-{modes} {np.max(np.abs(lam[5:] / lam_c[5:] - 1)):.2%}")


if __name__ == "__main__":
    main(*(tuple(int(v) for v in arg.split(",")) for arg in sys.argv[1:3]))
