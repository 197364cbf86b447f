"""Shells and solids of a Nastran deck (ffrf_fmu/solid/nastran.py; docs/nastran.md): K and the mass
split of solid/nastran_mass.py on the deck's 6-dof nodes.

Shells: CQUAD4 by solid/shell.py's MITC4 element (in blocks: solid/shell_batch.py) with the
thickness of its PSHELL, or the laminate of its PCOMP by classical laminate theory
(solid/shell_section.py: plies of MAT1 and MAT8 at their angles THETA_i from the element's material
axis, from Z0; LAM blank or SYM; A, B, D, the transverse shear H and the inertia m0, m1, m2). The
element's material axis (MSC QRG CQUAD4/CTRIA3): the side G1 -> G2 turned by the element's THETA
about the normal, or the x axis of the rectangular frame MCID projected on the element's plane;
each element's section is turned from that axis to the MITC4 frame (shell_section.rotate_sections).
CTRIA3 by the same element with its third corner
repeated (the collapsed MITC4: one rho t N_i N_j and stiffness of a quad whose 4th corner sits on
the 3rd). Mass: coupled (COUPMASS > 0) rho t int N_i N_j on the translations and the fibres' rotary
inertia as mass points (solid/shell_body.py: w = rho t det J_g, N = (t / sqrt 12) N(xi_g) (-n~));
lumped (Nastran's default) rho t A / k at each of the k corners, no rotary inertia. A laminate's
coupled mass: m0 N_i N_j, the rotary inertia about its centre of mass m2 - m1^2 / m0 as the fibre
points at z = sqrt((m2 - m1^2 / m0) / m0) (weight m0), and for m1 != 0 the offset of that centre,
z_c = m1 / m0, as a point on all dofs (N (I, -z_c n~), weight m0) less its translations (weight -m0):
the three give m0 |u0|^2 - 2 m1 u0 . (n~ theta) + m2 |n~ theta|^2 = int rho |u0 - z n~ theta|^2 dz.

Solids: CHEXA (8, 20 nodes), CPENTA (6), CTETRA (4, 10) with PSOLID: scikit-fem's reference elements
(ElementHex1, ElementHexS2, ElementWedge1, ElementTetP1, ElementTetP2; their shape functions at the
deck's nodes, isoparametric on them) and the element matrices of solid/mesh.py (_elasticity):
    K_(ia)(jb) = int lambda d_a phi_i d_b phi_j + mu (delta_ab grad phi_i . grad phi_j + d_b phi_i d_a phi_j),
    M_s,ij = int rho phi_i phi_j,
on Gauss rules exact to degree 3 (hex, tet4, wedge: 3-point-degree-3 triangle x line, as scikit-fem's
own wedge rule sums its weights to 1/4 of the volume in 12.0) and 6 (tet10, hex20). Lumped mass: the
row sums of M_s (all positive on the linear elements); the quadratic ones keep their consistent mass
(their row sums are negative at the corners) and NastranFE.notes says so. The 3-dof matrices go on
the translations of the 6-dof nodes; the rotations of a node only solids touch stay without stiffness
and mass (AUTOSPC or the reduction leaves them out).
"""
from __future__ import annotations

import numpy as np

from .mesh import Material, lame
from .shell import _GAUSS, _shape, element_frame, element_matrices
from .shell_batch import BLOCK, SectionBlock, element_frames, local_matrices, to_global
from .shell_section import Laminate, Orthotropic, Ply, isotropic_ply, rotate_sections

SHELL_CARDS = ("CQUAD4", "CTRIA3", "PSHELL", "PCOMP", "MAT8")
PYNASTRAN_BLANK_G = 1e8  # pyNastran's value for a blank MAT8 G1Z/G2Z (Nastran: infinite)
SOLID_CARDS = ("CHEXA", "CPENTA", "CTETRA", "PSOLID")
TS_T = 0.833333  # Nastran's default TS/T (pyNastran's too); shell.py's k = 5/6

# the deck's node order on the reference cell of scikit-fem's element (MSC QRG connectivity)
_HEX = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
_TET = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
_TET_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # G5..G10
_TET10 = _TET + [tuple((np.add(_TET[a], _TET[b]) / 2).tolist()) for a, b in _TET_EDGES]
_WEDGE = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (0, 1, 1)]
_HEX_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 5), (2, 6), (3, 7), (4, 5), (5, 6), (6, 7), (7, 4)]  # G9..G20
_HEX20 = _HEX + [tuple((np.add(_HEX[a], _HEX[b]) / 2).tolist()) for a, b in _HEX_EDGES]
QUADRATIC = ("tet10", "hex20")
SOLID_BLOCK = 512  # solids per block: the hex20's (512, 20, 3, 20, 3) integrals are 15 MB
_SHAPES = [_shape(xi, eta) for xi, eta in _GAUSS]  # shell.py's N, dN at its 2 x 2 Gauss points
# meshio (VTK) cell type and node order of each kind: VTK's 20-node brick takes the top edges before
# the vertical ones, Nastran's CHEXA the vertical ones first
VTK = {"hex8": ("hexahedron", slice(None)), "hex20": ("hexahedron20", [*range(12), *range(16, 20), *range(12, 16)]),
       "wedge6": ("wedge", slice(None)), "tet4": ("tetra", slice(None)), "tet10": ("tetra10", slice(None))}


def _material(refuse, mat, card, pid, notes=None):
    if mat.type != "MAT1":
        refuse(card, pid, f"material {mat.type} {mat.mid} not supported (MAT1 only)")
    if not mat.e or mat.nu is None:
        refuse(card, pid, f"MAT1 {mat.mid}: E and NU are needed (E = {mat.e}, NU = {mat.nu})")
    G = mat.e / (2 * (1 + mat.nu))
    if notes is not None and mat.g and abs(mat.g / G - 1) > 1e-6:
        notes.add(f"MAT1 {mat.mid}: shells and solids use E and NU (G = E / (2 (1 + NU)) = {G:.6g}), not the "
                  f"card's G = {mat.g:g}; bars, beams and rods use G = {mat.g:g}")
    return Material(E=float(mat.e), nu=float(mat.nu), rho=float(mat.rho or 0.0))


def shell_property(refuse, prop, notes=None):
    """(Material, thickness) of a PSHELL or of a PCOMP of one isotropic MAT1 (module doc)."""
    if prop.type == "PSHELL":
        mid1, mid2, mid3 = prop.mid1, prop.mid2, prop.mid3
        if mid1 is None or mid2 != mid1 or mid3 not in (mid1, None) or prop.mid4 is not None:
            refuse("PSHELL", prop.pid, f"MID1 = MID2 (= MID3 or blank), no MID4 needed: MID1..4 = "
                   f"{mid1}, {mid2}, {mid3}, {prop.mid4}")
        if abs(prop.twelveIt3 - 1.0) > 1e-6 or abs(prop.tst - TS_T) > 1e-6:
            refuse("PSHELL", prop.pid, f"12I/T^3 = {prop.twelveIt3}, TS/T = {prop.tst}: only the defaults "
                   f"1.0 and {TS_T} (homogeneous plate) are supported")
        if prop.nsm:
            refuse("PSHELL", prop.pid, f"NSM = {prop.nsm} not supported")
        if mid3 is None and notes is not None:
            notes.add(f"PSHELL {prop.pid}: MID3 blank, Nastran's plate is shear rigid; here MITC4 with "
                      "the transverse shear k G t, k = 5/6 (the same for thin plates)")
        if not prop.t or prop.t <= 0:
            refuse("PSHELL", prop.pid, f"thickness T = {prop.t} must be > 0")
        return _material(refuse, prop.mid1_ref, "PSHELL", prop.pid, notes), float(prop.t)
    if prop.type == "PCOMP":
        return laminate(refuse, prop, notes), None
    refuse(prop.type, prop.pid, "not a shell property (PSHELL, PCOMP)")


def _ply_material(refuse, mat, pid, notes):
    """The Orthotropic ply of a PCOMP's MAT1 or MAT8 (shell_section.py)."""
    if mat.type == "MAT1":
        return isotropic_ply(_material(refuse, mat, "PCOMP", pid, notes))
    if mat.type != "MAT8":
        refuse("PCOMP", pid, f"ply material {mat.type} {mat.mid} not supported (MAT1, MAT8)")
    g = []
    for name, value in (("G1Z", mat.g1z), ("G2Z", mat.g2z)):
        if value in (None, PYNASTRAN_BLANK_G):
            if notes is not None:
                notes.add(f"MAT8 {mat.mid}: {name} blank (Nastran: shear rigid; pyNastran gives 1e8); here "
                          f"G12 = {mat.g12:g} (MITC4 needs a finite transverse shear; thin plates do not feel it)")
            value = mat.g12
        g.append(float(value))
    ply = Orthotropic(float(mat.e11), float(mat.e22), float(mat.nu12 or 0.0), float(mat.g12 or 0.0), g[0], g[1],
                      float(mat.rho or 0.0))
    try:
        ply.Q()
    except ValueError as err:
        refuse("MAT8", mat.mid, str(err))
    if min(g) <= 0:
        refuse("MAT8", mat.mid, f"G1Z = {g[0]:g}, G2Z = {g[1]:g} must be > 0")
    return ply


def laminate(refuse, prop, notes=None) -> Laminate:
    """The Laminate of a PCOMP (module doc): plies from the bottom, LAM blank (as listed) or SYM (the
    listed plies are the lower half, bottom to centre, mirrored above), Z0 (pyNastran: -T/2 when blank)."""
    lam = (prop.lam or "").strip().upper()
    if lam not in ("", "BLANK", "SYM"):
        refuse("PCOMP", prop.pid, f"LAM = {prop.lam} not supported (blank or SYM; MEM, BEND, SMEAR, SMCORE "
               "change which stiffness the plies give)")
    mats = {}
    plies = []
    for mat, t, theta in zip(prop.mids_ref, prop.thicknesses, prop.thetas):
        if t is None or t <= 0:
            refuse("PCOMP", prop.pid, f"ply thicknesses {list(prop.thicknesses)} must be > 0")
        if mat.mid not in mats:
            mats[mat.mid] = _ply_material(refuse, mat, prop.pid, notes)
        plies.append(Ply(mats[mat.mid], float(t), float(theta or 0.0)))
    if lam == "SYM":
        plies = plies + plies[::-1]
    T = float(sum(p.thickness for p in plies))
    z0 = float(prop.z0) if prop.z0 is not None else -T / 2
    return Laminate(tuple(plies), z0, float(prop.nsm or 0.0))


def material_angle(refuse, elem, model_coords, T, X):
    """Angle [rad] from the element frame's e1 (rows of T: e1, e2, e3) to the element's material x axis
    (module doc) for corners X (k, 3) in the deck's order."""
    tm = elem.theta_mcid
    if isinstance(tm, (int, np.integer)) and not isinstance(tm, bool):
        coord = model_coords.get(int(tm)) if model_coords is not None else None
        if coord is None or coord.type not in ("CORD2R", "CORD1R"):
            refuse(elem.type, elem.eid, f"MCID = {tm}: a rectangular frame (CORD2R) is needed for the material "
                   f"axis, got {getattr(coord, 'type', 'none')}")
        x = np.asarray(coord.beta(), dtype=float)[0]  # its x axis in the basic frame
        theta = 0.0
    else:
        x = X[1] - X[0]
        theta = np.radians(float(tm or 0.0))
    a, b = x @ T[0], x @ T[1]
    if np.hypot(a, b) <= 1e-9 * np.linalg.norm(x):
        refuse(elem.type, elem.eid, f"MCID = {tm}: its x axis is normal to the element")
    return float(np.arctan2(b, a) + theta)


def _shell_element(asm, refuse, index, elem, notes, cache):
    """(corners q (4,), thickness, Material or Laminate) of one CQUAD4 or CTRIA3 (third corner
    repeated), checked."""
    nodes = _nodes(refuse, index, elem)
    if elem.zoffset:
        refuse(elem.type, elem.eid, f"ZOFFS = {elem.zoffset} not supported")
    prop = elem.pid_ref
    if (prop.type, prop.pid) not in cache:
        cache[prop.type, prop.pid] = shell_property(refuse, prop, notes)
    mat, t = cache[prop.type, prop.pid]
    if t is None:  # a laminate
        t = mat.thickness
    corner_t = [getattr(elem, f"T{k}") for k in range(1, len(nodes) + 1)]
    if any(c is not None and abs(c - (t if elem.tflag == 0 else 1.0)) > 1e-9 * t for c in corner_t):
        refuse(elem.type, elem.eid, f"corner thicknesses T1.. = {corner_t} (TFLAG {elem.tflag}) differ "
               f"from the property's T = {t:g}: not supported")
    asm.cell("quad" if len(nodes) == 4 else "triangle", nodes)
    return (nodes if len(nodes) == 4 else nodes[[0, 1, 2, 2]]), t, mat


def add_shells(asm, refuse, X, index, elems, kind, lumped: bool, notes=None, coords=None):
    """CQUAD4 and CTRIA3 into the Assembly asm (module doc), by shell_batch.py's MITC4 in blocks of one
    material or laminate (an element it refuses is found and named with shell.py's one-element
    version); coords: the deck's coordinate frames (pyNastran model.coords) for MCID."""
    cache = {}
    rows = [_shell_element(asm, refuse, index, elem, notes, cache) for elem in elems]
    groups = {}
    for k, (q, t, mat) in enumerate(rows):
        groups.setdefault(mat, []).append(k)
    N = np.stack([_SHAPES[g][0] for g in range(4)])  # (4 Gauss points, 4 corners)
    dN = np.stack([_SHAPES[g][1] for g in range(4)])  # (4, 2, 4)
    for mat, members in groups.items():
        for s in range(0, len(members), BLOCK):
            ks = members[s : s + BLOCK]
            Q, t = np.array([rows[k][0] for k in ks]), np.array([rows[k][1] for k in ks])
            sections = None
            try:
                T, xy = element_frames(X[Q])
                if isinstance(mat, Laminate):
                    sec = mat.section()
                    angle = np.array([material_angle(refuse, elems[k], coords, T[i], X[Q[i]])
                                      for i, k in enumerate(ks)])
                    sections = SectionBlock(*rotate_sections(sec, angle), np.tile(sec.inertia, (len(ks), 1)))
                Ke, _ = local_matrices(xy, t, mat if sections is None else Material(1.0, 0.0, 0.0), sections=sections)
            except ValueError:
                for k in ks:  # name the element
                    try:
                        element_matrices(element_frame(X[rows[k][0]])[1], rows[k][1], Material(1.0, 0.3, 0.0))
                    except ValueError as exc:
                        refuse(elems[k].type, elems[k].eid, str(exc))
                raise
            asm.stiffness((6 * Q[:, :, None] + np.arange(6)).reshape(len(ks), 24), to_global(Ke, T))
            m0, m1, m2 = (mat.rho * t, 0.0, None) if sections is None else sec.inertia
            w = np.broadcast_to(np.asarray(m0, dtype=float), (len(ks),))[:, None] * np.linalg.det(np.einsum("grk,ekj->egrj", dN, xy))  # (e, g)
            if lumped:  # w_e / k on each of the k distinct corners (a triangle's 4th is its 3rd)
                share = np.where(Q[:, 3] == Q[:, 2], 1 / 3, 1 / 4)[:, None] * np.array([1, 1, 1, 0]) \
                    + np.where(Q[:, 3] == Q[:, 2], 0, 1 / 4)[:, None] * np.array([0, 0, 0, 1])
                asm.node_mass(Q, w.sum(axis=1)[:, None, None] * np.eye(4) * share[:, None, :])
                continue
            asm.node_mass(Q, np.einsum("eg,gi,gj->eij", w, N, N))
            if not np.any(w):
                continue
            nx = -np.stack([skew_of(n) for n in T[:, 2]])  # (e, 3, 3): -n~
            z = t / np.sqrt(12.0) if sections is None else np.full(len(ks), np.sqrt(max(m2 - m1**2 / m0, 0.0) / m0))
            Np = z[:, None, None, None, None] * np.einsum("gi,eac->egaic", N, nx)
            dofs = np.repeat((6 * Q[:, :, None] + 3 + np.arange(3)).reshape(len(ks), 1, 12), 4, axis=1)
            asm.points(dofs.reshape(-1, 12), Np.reshape(-1, 3, 12), w.ravel())
            if m1:  # the centre of mass at z_c = m1 / m0 off the reference plane (module doc)
                Nu = np.broadcast_to(np.einsum("gi,ac->gaic", N, np.eye(3))[None], (len(ks), 4, 3, 4, 3))
                Nfull = np.concatenate([Nu, (m1 / m0) * np.einsum("gi,eac->egaic", N, nx)], axis=4)
                full = np.repeat((6 * Q[:, :, None] + np.arange(6)).reshape(len(ks), 1, 24), 4, axis=1)
                asm.points(full.reshape(-1, 24), Nfull.reshape(-1, 3, 24), w.ravel())
                trans = np.repeat((6 * Q[:, :, None] + np.arange(3)).reshape(len(ks), 1, 12), 4, axis=1)
                asm.points(trans.reshape(-1, 12), Nu.reshape(-1, 3, 12), -w.ravel())


def _nodes(refuse, index, elem):
    if len(set(elem.nodes)) != len(elem.nodes):
        refuse(elem.type, elem.eid, f"a GRID repeated in its connectivity {elem.nodes} (degenerate element)")
    return np.array([index[g] for g in elem.nodes], dtype=int)


def skew_of(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _reference(kind):
    """(scikit-fem element, reference node positions in the deck's order, quadrature X (3, q), w (q,))."""
    import skfem
    from skfem.quadrature import get_quadrature, get_quadrature_line, get_quadrature_tri

    e, ref, order = {"hex8": (skfem.ElementHex1(), _HEX, 3), "hex20": (skfem.ElementHexS2(), _HEX20, 6),
                     "wedge6": (skfem.ElementWedge1(), _WEDGE, 3),
                     "tet4": (skfem.ElementTetP1(), _TET, 3), "tet10": (skfem.ElementTetP2(), _TET10, 6)}[kind]
    if kind == "wedge6":
        Xt, wt = get_quadrature_tri(3)
        Xl, wl = get_quadrature_line(3)
        Xq = np.vstack([np.repeat(Xt, len(wl), axis=1), np.tile(Xl, len(wt))])
        wq = np.repeat(wt, len(wl)) * np.tile(wl, len(wt))
    else:
        Xq, wq = get_quadrature(e.refdom, order)
    locs = np.asarray(e.doflocs, dtype=float)
    perm = [int(np.argmin(np.abs(locs - np.asarray(r)).sum(axis=1))) for r in ref]
    if sorted(perm) != list(range(len(ref))):  # pragma: no cover - a scikit-fem release with other dof locations
        raise RuntimeError(f"scikit-fem's {type(e).__name__} dof locations do not match the deck's node order")
    return e, perm, Xq, wq


def solid_kind(elem):
    n = len(elem.nodes)
    if any(g is None for g in elem.nodes):
        return None
    return {("CHEXA", 8): "hex8", ("CHEXA", 20): "hex20", ("CPENTA", 6): "wedge6", ("CTETRA", 4): "tet4", ("CTETRA", 10): "tet10"}.get((elem.type, n))


def add_solids(asm, refuse, X, index, elems, kind: str, lumped: bool, notes):
    """Solid elements of one kind (same node count) into the Assembly asm (module doc), in blocks of
    one material."""
    e, perm, Xq, wq = _reference(kind)
    phi = np.stack([e.lbasis(Xq, i)[0] for i in perm])  # (nloc, nq), the deck's node order
    dphi_ref = np.stack([e.lbasis(Xq, i)[1] for i in perm])  # (nloc, 3, nq)
    groups = {}
    for elem in elems:
        prop = elem.pid_ref
        if prop.type != "PSOLID":
            refuse(elem.type, elem.eid, f"property {prop.type} {prop.pid} is not a PSOLID")
        if prop.fctn != "SMECH" or prop.isop not in (None, "", "FULL", "REDUCED", 0, 1, 2):
            refuse("PSOLID", prop.pid, f"FCTN = {prop.fctn}, ISOP = {prop.isop} not supported (structural solid)")
        if prop.isop not in (None, ""):
            notes.add(f"PSOLID {prop.pid}: ISOP = {prop.isop} (Nastran's integration scheme) not used: "
                      "full Gauss integration here")
        nodes = _nodes(refuse, index, elem)
        asm.cell(VTK[kind][0], nodes[VTK[kind][1]])
        groups.setdefault(_material(refuse, prop.mid_ref, "PSOLID", prop.pid, notes), []).append((elem, nodes))
    if lumped and kind in QUADRATIC:
        notes.add(f"{elems[0].type} ({phi.shape[0]} nodes): consistent mass (the row-sum lumping of a "
                  "quadratic solid is negative at the corners); Nastran lumps it its own way")
    for mat, members in groups.items():
        lam, mu = lame(mat)
        for s in range(0, len(members), SOLID_BLOCK):
            block = members[s : s + SOLID_BLOCK]
            nodes = np.array([m[1] for m in block])  # (ne, nloc)
            J = np.einsum("eia,ibq->eqab", X[nodes], dphi_ref)  # dx_a / dxi_b
            det = np.linalg.det(J)
            bad = np.any(det * np.sign(det[:, :1]) <= 0, axis=1)
            if np.any(bad):
                elem = block[int(np.argmax(bad))][0]
                refuse(elem.type, elem.eid, "element folded or degenerate (det J changes sign or vanishes)")
            dphi = np.einsum("ibq,eqba->eqia", dphi_ref, np.linalg.inv(J))  # (ne, nq, nloc, 3)
            dx = np.abs(det) * wq
            ne, n = nodes.shape
            A = np.einsum("eq,eqia,eqjb->eiajb", dx, dphi, dphi, optimize=True)  # int d_a phi_i d_b phi_j
            Ke = lam * A + mu * A.transpose(0, 1, 4, 3, 2)
            Ke += mu * np.einsum("eicjc->eij", A)[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
            asm.stiffness((6 * nodes[:, :, None] + np.arange(3)).reshape(ne, 3 * n), Ke.reshape(ne, 3 * n, 3 * n))
            Ms = mat.rho * np.einsum("eq,iq,jq->eij", dx, phi, phi)
            if lumped and kind not in QUADRATIC:
                Ms = Ms.sum(axis=2)[:, :, None] * np.eye(n)
            asm.node_mass(nodes, Ms)
