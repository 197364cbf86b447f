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


@dataclass(frozen=True, eq=False)
class MeshStrain:
    """What the element stresses of a mesh need (geometric stiffening, solid/stiffening.py): the
    scikit-fem mesh, the element name and the material."""

    mesh: object  # skfem.Mesh
    element: str  # one of ELEMENTS
    material: Material


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
# The polynomial degree of each element's shape functions: per direction on a hexahedron (the Gauss
# rule is a tensor product), total on a tetrahedron.
DEGREE = {"hex8": 1, "hex20": 2, "hex27": 2, "tet4": 1, "tet10": 2}


def quadrature_order(element: str) -> int:
    """The one Gauss order of every mesh integral here (K, M and the membrane tensors of
    solid/stiffening.py, whose identity a^T a = K_bar needs the quadrature of K): exact on an affine
    element (a parallelepiped, a straight tetrahedron) for products of up to 3 shape functions or
    gradients, the membrane tensors' cubic terms: 3 x degree (hex27: 4 x 4 x 4 points). scikit-fem's
    default, 2 x maxdeg of the element's monomials (hex27: 7 x 7 x 7 = 343 points), integrates the same
    polynomials exactly with 5.4 times the points (the benchmark bar at 56k dofs: assembly 5.7 -> 3.8 CPU
    s, membrane tensors 38.7 -> 9.3 s; K, M and the tensors equal to 2e-15 on boxes). On a distorted (non-affine)
    hexahedron neither rule is exact: a generated cylinder's K moves by 4e-5 of its largest entry."""
    if element not in DEGREE:
        raise ValueError(f"element {element!r}: expected one of {', '.join(ELEMENTS)}")
    return 3 * DEGREE[element]


def element_geometry(m, e, order: int):
    """The isoparametric map of the linear geometry, in chunks of CHUNK elements: yields
    (c slice of elements, vd (ne, 3 nloc) vector dofs (i, a) node-major, dphi (ne, nq, nloc, 3) the
    physical gradients of the shape functions at the quadrature points, dx (ne, nq) the weights
    |det J| w_q); with the reference values phi (nloc, nq), the FE node coordinates (N, 3) and N first,
    as (phi, coords, N, chunks). scikit-fem's reference shape functions, its Gauss rule exact to degree
    `order` (quadrature_order) and dof numbering. Raises ValueError on a folded element."""
    from skfem.assembly import Dofs
    from skfem.quadrature import get_quadrature

    geo = m.elem()  # the linear geometry element, local corner order of m.t
    Xq, wq = get_quadrature(e.refdom, order)
    nloc, ncor = e.doflocs.shape[0], m.t.shape[0]
    phi = np.stack([e.lbasis(Xq, i)[0] for i in range(nloc)])  # (nloc, nq)
    dphi_ref = np.stack([e.lbasis(Xq, i)[1] for i in range(nloc)])  # (nloc, 3, nq)
    dgeo = np.stack([geo.lbasis(Xq, c)[1] for c in range(ncor)])  # (ncor, 3, nq)
    Xe = m.p.T[m.t.T]  # (nel, ncor, 3)
    dofs = Dofs(m, e).element_dofs  # (nloc, nel)
    nel = Xe.shape[0]
    N = int(dofs.max()) + 1
    # FE node coordinates: the reference dof locations through the geometry map
    ngeo = np.stack([geo.lbasis(e.doflocs.T, c)[0] for c in range(ncor)])  # (ncor, nloc)
    coords = np.zeros((N, 3))
    coords[dofs.T.ravel()] = np.einsum("eca,ci->eia", Xe, ngeo).reshape(-1, 3)
    vd = (3 * dofs.T[:, :, None] + np.arange(3)).reshape(nel, 3 * nloc)  # (nel, 3 nloc) vector dofs, (i, a)

    def chunks():
        for s in range(0, nel, CHUNK):
            c = slice(s, min(s + CHUNK, nel))
            J = np.einsum("eca,cbq->eqab", Xe[c], dgeo)  # dx_a / dxi_b
            det = np.linalg.det(J)
            bad = np.any(det * np.sign(det[:, :1]) <= 0, axis=1)  # a sign change inside an element: folded
            if np.any(bad):  # (the sign itself is the corner order's convention: |det J| is the volume factor)
                raise ValueError(f"mesh: {int(bad.sum())} element(s) folded or degenerate")
            dphi = np.einsum("ibq,eqba->eqia", dphi_ref, np.linalg.inv(J), optimize=True)  # (ne, nq, nloc, 3)
            yield c, vd[c], dphi, np.abs(det) * wq

    return phi, coords, N, chunks()


def lame(material: Material) -> tuple[float, float]:
    """Lame's lambda, mu of an isotropic material."""
    E, nu = material.E, material.nu
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def _elasticity(m, e, material: Material, order: int):
    """K (3N, 3N, node-major) and M_s (N, N) on the scikit-fem mesh m with element e, and the FE node
    coordinates (N, 3): scikit-fem's reference shape functions, quadrature and dof numbering, the
    isoparametric map of the linear geometry and the element matrices by einsum here (scikit-fem's own
    assembly recomputes the map per shape function and loops over every pair of local dofs in Python:
    18 s of fixed cost on hex27, 48 s for 56k dofs; equal to it to 1e-15, tests/test_solids.py):
        K_(ia)(jb) = int lambda d_a phi_i d_b phi_j + mu (delta_ab grad phi_i . grad phi_j + d_b phi_i d_a phi_j),
        M_s,ij = int rho phi_i phi_j."""
    from skfem.assembly import Dofs

    lam, mu = lame(material)
    nloc = e.doflocs.shape[0]
    dofs = Dofs(m, e).element_dofs  # (nloc, nel)
    phi, coords, N, chunks = element_geometry(m, e, order)
    rows, cols, kv, mv, mr, mc = [], [], [], [], [], []
    for c, vdc, dphi, dx in chunks:
        ne, nq = dx.shape
        D = dphi.reshape(ne, nq, 3 * nloc)
        A = np.matmul(D.transpose(0, 2, 1), D * dx[:, :, None]).reshape(ne, nloc, 3, nloc, 3)  # int d_a phi_i d_b phi_j
        Ke = lam * A + mu * A.transpose(0, 1, 4, 3, 2)
        Ke += mu * np.einsum("eicjc->eij", A)[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
        ne = Ke.shape[0]
        rows.append(np.repeat(vdc, 3 * nloc, axis=1).ravel())
        cols.append(np.tile(vdc, (1, 3 * nloc)).ravel())
        kv.append(Ke.reshape(ne, -1).ravel())
        mv.append(material.rho * np.matmul(phi[None] * dx[:, None, :], phi.T).ravel())
        d = dofs.T[c]
        mr.append(np.repeat(d, nloc, axis=1).ravel())
        mc.append(np.tile(d, (1, nloc)).ravel())
    K = sp.coo_matrix((np.concatenate(kv), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * N, 3 * N)).tocsr()
    Ms = sp.coo_matrix((np.concatenate(mv), (np.concatenate(mr), np.concatenate(mc))), shape=(N, N)).tocsr()
    return K, Ms, coords


def assemble(mesh, material: Material, element: str, node_sets=None, source: str = "") -> SolidFE:
    """K (linear elasticity) and M (consistent, rho) of a meshio mesh with scikit-fem elements `element`.
    node_sets: name -> meshio point indices; mapped to FE nodes, and every edge/face node of a quadratic
    element whose corners all lie in the set joins it (a face selection keeps its mid nodes)."""
    import meshio
    from skfem.io.meshio import from_meshio

    points, kind, cells, new = linear_corner_mesh(mesh)
    if kind != element[:3]:
        raise ValueError(f"element {element!r} on a mesh of {'hexahedra' if kind == 'hex' else 'tetrahedra'}")
    ctype = "hexahedron" if kind == "hex" else "tetra"
    m = from_meshio(meshio.Mesh(points, [(ctype, cells)]))
    if m.p.shape[1] != len(points) or np.abs(m.p.T - points).max() > 0.0:
        raise ValueError("internal: scikit-fem reordered the mesh vertices")
    e = _element(element)
    K, Ms, coords = _elasticity(m, e, material, quadrature_order(element))
    from skfem.assembly import Dofs

    dof = Dofs(m, e)
    sets = {}
    for name, idx in (node_sets or {}).items():
        v = new[np.asarray(idx, dtype=int)]
        inset = np.zeros(m.p.shape[1], dtype=bool)
        inset[v[v >= 0]] = True
        nodes = [np.flatnonzero(inset)]
        for dofs, verts in ((dof.edge_dofs, getattr(m, "edges", None)), (dof.facet_dofs, m.facets)):
            if dofs.size and verts is not None:
                full = inset[verts].all(axis=0)
                nodes.append(dofs[:, full].ravel())
        sets[name] = np.unique(np.concatenate(nodes))
    Ms = sp.csr_matrix(Ms)
    return SolidFE(coords, sp.csr_matrix(0.5 * (K + K.T)), sp.kron(Ms, sp.identity(3), format="csr"), Ms, sets,
                   source, ((ctype, cells),), MeshStrain(m, element, material))


def read_mesh(path):
    """A meshio mesh from a file (Gmsh, Abaqus .inp, VTK, ...), with its point sets (name -> indices)."""
    import meshio

    mesh = meshio.read(str(path))
    sets = {k: np.asarray(v, dtype=int) for k, v in getattr(mesh, "point_sets", {}).items()}
    return mesh, sets


def gmsh_model(name: str):
    """gmsh started quietly on a new model `name`; its OpenCASCADE kernel (the mesh scripts of
    models/data/ draw their solids in millimetres with it, then call write_tet10)."""
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    return gmsh.model.occ


def write_tet10(out, group: str, size: float) -> None:
    """The volumes of the gmsh model (one physical group `group`) meshed with quadratic tetrahedra of
    size `size` [mm], written in metres to `out` (gmsh 2.2 ASCII); one thread and a fixed seed, so that
    a rerun gives the committed mesh. Ends the gmsh session."""
    import gmsh

    gmsh.model.occ.synchronize()
    vols = gmsh.model.getEntities(3)
    gmsh.model.addPhysicalGroup(3, [v[1] for v in vols], name=group)
    for option, value in (("Mesh.MeshSizeMin", size), ("Mesh.MeshSizeMax", size), ("Mesh.ElementOrder", 2),
                          ("Mesh.SecondOrderLinear", 0), ("Mesh.ScalingFactor", 1e-3),  # mm -> m
                          ("Mesh.MshFileVersion", 2.2), ("Mesh.Binary", 0), ("General.NumThreads", 1),
                          ("Mesh.RandomSeed", 1)):
        gmsh.option.setNumber(option, value)
    gmsh.model.mesh.generate(3)
    gmsh.write(str(out))
    gmsh.finalize()
