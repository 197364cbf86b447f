"""Partners' FE exports read as they are: node coordinates plus exported mass and stiffness matrices.

- Abaqus `*MATRIX GENERATE` / `*MATRIX OUTPUT, FORMAT=COORDINATE` (.mtx: 1-based row, column, value,
  both triangles) with the .inp that made them (nodes, node sets, material). Rows are node-major
  over the nodes sorted by label, 3 translations each (C3D8/C3D10 have no other dofs).
- Ansys Matrix Market (`coordinate real symmetric`, lower triangle) with the dof mapping vector Ansys
  writes beside it (one node number per 3-row block, i.e. block k of the matrix belongs to node
  mapping[k]), and the node table (German headers, decimal commas, tab separated).

Neither states units. What is found from the files (docs/solids.md): coordinates are metres (the
Ansys header says so; the Abaqus rotor matches it node for node), mass kg (total mass = density x
volume of the mesh), stiffness N/m. Every reader checks the row-to-node mapping it assumed: the
stiffness must annihilate the rigid motions of the nodes (RIGID_TOL), else the mapping is wrong.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

from . import SolidFE, solid_fe

RIGID_TOL = 1e-6  # |K U| / (max|K| max|U|): a stiffness that does not annihilate rigid motions is mis-mapped


def rigid_residual(coords: np.ndarray, K: sp.spmatrix) -> float:
    """max |K U| / (max|K| max|U|) over the 6 rigid motions of node-major 3-dof nodes about their centroid."""
    X = coords - coords.mean(0)
    n = len(X)
    U = np.zeros((n, 3, 6))
    U[:, :, :3] = np.eye(3)
    U[:, 0, 4], U[:, 0, 5] = X[:, 2], -X[:, 1]  # theta x X: columns 3..5 rotations about x, y, z
    U[:, 1, 3], U[:, 1, 5] = -X[:, 2], X[:, 0]
    U[:, 2, 3], U[:, 2, 4] = X[:, 1], -X[:, 0]
    U = U.reshape(3 * n, 6)
    return float(np.abs(K @ U).max() / (abs(K).max() * np.abs(U).max()))


def _check_rigid(coords, K, source: str, mapping: str) -> None:
    r = rigid_residual(coords, K)
    if r > RIGID_TOL:
        raise ValueError(f"{source}: the stiffness does not annihilate the rigid motions of the nodes "
                         f"(residual {r:.1e} > {RIGID_TOL:g}) with {mapping}: wrong node mapping or not a free model")


def read_abaqus_mtx(path) -> sp.csr_matrix:
    """An Abaqus COORDINATE matrix file (1-based row, column, value; both triangles written)."""
    a = np.loadtxt(str(path), ndmin=2)
    if a.shape[1] != 3:
        raise ValueError(f"{path}: expected 3 columns (row, column, value) of *MATRIX OUTPUT, FORMAT=COORDINATE, "
                         f"got {a.shape[1]}")
    r, c = a[:, 0].astype(int) - 1, a[:, 1].astype(int) - 1
    n = int(max(r.max(), c.max())) + 1
    A = sp.coo_matrix((a[:, 2], (r, c)), shape=(n, n)).tocsr()
    asym = abs(A - A.T).max() / abs(A).max()
    if asym > 1e-9:  # both triangles are written: they must agree
        raise ValueError(f"{path}: not symmetric (max |A - A^T| / max|A| = {asym:.1e})")
    return A


def _abaqus_node_labels(inp) -> np.ndarray:
    """Node labels of the *Node blocks of an .inp, in file order."""
    labels, on = [], False
    for line in Path(inp).read_text(errors="replace").splitlines():
        s = line.strip()
        if s.startswith("*"):
            on = s.lower().startswith("*node") and not s.lower().startswith("*node ") or s.lower() == "*node"
            on = s.split(",")[0].strip().lower() == "*node"
            continue
        if on and s:
            labels.append(int(s.split(",")[0]))
    return np.asarray(labels, dtype=int)


def abaqus_material(inp) -> dict:
    """{'density': rho, 'E': E, 'nu': nu} from the first *Material of an .inp (keys absent when not given)."""
    out, key = {}, None
    for line in Path(inp).read_text(errors="replace").splitlines():
        s = line.strip()
        if s.startswith("**"):
            continue
        if s.startswith("*"):
            key = s.split(",")[0].strip().lower()
            continue
        vals = [v for v in s.split(",") if v.strip()]
        if key == "*density" and "density" not in out and vals:
            out["density"] = float(vals[0])
        elif key == "*elastic" and "E" not in out and len(vals) >= 2:
            out["E"], out["nu"] = float(vals[0]), float(vals[1])
    return out


def read_abaqus(inp, stiffness, mass) -> SolidFE:
    """The .inp's nodes and node sets (meshio) with the exported K and M; rows node-major over the
    nodes sorted by label (checked: K annihilates their rigid motions)."""
    import meshio

    mesh = meshio.read(str(inp))
    labels = _abaqus_node_labels(inp)
    if labels.size != len(mesh.points):
        raise ValueError(f"{inp}: read {labels.size} node labels but {len(mesh.points)} nodes")
    order = np.argsort(labels, kind="stable")  # matrix node k = file node order[k]
    K, M = read_abaqus_mtx(stiffness), read_abaqus_mtx(mass)
    coords = np.asarray(mesh.points, dtype=float)[order]
    pos = np.empty_like(order)
    pos[order] = np.arange(order.size)  # file node -> matrix node
    source = f"{Path(inp).name} + {Path(stiffness).name} + {Path(mass).name}"
    _check_rigid(coords, K, source, "rows node-major over the sorted node labels")
    sets = {k: pos[np.asarray(v, dtype=int)] for k, v in getattr(mesh, "point_sets", {}).items()}
    cells = tuple((c.type, pos[c.data]) for c in mesh.cells)
    return solid_fe(coords, K, M, sets, source, cells)


def _german_table(path) -> np.ndarray:
    """A tab-separated Ansys table with one header line and decimal commas, as floats."""
    rows = []
    for line in Path(path).read_text(encoding="utf-8", errors="replace").splitlines()[1:]:
        f = [x for x in line.replace(",", ".").split("\t") if x.strip()]
        if f:
            rows.append(f)
    return rows


def read_ansys(stiffness, mass, mapping, nodes, elements=None) -> SolidFE:
    """Ansys Matrix Market K and M, the dof mapping vector (matrix block k = node mapping[k]) and the
    node table (number, X, Y, Z [m]); elements (optional): the element table, for VTK output."""
    K = sp.csr_matrix(scipy.io.mmread(str(stiffness)))
    M = sp.csr_matrix(scipy.io.mmread(str(mass)))
    mp = np.asarray(scipy.io.mmread(str(mapping)), dtype=int).ravel()
    table = _german_table(nodes)
    number = np.array([int(float(r[0])) for r in table])
    xyz = np.array([[float(x) for x in r[1:4]] for r in table])
    if K.shape[0] != 3 * mp.size:
        raise ValueError(f"{mapping}: {mp.size} entries for a {K.shape[0]}-row matrix: expected one node per 3 rows")
    where = {int(k): i for i, k in enumerate(number)}
    missing = [int(k) for k in mp if int(k) not in where]
    if missing:
        raise ValueError(f"{mapping}: node numbers {missing[:5]} not in the node table {nodes}")
    coords = xyz[[where[int(k)] for k in mp]]
    source = f"{Path(stiffness).name} + {Path(mass).name} + {Path(mapping).name}"
    _check_rigid(coords, K, source, "matrix block k = node mapping[k]")
    cells = ()
    if elements is not None:
        block = {int(k): i for i, k in enumerate(mp)}
        conn = [[block[int(float(x))] for x in r[2:10]] for r in _german_table(elements) if r[1].lower() == "hex8"]
        if conn:
            cells = (("hexahedron", np.asarray(conn, dtype=int)),)
    return solid_fe(coords, K, M, {}, source, cells)
