"""CalculiX as an FE engine: a CalculiX/Abaqus deck's model data assembled by `ccx` (Debian's
calculix-ccx) with `*FREQUENCY, SOLVER=MATRIXSTORAGE`, which writes the assembled stiffness and mass
(jobname.sti, jobname.mas: the upper triangle as 1-based "row column value") and their dof map
(jobname.dof: one "node.direction" per row), then read as a partner's export (solid/exports.py): the
deck's nodes and node sets with K and M, checked to annihilate the rigid motions and to have the
node-block mass the invariants need. ccx's elements (C3D10, C3D20R, C3D8I, ...) become bodies that way.

The deck's model data is everything before its first `*STEP`; its steps are replaced by the one
MATRIXSTORAGE step. A free-free body is what the reduction takes, so a `*BOUNDARY` in the model data
is refused (the ports are frames on node sets, given in the model file). Shell and beam elements are
refused too: ccx expands them to bricks on nodes of its own, which the dof map names but the deck
does not (docs/solids.md, "CalculiX as an engine").
"""
from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from . import SolidFE, solid_fe

SOLID_TYPES = re.compile(r"^C3D(4|6|8|8R|8I|10|10T|15|20|20R)$", re.IGNORECASE)
TIMEOUT_S = 1800.0


class CalculixError(ValueError):
    """A deck this engine cannot turn into K and M; the message names the file, line and keyword."""


def model_data(deck: Path) -> tuple[str, list[str]]:
    """(the deck's text up to its first *STEP, its *INCLUDE files), checked (module doc)."""
    lines = deck.read_text(errors="replace").splitlines()
    out, includes = [], []
    for k, line in enumerate(lines, start=1):
        s = line.strip()
        key = s.split(",")[0].strip().upper() if s.startswith("*") and not s.startswith("**") else ""
        if key == "*STEP":
            break
        if key == "*BOUNDARY":
            raise CalculixError(f"{deck}:{k}: *BOUNDARY: a body is reduced free-free (its ports are frames on node "
                                "sets of the model file): remove the boundary conditions")
        if key == "*ELEMENT":
            m = re.search(r"TYPE\s*=\s*([A-Za-z0-9]+)", s, re.IGNORECASE)
            if not m or not SOLID_TYPES.match(m.group(1)):
                raise CalculixError(f"{deck}:{k}: *ELEMENT type {m.group(1) if m else '?'}: only solid elements "
                                    "(C3D4 .. C3D20R) are read through ccx's matrices (module doc)")
        if key == "*INCLUDE":
            m = re.search(r"INPUT\s*=\s*([^,]+)", s, re.IGNORECASE)
            if m:
                includes.append(m.group(1).strip().strip('"'))
        out.append(line)
    return "\n".join(out) + "\n", includes


def read_triangle(path: Path, n: int) -> sp.csr_matrix:
    """A symmetric matrix from ccx's upper triangle file (1-based row, column, value)."""
    a = np.loadtxt(str(path), ndmin=2)
    if a.shape[1] != 3:
        raise CalculixError(f"{path}: expected 3 columns (row, column, value), got {a.shape[1]}")
    r, c, v = a[:, 0].astype(int) - 1, a[:, 1].astype(int) - 1, a[:, 2]
    off = r != c
    return sp.coo_matrix((np.r_[v, v[off]], (np.r_[r, c[off]], np.r_[c, r[off]])), shape=(n, n)).tocsr()


def read_dof_map(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(node labels, directions 1..3) of the rows of ccx's .dof file."""
    nodes, dirs = [], []
    for k, line in enumerate(path.read_text().split(), start=1):
        node, _, d = line.partition(".")
        if not (node.isdigit() and d.isdigit()):
            raise CalculixError(f"{path}:{k}: expected node.direction, got {line!r}")
        nodes.append(int(node))
        dirs.append(int(d))
    return np.array(nodes), np.array(dirs)


def run_ccx(deck, timeout: float = TIMEOUT_S) -> SolidFE:
    """The SolidFE of a CalculiX/Abaqus deck (module doc): ccx assembles, this reads."""
    import meshio

    from .exports import _abaqus_node_labels, _check_rigid

    deck = Path(deck)
    ccx = shutil.which("ccx")
    if ccx is None:
        raise RuntimeError("CalculiX: `ccx` is not on PATH (Debian: apt-get install calculix-ccx)")
    text, includes = model_data(deck)
    mesh = meshio.read(str(deck), file_format="abaqus")
    labels = _abaqus_node_labels(deck)
    if labels.size != len(mesh.points):
        raise CalculixError(f"{deck}: read {labels.size} node labels but {len(mesh.points)} nodes")
    with tempfile.TemporaryDirectory() as tmp:
        for inc in includes:
            shutil.copy(deck.parent / inc, Path(tmp) / inc)
        Path(tmp, "body.inp").write_text(text + "*STEP\n*FREQUENCY,SOLVER=MATRIXSTORAGE\n*END STEP\n")
        run = subprocess.run([ccx, "body"], cwd=tmp, capture_output=True, text=True, timeout=timeout)
        files = {e: Path(tmp, f"body.{e}") for e in ("sti", "mas", "dof")}
        if run.returncode != 0 or not all(f.exists() for f in files.values()):
            raise CalculixError(f"{deck}: ccx failed (exit {run.returncode}): {run.stdout[-1500:]}{run.stderr[-500:]}")
        node, direction = read_dof_map(files["dof"])
        K, M = (read_triangle(files[e], len(node)) for e in ("sti", "mas"))
    where = {int(lab): i for i, lab in enumerate(labels)}
    unknown = sorted(set(node.tolist()) - set(where))
    if unknown or direction.max() > 3:
        raise CalculixError(f"{deck}: ccx's dof map names nodes the deck does not ({unknown[:5]}) or rotations: "
                            "a shell or beam element, expanded by ccx (module doc)")
    used = np.unique([where[int(n)] for n in node])
    slot = -np.ones(len(labels), dtype=int)
    slot[used] = np.arange(used.size)
    rows = 3 * slot[[where[int(n)] for n in node]] + direction - 1
    if rows.size != 3 * used.size:
        raise CalculixError(f"{deck}: {rows.size} dofs for {used.size} nodes: every used node needs its 3 translations")
    P = sp.csr_matrix((np.ones(rows.size), (rows, np.arange(rows.size))), shape=(rows.size, rows.size))
    K, M = P @ K @ P.T, P @ M @ P.T  # node-major over the used nodes in file order
    coords = np.asarray(mesh.points, dtype=float)[used]
    source = f"{deck.name} (ccx MATRIXSTORAGE)"
    _check_rigid(coords, K, source, "ccx's dof map")
    sets = {k: slot[np.asarray(v, dtype=int)] for k, v in getattr(mesh, "point_sets", {}).items()}
    sets = {k: v[v >= 0] for k, v in sets.items()}
    cells = tuple((c.type, slot[c.data]) for c in mesh.cells)
    return solid_fe(coords, K, M, sets, source, cells)


CCX_TYPES = {"tetra": "C3D4", "tetra10": "C3D10", "hexahedron": "C3D8", "hexahedron20": "C3D20", "wedge": "C3D6"}


def solid_deck(points, cells, material) -> str:
    """A CalculiX deck's model data for a mesh (points (n, 3), cells [(meshio type, (e, k))]) of one
    isotropic material (E, nu, rho): what run_ccx assembles, to check our elements against ccx's. Node
    orders: meshio's (VTK's) are Abaqus's for these types. Numbers with 12 significant digits in
    exponent form (ccx reads fields of at most 20 characters)."""
    E, nu, rho = material
    lines = ["*NODE"] + [f"{i + 1},{x:.12e},{y:.12e},{z:.12e}" for i, (x, y, z) in enumerate(np.asarray(points, float))]
    first = 1
    for kind, conn in cells:
        if kind not in CCX_TYPES:
            raise CalculixError(f"cell type {kind!r}: CalculiX solids here are {sorted(CCX_TYPES)}")
        lines.append(f"*ELEMENT,TYPE={CCX_TYPES[kind]},ELSET=EALL")
        lines += [f"{first + e}," + ",".join(str(int(k) + 1) for k in c) for e, c in enumerate(conn)]
        first += len(conn)
    lines += ["*MATERIAL,NAME=BODY", "*ELASTIC", f"{E:.12e},{nu:.12e}", "*DENSITY", f"{rho:.12e}",
              "*SOLID SECTION,ELSET=EALL,MATERIAL=BODY"]
    return "\n".join(lines) + "\n"
