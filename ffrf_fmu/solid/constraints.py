"""Interface frames as constraints of a sparse body (reduction_sparse.py's module doc): u = T z with the
rigid (RBE2) sets eliminated, the frames' coordinates q_B = L z (averaging sets: RBE3), the rigid modes
U_z about the CM in z; and the mass and CM that place them (mass_properties), on 3- or 6-dof nodes."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..runtime.rotation import skew
from . import SolidFE
from .frames import averaging_weights, check_set


@dataclass(frozen=True, eq=False)
class Constraints:
    """u = T z (RBE2 frames eliminated), q_B = L z, rigid modes U_z about the CM in z."""

    T: sp.csr_matrix  # (n_dof, n_z)
    L: sp.csr_matrix  # (6 n_f, n_z)
    U: np.ndarray  # (n_z, 6)
    dof_node: np.ndarray  # (n_z,) the FE node of each z dof, -1 for a rigid frame's own 6 (the LU's ordering)


def mass_properties(fe: SolidFE) -> tuple[float, np.ndarray]:
    """Mass and CM from the mass matrix and the rigid fields about the origin: with t_j the unit
    translations and r_k the rotations about e_k, m = tr(t^T M t) / 3 and t_j^T M r_k = -(m x_cm)~[j, k]
    (exact for any mass that moves rigidly with the nodes: node-block, shell fibres, offset masses)."""
    Ut = np.zeros((fe.n_nodes, fe.dofs_per_node, 3))
    Ut[:, :3] = np.eye(3)
    Ur0 = np.zeros((fe.n_nodes, fe.dofs_per_node, 3))
    Ur0[:, :3] = -skew(fe.coords)
    if fe.dofs_per_node == 6:
        Ur0[:, 3:] = np.eye(3)
    Ut, Ur0 = Ut.reshape(fe.n_dof, 3), Ur0.reshape(fe.n_dof, 3)
    MUt = np.asarray(fe.M @ Ut)
    mass = float(np.trace(Ut.T @ MUt)) / 3
    S = MUt.T @ Ur0  # = -(m x_cm)~
    c = 0.5 * np.array([S[1, 2] - S[2, 1], S[2, 0] - S[0, 2], S[0, 1] - S[1, 0]])
    return mass, c / mass


def rigid_rows(X: np.ndarray) -> np.ndarray:
    """(k, 3, 6): the displacement of nodes at X (from the origin of the rotations) in the 6 rigid modes."""
    out = np.zeros((len(X), 3, 6))
    out[:, :, :3] = np.eye(3)
    out[:, :, 3:] = -skew(X)
    return out


def active_rotations(fe: SolidFE) -> np.ndarray:
    """(n_nodes, 3) bool: the rotation dofs some element stiffens (all False on 3-dof nodes). A 6-dof
    node of bricks only has none: its rotations carry neither stiffness nor mass and are left out."""
    if fe.dofs_per_node == 3:
        return np.zeros((fe.n_nodes, 3), dtype=bool)
    d = np.abs(fe.K.diagonal()).reshape(fe.n_nodes, 6)
    return d[:, 3:] > 0.0


def constraints(fe: SolidFE, frames, x_cm) -> Constraints:
    """T, L and U_z (module doc). Rigid sets are eliminated (their nodes' translations follow the frame
    rigidly, their rotations are the frame's); averaging sets act on the translations of the remaining
    dofs. Rotation dofs no element stiffens are not in z. A node in two rigid sets, or in a rigid and an
    averaging set, is an error naming both ports."""
    n, d = fe.n_nodes, fe.dofs_per_node
    owner = -np.ones(n, dtype=int)
    rot = active_rotations(fe)
    for f, fr in enumerate(frames):
        check_set(fr, fe.coords, rotations=bool(rot[fr.nodes].all()))
        if fr.coupling == "rigid":
            clash = fr.nodes[owner[fr.nodes] >= 0]
            if clash.size:
                raise ValueError(f"ports {frames[owner[clash[0]]].name!r} and {fr.name!r}: node {clash[0]} is in two "
                                 "rigid sets")
            owner[fr.nodes] = f
    keep = np.concatenate([np.ones((n, 3), dtype=bool), rot], axis=1)[:, :d]  # (n, d) dofs in z when free
    keep[owner >= 0] = False
    free_dofs = np.flatnonzero(keep.reshape(-1))  # global dofs of the free nodes, node-major
    n_free = free_dofs.size
    zof = -np.ones(d * n, dtype=int)
    zof[free_dofs] = np.arange(n_free)
    rigid = [f for f, fr in enumerate(frames) if fr.coupling == "rigid"]
    zframe = {f: n_free + 6 * i for i, f in enumerate(rigid)}
    n_z = n_free + 6 * len(rigid)
    rows, cols, vals = [free_dofs], [np.arange(n_free)], [np.ones(n_free)]
    for f in rigid:
        nodes = frames[f].nodes
        B = np.concatenate([np.broadcast_to(np.eye(3), (len(nodes), 3, 3)),
                            -skew(fe.coords[nodes] - frames[f].point)], axis=2)  # (k, 3, 6)
        rows.append(np.repeat(d * nodes[:, None] + np.arange(3), 6).ravel())
        cols.append(np.tile(zframe[f] + np.arange(6), 3 * len(nodes)))
        vals.append(B.ravel())
        rn, rc = np.nonzero(rot[nodes])  # the set's stiffened rotations are the frame's
        rows.append(d * nodes[rn] + 3 + rc), cols.append(zframe[f] + 3 + rc), vals.append(np.ones(rn.size))
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(d * n, n_z))
    Lr, Lc, Lv = [], [], []
    for f, fr in enumerate(frames):
        if fr.coupling == "rigid":
            Lr.append(6 * f + np.arange(6)), Lc.append(zframe[f] + np.arange(6)), Lv.append(np.ones(6))
        else:
            clash = fr.nodes[owner[fr.nodes] >= 0]
            if clash.size:
                raise ValueError(f"port {fr.name!r} (averaging) shares node {clash[0]} with the rigid set of port "
                                 f"{frames[owner[clash[0]]].name!r}")
            W = averaging_weights(fe.coords, fr)  # (6, 3k)
            zc = zof[(d * fr.nodes[:, None] + np.arange(3)).ravel()]
            Lr.append(np.repeat(6 * f + np.arange(6), zc.size)), Lc.append(np.tile(zc, 6)), Lv.append(W.ravel())
    L = sp.csr_matrix((np.concatenate(Lv), (np.concatenate(Lr), np.concatenate(Lc))), shape=(6 * len(frames), n_z))
    Uz = np.zeros((n_z, 6))
    node_of, comp_of = np.divmod(free_dofs, d)
    tr = comp_of < 3
    Uz[np.flatnonzero(tr)] = rigid_rows(fe.coords[node_of[tr]] - x_cm)[np.arange(tr.sum()), comp_of[tr]]
    Uz[np.flatnonzero(~tr), comp_of[~tr]] = 1.0  # a node's rotation dof c in the rigid rotation c
    for f in rigid:
        Uz[zframe[f] : zframe[f] + 3] = rigid_rows((frames[f].point - x_cm)[None])[0]
        Uz[zframe[f] + 3 : zframe[f] + 6, 3:] = np.eye(3)
    dof_node = np.full(n_z, -1)
    dof_node[:n_free] = node_of
    return Constraints(T, L, Uz, dof_node)
