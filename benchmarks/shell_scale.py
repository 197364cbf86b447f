"""Cost of a shell body against its dof count (docs/shells.md, "Scale"): Witteveen's plate (1000 x 1000 x
0.5 mm steel) of n x n MITC4 quads, 6 dofs per node, the four corners as averaging frames, 20 free-free
modes (models/witteveen_plate.toml at other meshes). Each size runs in a fresh process: CPU time of the
mesh and assembly (solid/shell_batch.py), of the 6-dof body (the fibres' mass points) and of the reduction
stages (one BLAS thread), the wall time of the whole, and the peak resident memory of that process.

    python benchmarks/shell_scale.py                  # n = 40, 80, 120, 182 (10k to 201k dofs)
    python benchmarks/shell_scale.py --n 40 80
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def one(n: int, modes: int = 20) -> dict:
    """Mesh, assemble and reduce the n x n plate in this process."""
    import resource

    import numpy as np

    from ffrf_fmu.reduction_sparse import reduce_solid
    from ffrf_fmu.solid.frames import Frame
    from ffrf_fmu.solid.mesh import Material
    from ffrf_fmu.solid.shell import plate_mesh
    from ffrf_fmu.solid.shell_batch import assemble_mitc4
    from ffrf_fmu.solid.shell_body import shell_body

    w0, c0 = time.perf_counter(), time.process_time()
    nodes, quads = plate_mesh(1.0, 1.0, n, n)
    shell = assemble_mitc4(nodes, quads, 0.0005, Material(2.1e11, 0.3, 7850.0))
    c1 = time.process_time()
    fe = shell_body(shell)
    c2 = time.process_time()
    radius = 1.5 / n  # the corner node and its three neighbours
    frames = [Frame(f"c{i}", np.flatnonzero(np.linalg.norm(fe.coords - p, axis=1) < radius), "averaging",
                    np.array(p, dtype=float)) for i, p in enumerate(([0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]))]
    red = reduce_solid(fe, frames, n_modes=modes)
    c3, w3 = time.process_time(), time.perf_counter()
    return {"n": n, "dofs": fe.n_dof, "assemble_s": c1 - c0, "body_s": c2 - c1, "reduce_s": c3 - c2,
            "wall_s": w3 - w0, "stages_s": red.timings,
            "peak_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "f1_hz": float(red.data.frequencies_hz[0]), "lu_fill": red.lu_fill}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[40, 80, 120, 182])
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.one)))
        return
    print("| n x n | dofs | assemble [s] | body [s] | reduce [s] (factor, modes, attachment) | wall [s] | peak [MB] | f1 [Hz] |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.n:
        out = subprocess.run([sys.executable, __file__, "--one", str(n)], capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        st = r["stages_s"]
        print(f"| {n} x {n} | {r['dofs']:,} | {r['assemble_s']:.2f} | {r['body_s']:.2f} | {r['reduce_s']:.2f} "
              f"({st['factor']:.2f}, {st['modes']:.2f}, {st['attachment']:.2f}) | {r['wall_s']:.1f} | "
              f"{r['peak_MB']:.0f} | {r['f1_hz']:.4f} |", flush=True)


if __name__ == "__main__":
    main()
