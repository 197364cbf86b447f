"""A shell mesh as a CalculiX deck (S4/S4R/S8/S8R, *FREQUENCY) and the eigenvalue table of its .dat file:
the independent solver the shells are checked against (docs/shells.md). CalculiX expands each shell
element to a brick through the thickness (S4 -> C3D8I, S4R -> C3D8R, S8 -> C3D20, S8R -> C3D20R); the
linear bricks lock on thin plates (measured: S4 at a/h = 1000), the quadratic ones do not (S8 at 2000)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from .mesh import Material

EIGEN_TABLE = "E I G E N V A L U E   O U T P U T"


def calculix_deck(nodes, quads, thickness: float, mat: Material, n_modes: int, element: str = "S4") -> str:
    """The text of a free-free *FREQUENCY deck of the quads (1-based node and element numbers); S8/S8R:
    the quads with a node added at each edge's midpoint (quadratic_quads)."""
    if element not in ("S4", "S4R", "S8", "S8R"):
        raise ValueError(f"element {element!r}: expected S4, S4R, S8 or S8R")
    if element in ("S8", "S8R"):
        nodes, quads = quadratic_quads(nodes, quads)
    lines = ["*NODE"] + [f"{i + 1},{x:.15g},{y:.15g},{z:.15g}" for i, (x, y, z) in enumerate(np.asarray(nodes, float))]
    lines += [f"*ELEMENT,TYPE={element},ELSET=EALL"]
    lines += [f"{e + 1}," + ",".join(str(int(k) + 1) for k in q) for e, q in enumerate(quads)]
    lines += ["*MATERIAL,NAME=SHELLMAT", "*ELASTIC", f"{mat.E:.15g},{mat.nu:.15g}", "*DENSITY", f"{mat.rho:.15g}",
              "*SHELL SECTION,ELSET=EALL,MATERIAL=SHELLMAT", f"{thickness:.15g}",
              "*STEP", "*FREQUENCY", f"{int(n_modes)}", "*END STEP"]
    return "\n".join(lines) + "\n"


def quadratic_quads(nodes, quads):
    """(nodes, quads8): the 4-node quads with a node at each edge's midpoint, shared between neighbours,
    in CalculiX's S8 order (corners, then the midpoints of edges 1-2, 2-3, 3-4, 4-1). The geometry of
    the flat quads is kept; a quadratic element on it is the same mesh refined in its interpolation."""
    X = np.asarray(nodes, dtype=float)
    Q = np.asarray(quads, dtype=int)
    edges = np.stack([Q, np.roll(Q, -1, axis=1)], axis=2).reshape(-1, 2)  # (4e, 2): 1-2, 2-3, 3-4, 4-1
    unique, inverse = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True)
    mid = 0.5 * (X[unique[:, 0]] + X[unique[:, 1]])
    return np.vstack([X, mid]), np.hstack([Q, len(X) + inverse.reshape(-1, 4)])


def calculix_frequencies(dat: str, where: str = "ccx .dat") -> np.ndarray:
    """Frequencies [Hz] (the CYCLES/TIME column) of the eigenvalue table of a ccx .dat file's text."""
    lines = dat.splitlines()
    start = next((i for i, s in enumerate(lines) if EIGEN_TABLE in s), None)
    if start is None:
        raise ValueError(f"{where}: no eigenvalue output table ({EIGEN_TABLE!r})")
    f = []
    for s in lines[start + 1:]:
        parts = s.split()
        if len(parts) == 5 and parts[0].isdigit():
            f.append(float(parts[3]))
        elif f and not parts:
            break
    if not f:
        raise ValueError(f"{where}: the eigenvalue table has no rows")
    return np.array(f)


def run_calculix(nodes, quads, thickness: float, mat: Material, n_modes: int, element: str = "S4",
                 timeout: float = 600.0) -> np.ndarray:
    """Run `ccx` on the deck in a temporary directory; the frequencies [Hz], rigid modes included."""
    ccx = shutil.which("ccx")
    if ccx is None:
        raise RuntimeError("CalculiX: `ccx` is not on PATH")
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "shell.inp").write_text(calculix_deck(nodes, quads, thickness, mat, n_modes, element))
        run = subprocess.run([ccx, "shell"], cwd=tmp, capture_output=True, text=True, timeout=timeout)
        dat = Path(tmp, "shell.dat")
        if run.returncode != 0 or not dat.exists():
            raise RuntimeError(f"ccx failed (exit {run.returncode}): {run.stdout[-1500:]}{run.stderr[-500:]}")
        return calculix_frequencies(dat.read_text(), "ccx shell.dat")
