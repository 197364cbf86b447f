"""Solid FE models assembled with scikit-fem: linear elasticity (isotropic E, nu) and the consistent
mass (rho) on hexahedra and tetrahedra, linear or quadratic (docs/solids.md: which to use).

The mesh geometry is linear (corner nodes); the element order sets the interpolation: hex8 (trilinear,
locks in bending: a slender bar is several times too stiff on a coarse mesh), hex20 (serendipity),
hex27 (triquadratic), tet4 (locks worse than hex8), tet10 (quadratic). FE nodes are scikit-fem's
Lagrange dof locations: the mesh vertices first (same order), then edge, face and cell nodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from . import SolidFE

ELEMENTS = ("hex8", "hex20", "hex27", "tet4", "tet10")
_CORNERS = {"hexahedron": ("hex", 8), "hexahedron20": ("hex", 8), "hexahedron27": ("hex", 8),
            "tetra": ("tet", 4), "tetra10": ("tet", 4)}


@dataclass(frozen=True)
class Material:
    E: float  # Young's modulus [Pa]
    nu: float  # Poisson's ratio
    rho: float  # density [kg/m^3]


def _element(kind: str):
    from skfem import ElementHex1, ElementHex2, ElementHexS2, ElementTetP1, ElementTetP2

    table = {"hex8": ElementHex1, "hex20": ElementHexS2, "hex27": ElementHex2, "tet4": ElementTetP1, "tet10": ElementTetP2}
    if kind not in table:
        raise ValueError(f"element {kind!r}: expected one of {', '.join(ELEMENTS)}")
    return table[kind]()


def box_points(size, divisions, origin=(0.0, 0.0, 0.0)):
    """Vertices and hexahedra (meshio order) of a box `size` [m] from `origin`, `divisions` cells per side."""
    import meshio

    axes = [np.linspace(o, o + s, int(d) + 1) for o, s, d in zip(origin, size, divisions)]
    from skfem import MeshHex
    from skfem.io.meshio import to_meshio

    m = to_meshio(MeshHex.init_tensor(*axes))
    return meshio.Mesh(m.points, [(c.type, c.data) for c in m.cells])


def cylinder_points(radius: float, length: float, radial: int, axial: int, origin=(0.0, 0.0, 0.0)):
    """A hexahedral cylinder along +Z from `origin`: a box [-1, 1]^2 x [0, 1] with 2 radial x 2 radial x
    axial cells, its cross-section mapped onto the disc by (x, y) -> (x sqrt(1 - y^2/2), y sqrt(1 - x^2/2))
    (the elliptical grid mapping: no collapsed cell; the corners of the square become 45-degree points)."""
    m = box_points((2.0, 2.0, 1.0), (2 * radial, 2 * radial, axial), (-1.0, -1.0, 0.0))
    x, y, z = m.points.T
    p = np.column_stack([radius * x * np.sqrt(1 - y**2 / 2), radius * y * np.sqrt(1 - x**2 / 2), length * z])
    m.points = p + np.asarray(origin, dtype=float)
    return m


def linear_corner_mesh(mesh):
    """(points, kind 'hex'|'tet', cells (n_cells, 8|4) into points, old -> new point index (-1 unused)):
    the corner nodes of a meshio mesh's solid cells (quadratic cells lose their mid nodes: the element
    order decides the interpolation). Raises ValueError without solid cells or with both kinds."""
    kinds = {_CORNERS[c.type][0] for c in mesh.cells if c.type in _CORNERS}
    if len(kinds) != 1:
        found = sorted({c.type for c in mesh.cells})
        raise ValueError(f"expected one kind of solid cell (hexahedra or tetrahedra), found cell types {found}")
    kind = kinds.pop()
    cells = np.concatenate([c.data[:, : _CORNERS[c.type][1]] for c in mesh.cells if c.type in _CORNERS])
    used = np.unique(cells)
    new = -np.ones(len(mesh.points), dtype=int)
    new[used] = np.arange(used.size)
    return np.asarray(mesh.points, dtype=float)[used], kind, new[cells], new


CHUNK = 1024  # elements per batch of element matrices (hex27: 1024 x 81 x 81 doubles = 54 MB)


def _elasticity(scalar, material: Material):
    """K (3N, 3N, node-major) and M_s (N, N) from scikit-fem's scalar basis (shape functions, gradients
    and quadrature weights), element matrices by einsum (scikit-fem's own vector assembly loops over
    every pair of local dofs in Python: 18 s of fixed cost on hex27):
        K_(ia)(jb) = int lambda d_a phi_i d_b phi_j + mu (delta_ab grad phi_i . grad phi_j + d_b phi_i d_a phi_j),
        M_s,ij = int rho phi_i phi_j."""
    E, nu = material.E, material.nu
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    nloc = len(scalar.basis)
    phi = np.stack([np.asarray(scalar.basis[i][0]) for i in range(nloc)])  # (nloc, nel, nq)
    dphi = np.stack([scalar.basis[i][0].grad for i in range(nloc)])  # (nloc, 3, nel, nq)
    dx = scalar.dx  # (nel, nq)
    dofs = scalar.element_dofs  # (nloc, nel)
    N = scalar.N
    nel = dx.shape[0]
    rows, cols, kv, mv = [], [], [], []
    vd = (3 * dofs.T[:, :, None] + np.arange(3)).reshape(nel, 3 * nloc)  # (nel, 3 nloc) vector dofs, (i, a)
    for s in range(0, nel, CHUNK):
        c = slice(s, min(s + CHUNK, nel))
        A = np.einsum("iaeq,jbeq,eq->eiajb", dphi[:, :, c], dphi[:, :, c], dx[c], optimize=True)
        Ke = lam * A + mu * A.transpose(0, 1, 4, 3, 2)
        Ke += mu * np.einsum("eicjc->eij", A)[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
        ne = Ke.shape[0]
        Ke = Ke.reshape(ne, 3 * nloc, 3 * nloc)
        rows.append(np.repeat(vd[c], 3 * nloc, axis=1).ravel())
        cols.append(np.tile(vd[c], (1, 3 * nloc)).ravel())
        kv.append(Ke.ravel())
        mv.append(material.rho * np.einsum("ieq,jeq,eq->eij", phi[:, c], phi[:, c], dx[c], optimize=True).ravel())
    K = sp.coo_matrix((np.concatenate(kv), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * N, 3 * N)).tocsr()
    d = dofs.T
    Ms = sp.coo_matrix((np.concatenate(mv), (np.repeat(d, nloc, axis=1).ravel(), np.tile(d, (1, nloc)).ravel())),
                       shape=(N, N)).tocsr()
    return K, Ms


def assemble(mesh, material: Material, element: str, node_sets=None, source: str = "") -> SolidFE:
    """K (linear elasticity) and M (consistent, rho) of a meshio mesh with scikit-fem elements `element`.
    node_sets: name -> meshio point indices; mapped to FE nodes, and every edge/face node of a quadratic
    element whose corners all lie in the set joins it (a face selection keeps its mid nodes)."""
    import meshio
    from skfem import Basis
    from skfem.io.meshio import from_meshio

    points, kind, cells, new = linear_corner_mesh(mesh)
    if kind != element[:3]:
        raise ValueError(f"element {element!r} on a mesh of {'hexahedra' if kind == 'hex' else 'tetrahedra'}")
    ctype = "hexahedron" if kind == "hex" else "tetra"
    m = from_meshio(meshio.Mesh(points, [(ctype, cells)]))
    if m.p.shape[1] != len(points) or np.abs(m.p.T - points).max() > 0.0:
        raise ValueError("internal: scikit-fem reordered the mesh vertices")
    e = _element(element)
    scalar = Basis(m, e)
    K, Ms = _elasticity(scalar, material)
    coords = scalar.doflocs.T.copy()
    sets = {}
    for name, idx in (node_sets or {}).items():
        v = new[np.asarray(idx, dtype=int)]
        inset = np.zeros(m.p.shape[1], dtype=bool)
        inset[v[v >= 0]] = True
        nodes = [np.flatnonzero(inset)]
        for dofs, verts in ((scalar.edge_dofs, getattr(m, "edges", None)), (scalar.facet_dofs, m.facets)):
            if dofs.size and verts is not None:
                full = inset[verts].all(axis=0)
                nodes.append(dofs[:, full].ravel())
        sets[name] = np.unique(np.concatenate(nodes))
    Ms = sp.csr_matrix(Ms)
    return SolidFE(coords, sp.csr_matrix(0.5 * (K + K.T)), sp.kron(Ms, sp.identity(3), format="csr"), Ms, sets,
                   source, ((ctype, cells),))


def read_mesh(path):
    """A meshio mesh from a file (Gmsh, Abaqus .inp, VTK, ...), with its point sets (name -> indices)."""
    import meshio

    mesh = meshio.read(str(path))
    sets = {k: np.asarray(v, dtype=int) for k, v in getattr(mesh, "point_sets", {}).items()}
    return mesh, sets
