"""A Nastran deck as the reduction's input: the SolidFE on 6 dofs per node (solid/__init__.py) of
read_nastran's K and M, whose mass is split into the node-block mass of the translations and mass
points (solid/nastran_mass.py: shell fibres, CONM2 offsets and inertias, beam rotary inertia and the
consistent beam mass); six_dof_fe checks that the split adds up to M (docs/nastran.md).

The body floats: the deck's SPCs are not applied (the floating frame carries the rigid motion); the
GRIDs whose three translations an SPC fixes are the node set "spc" (a natural port: where the deck
was held; SPCs of rotations only, as on the GRIDs of bricks, make no port). Node sets, by GRID id:
each SET1 card of the deck as "SET1 <sid>", and `node_sets` (name -> GRID ids) given here.
"""
from __future__ import annotations

import numpy as np

from . import SolidFE, six_dof_fe
from .nastran import NastranError, read_nastran


def nastran_body(path, node_sets=None) -> SolidFE:
    """The SolidFE (dofs_per_node 6, M_scalar, mass_points) of the deck at `path` (module doc);
    node_sets: name -> GRID ids, added to the deck's "spc" and "SET1 <sid>" sets."""
    fe = read_nastran(path)
    if fe.T is not None:
        raise NastranError(f"{fe.path}: RBE2/RBE3 (dependent dofs {len(fe.mpc_dofs)}) are not supported in a body: "
                           "its nodes keep 6 dofs each; a rigid port is a node set (SET1) of the reduction instead")
    held = np.zeros((len(fe.node_ids), 6), dtype=bool)
    held.reshape(-1)[fe.spc_dofs] = True
    sets = {"spc": np.flatnonzero(held[:, :3].all(axis=1))}
    for name, grids in {**{k: v for k, v in fe.grid_sets.items() if k != "spc"}, **(node_sets or {})}.items():
        grids = np.asarray(list(grids), dtype=int)
        a = np.searchsorted(fe.node_ids, grids)
        bad = (a >= len(fe.node_ids)) | (fe.node_ids[np.minimum(a, len(fe.node_ids) - 1)] != grids)
        if np.any(bad):
            raise NastranError(f"{fe.path}: node set {name!r}: no GRID {grids[bad].tolist()} in the deck")
        sets[name] = a
    return six_dof_fe(fe.coords, fe.K, fe.M, fe.M_scalar, fe.mass_points, sets, source=fe.path, cells=fe.cells)
