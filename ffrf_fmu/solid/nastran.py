"""Nastran bulk data decks -> 6-dof-node K and M (docs/nastran.md).

Reading is pyNastran's (optional extra `nastran`); this module turns the cards it parsed into
scipy.sparse K and M on dofs node_index * 6 + i (i = T1 T2 T3 R1 R2 R3, global axes); the mass is
assembled as node-block mass and mass points (solid/nastran_mass.py), kept in NastranFE for the body
(solid/nastran_body.py); shells and solids are solid/nastran_continuum.py's.

Supported: GRID (positions through CORD2R/C/S by pyNastran's get_position; displacement frames
CD: the dofs stay in the basic frame, nastran_frames.py), CBAR and CBEAM (orientation vector X or G0; pin flags, offsets WA/WB and warping
points refused), CROD (axial + torsion), PBAR, PBARL, PBEAM (constant section), PBEAML (section
properties A, I1, I2, J as pyNastran computes them; I12 must be 0), PROD, MAT1, CONM2 (mass,
offset, rotary inertia about the centre of mass), CQUAD4, CTRIA3, PSHELL, PCOMP + MAT8 (laminates), CHEXA,
CPENTA, CTETRA, PSOLID, SET1 (node sets), SPC/SPC1/SPCADD (zero values only), PARAM WTMASS (scales
M), COUPMASS (> 0 coupled mass, else Nastran's default lumped mass), AUTOSPC, RBE2 and RBE3
(eliminated: solid/nastran_rigid.py). Any other card is refused, named by file and line.

Beam element: ffrf_fmu/fe/beam.py (linear axial and twist, IIE bending): Euler-Bernoulli (GA =
None, cubic Hermite) unless the property gives shear flexibility, then Timoshenko with
GA = K A G: PBAR K1/K2 if given (blank = shear rigid, as in Nastran), PBEAM K1/K2 (Nastran
default 1.0), PBARL/PBEAML by SHEAR_FACTOR_L (ROD 0.9); the
element frame is Nastran's: x from GA to GB, v the orientation vector, z = x cross v, y = z cross x;
I1 bends in plane 1 (x-y, about z), I2 in plane 2 (x-z, about y).
Lumped mass (Nastran default, COUPMASS <= 0): half the element's translational mass (rho A + nsm)
L at each end, for CBEAM also half its torsional inertia rho (I1 + I2) L; no bending rotary
inertia. Coupled mass: the consistent mass of fe/beam.py (with the section's rotary inertia).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..fe.beam import element_matrices
from ..section import Section
from . import MassPoints
from .nastran_continuum import SHELL_CARDS, SOLID_CARDS, add_shells, add_solids, solid_kind
from .nastran_deck import locate_card
from .nastran_frames import check_displacement_frames
from .nastran_mass import Assembly
from .nastran_rigid import RIGID_CARDS, rigid_elements

# cards that do not enter K or M (solution control, output sets, loads); read, listed in
# NastranFE.ignored_cards, never silently
HARMLESS_CARDS = ("PARAM", "EIGRL", "EIGR", "ENDDATA", "USET", "USET1", "LOAD", "FORCE", "MOMENT")
MODEL_CARDS = (
    "GRID", "CORD2R", "CORD2C", "CORD2S", "CBAR", "CBEAM", "CROD", "PBAR", "PBARL", "PBEAM",
    "PBEAML", "PROD", "MAT1", "CONM2", "SPC", "SPC1", "SPCADD", "SET1", *SHELL_CARDS, *SOLID_CARDS, *RIGID_CARDS,
)
# PARAMs read (WTMASS, COUPMASS, AUTOSPC) or output only; any other PARAM is refused
PARAMS_USED = ("WTMASS", "COUPMASS", "AUTOSPC")
PARAMS_OUTPUT = ("POST", "POSTEXT", "OUGCORD", "GRDPNT", "PRTMAXIM", "K6ROT")  # K6ROT: shell.py DRILL used


# shear factors Nastran uses for PBARL/PBEAML sections (measured: with 0.9 the ROD sections of
# models/data/nastran/beam_modes agree with Nastran's bending frequencies to 5e-7, docs/nastran.md);
# other section types are Euler-Bernoulli here, which NastranFE.notes says
SHEAR_FACTOR_L = {"ROD": 0.9}


class NastranError(ValueError):
    """A deck this reader cannot turn into K and M; the message names file, line and card."""


@dataclass(frozen=True)
class NastranFE:
    """Assembled model of a deck. Dof of node index a, component i (T1..R3 = 0..5): 6 a + i."""

    path: str
    node_ids: np.ndarray  # (n,) GRID ids, sorted
    coords: np.ndarray  # (n, 3) basic-frame positions
    K: sp.csr_matrix  # (6n, 6n)
    M: sp.csr_matrix  # (6n, 6n), WTMASS applied
    spc_dofs: np.ndarray  # dofs fixed by the case control's SPC set
    autospc_dofs: np.ndarray  # dofs without stiffness and mass fixed by PARAM AUTOSPC
    T: sp.csr_matrix | None = None  # RBE2/RBE3: u = T u, the model T^T K T, T^T M T (nastran_rigid.py)
    mpc_dofs: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # their dependent dofs
    grid_sets: dict = field(default_factory=dict)  # name -> GRID ids: "spc", "SET1 <sid>" of each SET1
    M_scalar: sp.csr_matrix | None = None  # (n, n) node-block mass of the translations (nastran_mass.py)
    mass_points: MassPoints | None = None  # the rest of M: M = S^T (M_scalar (x) I3) S + mass points
    cells: tuple = ()  # ((meshio cell type, (n_cells, k) node indices), ...): the elements, for VTK output
    wtmass: float = 1.0
    mass_form: str = "lumped"
    ignored_cards: tuple = ()
    notes: tuple = ()  # where the element theory departs from Nastran's
    units: str = ("consistent units as the deck's: lengths of GRID, E of MAT1, mass = "
                  "WTMASS * rho * volume (US decks: in, lbf, lbf s^2/in after WTMASS)")

    def dof(self, grid_id: int, component: int) -> int:
        """Dof of GRID grid_id, component 1..6 (Nastran numbering)."""
        a = int(np.searchsorted(self.node_ids, grid_id))
        if a >= len(self.node_ids) or self.node_ids[a] != grid_id:
            raise KeyError(f"{self.path}: no GRID {grid_id}")
        return 6 * a + component - 1

    @property
    def free_dofs(self) -> np.ndarray:
        fixed = np.union1d(np.union1d(self.spc_dofs, self.autospc_dofs), self.mpc_dofs)
        return np.setdiff1d(np.arange(self.K.shape[0]), fixed)

    def frequencies(self, n: int) -> np.ndarray:
        """Lowest n natural frequencies [Hz] of the constrained model (dense, small decks).

        Solved as M x = mu K x, mu = 1 / omega^2 (K positive definite once constrained), so the
        massless rotation dofs of a lumped mass matrix are admitted (they give mu = 0)."""
        from scipy.linalg import eigh

        f, T = self.free_dofs, self.T
        K, M = (self.K, self.M) if T is None else (T.T @ self.K @ T, T.T @ self.M @ T)
        K, M = K[f][:, f].toarray(), M[f][:, f].toarray()
        mu = eigh(M, K, eigvals_only=True, subset_by_index=[len(f) - n, len(f) - 1])[::-1]
        return 1.0 / np.sqrt(mu) / (2 * np.pi)


def _read(path: str):
    try:
        from pyNastran.bdf.bdf import BDF
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "reading Nastran decks needs pyNastran: pip install 'ffrf-fmu[nastran]'"
        ) from exc
    model = BDF(debug=None)
    try:
        model.read_bdf(path, xref=True, punch=False)
    except Exception as exc:  # pyNastran raises many kinds; name the card it stopped on
        msg = str(exc)
        where = ""
        card = re.search(r"card=\['(\w+)', '([^']*)'", msg)  # pyNastran quotes the card's fields
        if card:
            where = "; " + locate_card(path, card.group(1).upper(), card.group(2).strip())
        for name in () if card else MODEL_CARDS + HARMLESS_CARDS:
            if re.search(rf"\b{name}\b", msg):
                where = "; " + locate_card(path, name)
                break
        raise NastranError(f"{path}: pyNastran could not read the deck ({type(exc).__name__}: "
                           f"{msg.strip()[:400]}){where}") from exc
    return model


def _refuse(path, card, card_id, why):
    raise NastranError(f"{locate_card(path, card, card_id)}: {card} {card_id}: {why}")


def _check_cards(path, model):
    unsupported = [c for c in model.card_count if c not in MODEL_CARDS + HARMLESS_CARDS]
    if unsupported:
        where = "\n  ".join(f"{c} ({model.card_count[c]}x), first at {locate_card(path, c)}"
                            for c in unsupported)
        raise NastranError(f"{path}: cards not supported by ffrf_fmu.solid.nastran "
                           f"(supported: {', '.join(MODEL_CARDS)}):\n  {where}")
    for name in model.params:
        if name not in PARAMS_USED + PARAMS_OUTPUT:
            _refuse(path, "PARAM", name, "this PARAM may change K or M and is not implemented "
                    f"(read: {', '.join(PARAMS_USED)}; output only: {', '.join(PARAMS_OUTPUT)})")


def _param(model, name, default):
    p = model.params.get(name)
    return default if p is None else p.values[0]


def _round_section(beam_type, dim):
    """A, I1, I2, I12, J of the closed round PBARL/PBEAML sections (MSC QRG: ROD DIM1 = R, TUBE DIM1 = R
    outer, DIM2 = R inner), written out because pyNastran's values differ between its releases."""
    r_out, r_in = dim[0], (dim[1] if beam_type == "TUBE" else 0.0)
    inertia = np.pi * (r_out**4 - r_in**4) / 4
    return np.pi * (r_out**2 - r_in**2), inertia, inertia, 0.0, 2 * inertia


def _section(path, elem, prop, lumped, notes):
    """Section of a CBAR/CBEAM property; also returns the per-length lumped torsion inertia."""
    mat = prop.mid_ref
    if mat.type != "MAT1":
        _refuse(path, prop.type, prop.pid, f"material {mat.type} {mat.mid} not supported (MAT1 only)")
    E, G, rho = mat.e, mat.G(), mat.rho or 0.0
    GA2 = GA3 = None
    if prop.type == "PBAR":
        A, I1, I2, I12, J, nsm = prop.A, prop.i1, prop.i2, prop.i12, prop.j, prop.nsm
        # blank K1/K2: shear rigid in Nastran; pyNastran stores blank as 1e8
        if prop.k1 is not None and 0.0 < prop.k1 < 1e8:
            GA2 = prop.k1 * A * G
        if prop.k2 is not None and 0.0 < prop.k2 < 1e8:
            GA3 = prop.k2 * A * G
    elif prop.type == "PBEAM":
        ends = np.array([[q[0], q[-1]] for q in (prop.A, prop.i1, prop.i2, prop.j)], dtype=float)
        if len(prop.A) > 2 or not np.allclose(ends[:, 0], ends[:, 1], rtol=1e-3, atol=0.0):
            _refuse(path, "PBEAM", prop.pid, "tapered PBEAM (stations differing by more than 1e-3 "
                    "relative) not supported")
        if np.any(ends[:, 0] != ends[:, 1]):
            notes.add(f"PBEAM {prop.pid}: end B differs from end A by at most "
                      f"{np.max(np.abs(ends[:, 1] / ends[:, 0] - 1)):.1e} relative; end A used")
        A, I1, I2, I12, J, nsm = prop.A[0], prop.i1[0], prop.i2[0], prop.i12[0], prop.j[0], prop.nsm[0]
        if any(abs(v or 0.0) > 0 for v in np.r_[prop.cwa, prop.cwb]):
            _refuse(path, "PBEAM", prop.pid, "warping coefficient CW not supported")
        if prop.k1:  # PBEAM K1, K2 default 1.0 in Nastran; 0 -> shear rigid
            GA2 = prop.k1 * A * G
        if prop.k2:
            GA3 = prop.k2 * A * G
    elif prop.type in ("PBARL", "PBEAML"):
        nsm = float(np.atleast_1d(prop.nsm)[0] or 0.0)
        if prop.type == "PBEAML" and np.asarray(prop.dim).shape[0] != 1:
            _refuse(path, "PBEAML", prop.pid, "tapered PBEAML (several stations) not supported")
        if prop.beam_type in ("ROD", "TUBE"):
            A, I1, I2, I12, J = _round_section(prop.beam_type, np.ravel(prop.dim).astype(float))
        else:  # pyNastran's section library (1.3 gives None for every PBEAML inertia, 1.4 for a ROD's J)
            A, I1, I2, I12, J = prop.Area(), prop.I11(), prop.I22(), prop.I12(), prop.J()
        k = SHEAR_FACTOR_L.get(prop.beam_type)
        if k is not None:
            GA2 = GA3 = k * A * G
        if J is None or I1 is None or I2 is None:
            _refuse(path, prop.type, prop.pid, f"pyNastran gives no A, I1, I2, J for section {prop.beam_type}")
    else:
        _refuse(path, elem.type, elem.eid, f"property {prop.type} {prop.pid} is not a bar/beam property")
    I12 = I12 or 0.0
    if abs(I12) > 1e-12 * max(I1, I2):
        _refuse(path, prop.type, prop.pid, "I12 != 0 (unsymmetric section) not supported")
    m = rho * A + (nsm or 0.0)
    if prop.type in ("PBARL", "PBEAML") and GA2 is None:
        notes.add(f"{prop.type} {prop.pid} section {prop.beam_type}: shear factor unknown, "
                  "Euler-Bernoulli (Nastran includes shear flexibility)")
    sec = Section(EA=E * A, GJ=G * J, EI2=E * I2, EI3=E * I1, m=m,
                  m22=0.0 if lumped else rho * I2, m33=0.0 if lumped else rho * I1,
                  m11=0.0 if lumped else rho * (I1 + I2), GA2=GA2, GA3=GA3)
    return sec, rho * (I1 + I2)


def _frame(path, model, elem, xa, xb):
    """Nastran's element frame: columns x, y, z in the basic frame."""
    ex = xb - xa
    L = float(np.linalg.norm(ex))
    if L == 0.0:
        _refuse(path, elem.type, elem.eid, "zero length")
    ex = ex / L
    if elem.g0 is not None:
        v = model.nodes[elem.g0].get_position() - xa
    else:
        if model.nodes[elem.ga].cd != 0:
            _refuse(path, elem.type, elem.eid, "orientation vector in a GRID CD frame != 0")
        v = np.asarray(elem.x, dtype=float)
    ez = np.cross(ex, v)
    if np.linalg.norm(ez) < 1e-9 * np.linalg.norm(v) or np.linalg.norm(v) == 0.0:
        _refuse(path, elem.type, elem.eid, "orientation vector parallel to the element axis")
    ez /= np.linalg.norm(ez)
    return L, np.column_stack([ex, np.cross(ez, ex), ez])


def _spc_dofs(path, model, index):
    sub = [s for s in model.case_control_deck.subcases.values() if "SPC" in s.params]
    if not sub:
        return np.zeros(0, dtype=int)
    sid = int(sub[-1].get_parameter("SPC")[0])
    sids = [sid]
    if sid in model.spcadds:
        sids = [s for add in model.spcadds[sid] for s in add.sets]
    dofs = []
    for s in sids:
        if s not in model.spcs:
            raise NastranError(f"{path}: case control SPC = {sid}: no SPC/SPC1 set {s} in the deck")
        for card in model.spcs[s]:
            if card.type == "SPC":
                if any(abs(e) > 0.0 for e in card.enforced):
                    _refuse(path, "SPC", s, "enforced (nonzero) SPC values not supported")
                pairs = zip(card.nodes, card.components)
            else:  # SPC1
                pairs = ((n, card.components) for n in card.nodes)
            for n, comp in pairs:
                for c in str(comp):
                    if c != "0":
                        dofs.append(6 * index[n] + int(c) - 1)
    return np.unique(dofs)


def read_nastran(path: str) -> NastranFE:
    """Read a bulk data deck and assemble K and M (module doc lists what is supported)."""
    path = os.fspath(path)
    model = _read(path)
    _check_cards(path, model)
    check_displacement_frames(lambda card, i, why: _refuse(path, card, i, why), model)  # dofs in basic
    for nid, node in model.nodes.items():
        if node.ps:
            _refuse(path, "GRID", nid, "GRID PS (permanent SPC) not supported")
    node_ids = np.array(sorted(model.nodes), dtype=int)
    index = {int(n): a for a, n in enumerate(node_ids)}
    X = np.array([model.nodes[n].get_position() for n in node_ids], dtype=float).reshape(-1, 3)
    n_dof = 6 * len(node_ids)
    coupmass = int(_param(model, "COUPMASS", -1))
    lumped = coupmass <= 0
    notes = set()
    asm = Assembly(len(node_ids))

    def refuse(card, card_id, why):
        _refuse(path, card, card_id, why)

    solids = {}
    for eid, elem in sorted(model.elements.items()):
        if elem.type in SHELL_CARDS:
            solids.setdefault("shell", []).append(elem)
            continue
        if elem.type in SOLID_CARDS:
            kind = solid_kind(elem)
            if kind is None:
                refuse(elem.type, eid, f"{len(elem.nodes)} nodes ({elem.nodes}) not supported (CHEXA 8 or "
                       "20, CPENTA 6, CTETRA 4 or 10)")
            solids.setdefault(kind, []).append(elem)
            continue
        a, b = index[elem.nodes[0]], index[elem.nodes[1]]
        dofs = np.r_[6 * a : 6 * a + 6, 6 * b : 6 * b + 6]
        asm.cell("line", [a, b])
        if elem.type in ("CBAR", "CBEAM"):
            if elem.pa or elem.pb:
                _refuse(path, elem.type, eid, f"pin flags PA={elem.pa} PB={elem.pb} not supported")
            if np.any(np.asarray(elem.wa, float) != 0.0) or np.any(np.asarray(elem.wb, float) != 0.0):
                _refuse(path, elem.type, eid, "offsets WA/WB not supported")
            if elem.type == "CBEAM" and (elem.sa or elem.sb):
                _refuse(path, "CBEAM", eid, "warping scalar points SA/SB not supported")
            L, R = _frame(path, model, elem, X[a], X[b])
            sec, rho_ip = _section(path, elem, elem.pid_ref, lumped, notes)
            asm.stiffness(dofs, element_matrices(sec, np.array([L]), R[None])[0][0])
            if not lumped:
                asm.beam_mass(sec, L, R, dofs)
                continue
            asm.node_mass([[a], [b]], np.full((2, 1, 1), sec.m * L / 2))
            if elem.type == "CBEAM":  # torsional inertia about the element axis
                for node in (a, b):
                    asm.inertia(node, rho_ip * L / 2 * np.outer(R[:, 0], R[:, 0]))
        elif elem.type == "CROD":
            prop = elem.pid_ref
            mat = prop.mid_ref
            ex = X[b] - X[a]
            L = float(np.linalg.norm(ex))
            if L == 0.0:
                _refuse(path, "CROD", eid, "zero length")
            ex /= L
            P = np.outer(ex, ex)
            Ke = np.zeros((12, 12))
            for off, stiff in ((0, mat.e * prop.A / L), (3, mat.G() * prop.j / L)):
                for i, j, s in ((0, 0, 1), (0, 6, -1), (6, 0, -1), (6, 6, 1)):
                    Ke[off + i : off + i + 3, off + j : off + j + 3] += s * stiff * P
            asm.stiffness(dofs, Ke)
            m = (mat.rho or 0.0) * prop.A + (prop.nsm or 0.0)
            # lumped (Nastran's): m L / 2 in every translation; coupled: (m L / 6) [[2, 1], [1, 2]]
            asm.node_mass([a, b], m * L / 2 * np.eye(2) if lumped else m * L / 6 * np.array([[2, 1], [1, 2]]))
        else:  # pragma: no cover - _check_cards refuses other elements first
            _refuse(path, elem.type, eid, "element not supported")
    for kind, elems in solids.items():
        extra = {"coords": model.coords} if kind == "shell" else {}  # MCID frames of the shells
        (add_shells if kind == "shell" else add_solids)(asm, refuse, X, index, elems, kind, lumped, notes, **extra)

    for mid, mass in sorted(model.masses.items()):
        if mass.type != "CONM2":  # pragma: no cover - refused by _check_cards
            _refuse(path, mass.type, mid, "mass card not supported")
        asm.conm2(refuse, mass, X, index[mass.nid])

    wtmass = float(_param(model, "WTMASS", 1.0))
    K, M, Ms, points = asm.matrices(wtmass)
    spc = _spc_dofs(path, model, index)
    T, mpc = rigid_elements(refuse, model, index, X, spc)
    autospc = np.zeros(0, dtype=int)
    if str(_param(model, "AUTOSPC", "YES")).upper() != "NO":
        Kc, Mc = (K, M) if T is None else (T.T @ K @ T, T.T @ M @ T)
        empty = (abs(Kc).sum(axis=1).A1 == 0.0) & (abs(Mc).sum(axis=1).A1 == 0.0)
        autospc = np.setdiff1d(np.flatnonzero(empty), np.union1d(spc, mpc))
    spc_grids = sorted({int(node_ids[d // 6]) for d in spc})
    ignored = tuple(f"{c} ({model.card_count[c]}x)" for c in model.card_count if c in HARMLESS_CARDS)
    sets = {"spc": spc_grids, **{f"SET1 {sid}": sorted(int(g) for g in s.ids) for sid, s in model.sets.items()}}
    for sid, grids in ((k, v) for k, v in sets.items() if k != "spc"):
        if set(grids) - set(index):
            _refuse(path, "SET1", sid[5:], f"GRID {sorted(set(grids) - set(index))} not in the deck")
    return NastranFE(path=path, node_ids=node_ids, coords=X, K=K, M=M, spc_dofs=spc,
                     autospc_dofs=autospc, T=T, mpc_dofs=mpc, grid_sets=sets, M_scalar=Ms, cells=asm.cell_blocks(), mass_points=points, wtmass=wtmass,
                     mass_form="lumped" if lumped else "coupled", ignored_cards=ignored,
                     notes=tuple(sorted(notes)))


def main(argv=None) -> None:
    """python -m ffrf_fmu.solid.nastran DECK [N [EIGENVALUES_CSV]]: the lowest N frequencies,
    with Nastran's (column cycles_hz of the CSV) beside them if given."""
    import sys

    args = sys.argv[1:] if argv is None else argv
    fe = read_nastran(args[0])
    n = int(args[1]) if len(args) > 1 else 10
    f = fe.frequencies(n)
    ref = None
    if len(args) > 2:
        ref = np.loadtxt(args[2], delimiter=",", skiprows=2, usecols=4)  # comment, header
    print(f"{fe.path}: {len(fe.node_ids)} grids, {fe.K.shape[0]} dofs, {len(fe.free_dofs)} free, "
          f"mass {fe.mass_form}, WTMASS {fe.wtmass:g}; not read: {', '.join(fe.ignored_cards)}")
    for note in fe.notes:
        print("note:", note)
    for k, fk in enumerate(f, 1):
        extra = "" if ref is None or k > len(ref) else f"  Nastran {ref[k - 1]:14.6e}  rel {fk / ref[k - 1] - 1:+.2e}"
        print(f"mode {k:3d}  {fk:14.6e} Hz{extra}")


if __name__ == "__main__":
    main()
