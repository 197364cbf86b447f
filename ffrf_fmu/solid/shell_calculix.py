"""A shell mesh as a CalculiX deck (S4/S4R, *FREQUENCY) and the eigenvalue table of its .dat file:
the independent solver the shells are checked against (docs/shells.md). CalculiX expands each shell
element to a brick through the thickness (S4 -> C3D8I, S4R -> C3D8R)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from .mesh import Material

EIGEN_TABLE = "E I G E N V A L U E   O U T P U T"


def calculix_deck(nodes, quads, thickness: float, mat: Material, n_modes: int, element: str = "S4") -> str:
    """The text of a free-free *FREQUENCY deck of the quads (1-based node and element numbers)."""
    if element not in ("S4", "S4R"):
        raise ValueError(f"element {element!r}: expected S4 or S4R")
    lines = ["*NODE"] + [f"{i + 1},{x:.15g},{y:.15g},{z:.15g}" for i, (x, y, z) in enumerate(np.asarray(nodes, float))]
    lines += [f"*ELEMENT,TYPE={element},ELSET=EALL"]
    lines += [f"{e + 1}," + ",".join(str(int(k) + 1) for k in q) for e, q in enumerate(quads)]
    lines += ["*MATERIAL,NAME=SHELLMAT", "*ELASTIC", f"{mat.E:.15g},{mat.nu:.15g}", "*DENSITY", f"{mat.rho:.15g}",
              "*SHELL SECTION,ELSET=EALL,MATERIAL=SHELLMAT", f"{thickness:.15g}",
              "*STEP", "*FREQUENCY", f"{int(n_modes)}", "*END STEP"]
    return "\n".join(lines) + "\n"


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
