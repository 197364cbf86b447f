"""The free-free square plate (nu = 0.3) on distorted meshes: the interior grid vertices moved at
random by up to 0.2 of a cell in x and y (seed 5), edges kept straight, for the MITC4 quad, the DKT
triangle (each cell cut along 0-2) and the MITC9 quad (midsides and centre at their bilinear places);
a/h 100, 1000, 2000. Prints the table of docs/shells.md.

    python benchmarks/shell_plate_distorted.py
"""
import numpy as np

from ffrf_fmu.solid.shell import assemble_shells, plate_mesh
from ffrf_fmu.solid.shell_mitc9 import plate_mesh9
from ffrf_fmu.solid.shell_tri import split_quads

from _plate import STEEL, elastic_lambdas, header


def vertices(n, seed=5, amount=0.2):
    V = np.stack(np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="xy"), axis=-1)
    V[1:-1, 1:-1] += np.random.default_rng(seed).uniform(-amount, amount, V[1:-1, 1:-1].shape) / n
    return V


def mesh(element, n):
    V = vertices(n)
    if element == "MITC9":
        nodes, q9 = plate_mesh9(1.0, 1.0, n, n)
        J, I = np.divmod(np.arange(len(nodes)), 2 * n + 1)
        nodes[:, :2] = 0.25 * (V[J // 2, I // 2] + V[J // 2, (I + 1) // 2] + V[(J + 1) // 2, I // 2]
                               + V[(J + 1) // 2, (I + 1) // 2])
        return nodes, {"quads": None, "quads9": q9}
    nodes, quads = plate_mesh(1.0, 1.0, n, n)
    nodes[:, :2] = V.reshape(-1, 2)
    return nodes, ({"quads": quads} if element == "MITC4" else {"quads": None, "trias": split_quads(quads, "02")})


def main():
    print(header(5))
    for element, sizes in (("MITC4", (8, 16)), ("DKT", (8, 16)), ("MITC9", (4, 8))):
        for n in sizes:
            nodes, cells = mesh(element, n)
            for r in (100, 1000, 2000):
                h = 1.0 / r
                fe = assemble_shells(nodes, cells["quads"], h, STEEL, **{k: v for k, v in cells.items() if k != "quads"})
                lam = elastic_lambdas(fe, h, 5)
                print(f"{element:5s} {n:2d}x{n:<2d} distorted a/h={r:<5d}" + " ".join(f"{x:7.3f}" for x in lam))


if __name__ == "__main__":
    main()
