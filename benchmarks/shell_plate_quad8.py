"""The free square steel plate (docs/shells.md, "The 8-node quad") on 8-node quads made from MITC9
(shell_mitc9.quad8_matrices): the centre condensed (Guyan) or tied to the serendipity interpolation.
python benchmarks/shell_plate_quad8.py [condensed|serendipity] [MESHES] [A/H LIST]"""
from __future__ import annotations

import sys

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

from ffrf_fmu.solid.mesh import Material
from ffrf_fmu.solid.shell_mitc9 import plate_mesh9, quad8_matrices, quad9_frame

from _plate import STEEL, frequency_parameter



def quad8_plate(n: int, h: float, centre: str = "condensed", mat: Material = STEEL):
    """(nodes, quads8, K, M) of the unit square, n x n 8-node quads (6 dofs per node, global axes)."""
    nodes, q9 = plate_mesh9(1.0, 1.0, n, n)
    used = np.unique(q9[:, :8])
    ren = -np.ones(len(nodes), dtype=int)
    ren[used] = np.arange(len(used))
    X, q8 = nodes[used], ren[q9[:, :8]]
    rows, cols, kv, mv = [], [], [], []
    for q in q8:
        T, xy = quad9_frame(np.vstack([X[q], X[q[:4]].mean(axis=0)]))
        K, M = quad8_matrices(xy[:8], h, mat, centre=centre)
        R = np.kron(np.eye(16), T)
        d = (6 * q[:, None] + np.arange(6)).ravel()
        rows.append(np.repeat(d, 48))
        cols.append(np.tile(d, 48))
        kv.append((R.T @ K @ R).ravel())
        mv.append((R.T @ M @ R).ravel())
    n6 = 6 * len(X)
    r, c = np.concatenate(rows), np.concatenate(cols)
    return X, q8, sp.csc_matrix((np.concatenate(kv), (r, c)), (n6, n6)), sp.csc_matrix((np.concatenate(mv), (r, c)), (n6, n6))


def plate_lambda(n: int, aoh: float, centre: str = "condensed", count: int = 16, mat: Material = STEEL):
    """lambda = omega a^2 sqrt(rho h / D) of the lowest `count` modes (6 rigid first)."""
    h = 1.0 / aoh
    _, _, K, M = quad8_plate(n, h, centre, mat)
    w2 = np.sort(eigsh(K, count, M, sigma=-1.0, which="LM", return_eigenvectors=False))
    return frequency_parameter(np.sqrt(np.abs(w2)), h, mat=mat)


if __name__ == "__main__":
    centre = sys.argv[1] if len(sys.argv) > 1 else "condensed"
    meshes = [int(v) for v in sys.argv[2].split(",")] if len(sys.argv) > 2 else [4, 8, 16]
    ratios = [float(v) for v in sys.argv[3].split(",")] if len(sys.argv) > 3 else [100, 1000, 2000]
    for n in meshes:
        for aoh in ratios:
            lam = plate_lambda(n, aoh, centre)[6:]
            print(f"| quad8 {centre} {n}x{n} | {aoh:g} | " + " | ".join(f"{v:.3f}" for v in lam) + " |")
