"""A shell mesh as a CalculiX deck (S4/S4R and S8/S8R quads, S3/S6 triangles; *FREQUENCY) and the
eigenvalue table of its .dat file: the independent solver the shells are checked against
(docs/shells.md). CalculiX expands each shell element to a solid through the thickness (S4 -> C3D8I,
S4R -> C3D8R, S8 -> C3D20, S8R -> C3D20R bricks, S3 -> C3D6 and S6 -> C3D15 wedges); the linear bricks
lock on thin plates (measured: S4 at a/h = 1000), the quadratic ones do not (S8 at 2000)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from .mesh import Material

EIGEN_TABLE = "E I G E N V A L U E   O U T P U T"
CORNERS = {"S4": 4, "S4R": 4, "S8": 8, "S8R": 8, "S3": 3, "S6": 6}  # nodes per cell of each CalculiX shell element


def calculix_deck(nodes, quads, thickness: float, mat: Material, n_modes: int, element: str = "S4",
                  laminate=None) -> str:
    """The text of a free-free *FREQUENCY deck of the cells `quads` (quads for S4/S4R, 8-node quads for
    S8/S8R (serendipity; 4-node quads are made quadratic by quadratic_quads), triangles for S3, 6-node
    triangles for S6 (with_midsides); 1-based node and element numbers). With `laminate` (a
    shell_section.Laminate; ccx takes composites on S8R and S6 only) its plies as the layers of a
    `*SHELL SECTION, COMPOSITE` (composite_section; `thickness` and `mat` unused)."""
    if element not in CORNERS:
        raise ValueError(f"element {element!r}: expected one of {', '.join(CORNERS)}")
    if CORNERS[element] == 8 and np.shape(quads)[1:] == (4,):
        nodes, quads = quadratic_quads(nodes, quads)
    if np.shape(quads)[1:] != (CORNERS[element],):
        raise ValueError(f"element {element}: cells of shape {np.shape(quads)}, expected (e, {CORNERS[element]})")
    lines = ["*NODE"] + [f"{i + 1},{x:.15g},{y:.15g},{z:.15g}" for i, (x, y, z) in enumerate(np.asarray(nodes, float))]
    lines += [f"*ELEMENT,TYPE={element},ELSET=EALL"]
    lines += [f"{e + 1}," + ",".join(str(int(k) + 1) for k in q) for e, q in enumerate(quads)]
    if laminate is not None:
        if element not in ("S8R", "S6"):
            raise ValueError(f"element {element}: CalculiX's composite shells are S8R and S6")
        lines += composite_section(laminate)
    else:
        lines += ["*MATERIAL,NAME=SHELLMAT", "*ELASTIC", f"{mat.E:.15g},{mat.nu:.15g}", "*DENSITY", f"{mat.rho:.15g}",
                  "*SHELL SECTION,ELSET=EALL,MATERIAL=SHELLMAT", f"{thickness:.15g}"]
    lines += ["*STEP", "*FREQUENCY", f"{int(n_modes)}", "*END STEP"]
    return "\n".join(lines) + "\n"


def composite_section(laminate, E3_over_E2: float = 1.0, nu23: float = 0.3) -> list:
    """ccx lines of a laminate (shell_section.Laminate) on the element set EALL of a plate in the x-y
    plane: per ply material `*ELASTIC, TYPE=ENGINEERING CONSTANTS` (E1, E2, E3, nu12, nu13, nu23, G12,
    G13, G23; an isotropic ply (E1 = E2, G12 = E1 / (2 (1 + nu12))) as `*ELASTIC` E, nu), one
    `*ORIENTATION` per ply angle (fibre at theta from x, about z), and `*SHELL SECTION, COMPOSITE` with
    one line "thickness, , material, orientation" per ply from the bottom (the side opposite the
    normal) and OFFSET = -(Z0 + T/2) / T (the nodes on the reference plane). The plate theory does not
    see E3, nu13, nu23 (sigma_33 = 0: the plane-stress Q is the inverse of the in-plane compliance,
    E1, E2, nu12, G12 only); ccx's bricks need them: E3 = E3_over_E2 E2, nu13 = nu12, nu23."""
    names, lines = {}, []
    for p in laminate.plies:
        m = p.material
        if m in names:
            continue
        name = names[m] = f"PLY{len(names) + 1}"
        lines += [f"*MATERIAL,NAME={name}"]
        iso = m.E1 == m.E2 and abs(m.G12 - m.E1 / (2 * (1 + m.nu12))) <= 1e-12 * m.G12 and m.G1z == m.G2z == m.G12
        if iso:
            lines += ["*ELASTIC", f"{m.E1:.12e},{m.nu12:.12e}"]
        else:
            lines += ["*ELASTIC,TYPE=ENGINEERING CONSTANTS",
                      f"{m.E1:.12e},{m.E2:.12e},{E3_over_E2 * m.E2:.12e},{m.nu12:.12e},{m.nu12:.12e},{nu23:.12e},"
                      f"{m.G12:.12e},{m.G1z:.12e},", f"{m.G2z:.12e},0."]
        lines += ["*DENSITY", f"{m.rho:.12e}"]
    angles = {}
    for p in laminate.plies:
        if p.theta not in angles:
            angles[p.theta] = f"OR{len(angles) + 1}"
            c, s_ = np.cos(np.radians(p.theta)), np.sin(np.radians(p.theta))
            lines += [f"*ORIENTATION,NAME={angles[p.theta]},SYSTEM=RECTANGULAR",
                      f"{c:.15g},{s_:.15g},0.,{-s_:.15g},{c:.15g},0."]
    T = laminate.thickness
    lines += [f"*SHELL SECTION,COMPOSITE,ELSET=EALL,OFFSET={-(laminate.z0 + T / 2) / T:.15g}"]
    lines += [f"{p.thickness:.15g},,{names[p.material]},{angles[p.theta]}" for p in laminate.plies]
    return lines


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


def with_midsides(nodes, trias):
    """Nodes and 6-node triangles (corners, then the midsides of 01 12 20: CalculiX's S6 order) of
    3-node triangles, one new node at the middle of each edge, shared by its two triangles."""
    X = np.asarray(nodes, dtype=float)
    T = np.asarray(trias, dtype=int)
    edges = np.sort(T[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 3, 2), axis=2).reshape(-1, 2)
    unique, index = np.unique(edges, axis=0, return_inverse=True)
    mid = 0.5 * (X[unique[:, 0]] + X[unique[:, 1]])
    return np.vstack([X, mid]), np.hstack([T, len(X) + np.asarray(index).reshape(-1, 3)])


def used_nodes(nodes, cells):
    """Nodes and cells renumbered to the nodes the cells use (CalculiX has no dofs on a free node)."""
    C = np.asarray(cells, dtype=int)
    used, inverse = np.unique(C, return_inverse=True)
    return np.asarray(nodes, dtype=float)[used], np.asarray(inverse).reshape(C.shape)


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
                 timeout: float = 600.0, laminate=None) -> np.ndarray:
    """Run `ccx` on the deck in a temporary directory; the frequencies [Hz], rigid modes included."""
    ccx = shutil.which("ccx")
    if ccx is None:
        raise RuntimeError("CalculiX: `ccx` is not on PATH")
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "shell.inp").write_text(calculix_deck(nodes, quads, thickness, mat, n_modes, element, laminate))
        run = subprocess.run([ccx, "shell"], cwd=tmp, capture_output=True, text=True, timeout=timeout)
        dat = Path(tmp, "shell.dat")
        if run.returncode != 0 or not dat.exists():
            raise RuntimeError(f"ccx failed (exit {run.returncode}): {run.stdout[-1500:]}{run.stderr[-500:]}")
        return calculix_frequencies(dat.read_text(), "ccx shell.dat")
