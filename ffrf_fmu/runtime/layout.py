"""Where the unknowns of a body live: the global vector, each superelement's local slots, the Newton
system's index maps (`newton_maps`), the superelement matrices stacked, and small helpers for named blocks
of flat buffers. A body read from the body cache brings its layout along (`Layout.remember`).

Unknowns (docs/background.md; geradin section 8.3, spatial coordinates)
    per boundary node P:   frame w_P = (x_P, R_P) (world position, rotation)
    per superelement e:    CM frame (x0, R0), modal amplitudes eta                    [configuration]
                           velocities v0 (world), Omega0 (body), r_bar = [r_B; r_eta] [independent field]
The global rate vector is ydot = [node zdot (6N) | SE zdot (6 + nm) E | SE vdot (6 + n) E] with
zdot = (xdot, W), W = R^T Rdot (body axes). The elastic boundary dofs q_B are not unknowns: eq. (89)
gives them from the frames (runtime/equations.py).

Local layout of one superelement (the rows and columns of its residual and Jacobian blocks):
    configuration columns (nc = 6 + nm + 6 nb): [x0, Theta0, eta, node p (x_P, Theta_P) ...]
    velocity columns      (nv = 6 + n):         [v0, Omega0, r_bar]
    rows (nv + nc): kinematic rows [k_x, k_T, k_q] on the velocity slots, then dynamic rows
                    [e_x0, e_T0, e_eta, node p (e_xP, e_TP) ...] on the configuration slots.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from .data import BodyData


@dataclass(frozen=True, eq=False)
class Layout:
    """Where each unknown lives in the global vector ydot = [node zdot (6N) | SE zdot (6+nm)E | SE v (nv)E]."""

    n_nodes: int
    n_se: int
    nb: int
    nm: int
    n: int  # reduced dofs per SE: 6 nb + nm
    nc: int  # local configuration-shaped size: 6 + nm + 6 nb
    nv: int  # local velocity size: 6 + n
    ny: int
    cfg_map: np.ndarray  # (E, nc) local [x0, Theta0, eta, node p (x, Theta)...] -> global
    vel_map: np.ndarray  # (E, nv)
    free: np.ndarray  # (ny,) bool: unknown (not prescribed by a motion input)
    rot_cols: np.ndarray  # (N + E, 3) global columns of every rotation rate (nodes then SEs)
    lin_slots: np.ndarray  # (3N + 3E + E nm + E nv,) the slots of the linear configuration xN, x0, eta, v, in that order
    maps: dict  # NEWTON_MAPS by name: the Newton system's (`newton_maps`; integrator.py `_build_newton`), the ports' codes

    @classmethod
    def of(cls, data: BodyData) -> "Layout":
        """The layout of a body: the one `remember`ed for it (read from the body cache with it), else computed."""
        known = _KNOWN.get(data)
        return known if known is not None else cls.compute(data)

    @classmethod
    def compute(cls, data: BodyData) -> "Layout":
        ses = data.superelements
        E, N = len(ses), len(data.node_positions)
        nb = len(ses[0].nodes)
        nm = ses[0].n - 6 * nb
        if any(se.n != ses[0].n or len(se.nodes) != nb for se in ses):
            raise ValueError("all superelements of a body must have the same boundary and mode counts")
        n, nc, nv = 6 * nb + nm, 6 + nm + 6 * nb, 6 + 6 * nb + nm
        se_cfg0 = 6 * N + np.arange(E) * (6 + nm)
        vel0 = 6 * N + E * (6 + nm) + np.arange(E) * nv
        nodes = np.array([se.nodes for se in ses], dtype=int)
        cfg_map = np.concatenate(
            [se_cfg0[:, None] + np.arange(6 + nm), (6 * nodes[:, :, None] + np.arange(6)).reshape(E, 6 * nb)], axis=1
        )
        vel_map = vel0[:, None] + np.arange(nv)
        ny = 6 * N + E * (6 + nm) + E * nv
        free = np.ones(ny, dtype=bool)
        for p in data.ports:
            if p.translation == "motion":
                free[6 * p.node : 6 * p.node + 3] = False
            if p.rotation == "motion":
                free[6 * p.node + 3 : 6 * p.node + 6] = False
        rot_cols = np.concatenate([6 * np.arange(N)[:, None] + 3 + np.arange(3), se_cfg0[:, None] + 3 + np.arange(3)])
        lin_slots = np.concatenate([(6 * np.arange(N)[:, None] + np.arange(3)).ravel(), cfg_map[:, 0:3].ravel(),
                                    cfg_map[:, 6 : 6 + nm].ravel(), vel_map.ravel()])
        motion_x = np.array([p.node for p in data.ports if p.translation == "motion"], dtype=int)
        motion_R = np.array([p.node for p in data.ports if p.rotation == "motion"], dtype=int)
        maps = newton_maps(N, E, nm, ny, cfg_map, vel_map, free, motion_x, motion_R)
        from .input_rule import port_codes  # (its modules import nothing of the body's)

        maps["port_node"], maps["port_mode"], maps["port_spring"] = port_codes(data.ports)
        maps["motion_parts"] = (~free[: 6 * N]).reshape(N, 2, 3).astype(float)  # 1 on motion-driven node dofs
        return cls(N, E, nb, nm, n, nc, nv, ny, cfg_map, vel_map, free, rot_cols, lin_slots, maps)

    _DIMS = ("n_nodes", "n_se", "nb", "nm", "n", "nc", "nv", "ny")
    _ARRAYS = ("cfg_map", "vel_map", "free", "rot_cols", "lin_slots")

    def arrays(self) -> dict[str, np.ndarray]:
        """The layout's arrays by name (its fields, then the maps as "maps.NAME")."""
        return {**{k: getattr(self, k) for k in self._ARRAYS}, **{f"maps.{k}": v for k, v in self.maps.items()}}

    def packed(self) -> tuple[dict, np.ndarray]:
        """The layout as (spec, words): its sizes and, per array, [dtype, shape, start, end] in words, one
        int64 array of every array's bytes (integers, floats by their bits, booleans a byte each, padded);
        `unpacked` views it back (the body cache's file, body_cache.py: one array to read, not one per map)."""
        spec, parts, offset = {"dims": [getattr(self, k) for k in self._DIMS]}, [], 0
        for name, a in self.arrays().items():
            a = np.ascontiguousarray(a)
            dtype, shape = a.dtype.str, list(a.shape)
            if dtype not in _WORDS:
                raise ValueError(f"layout array {name!r} of dtype {a.dtype}: not one of {sorted(_WORDS)}")
            if dtype == "|b1":  # its bytes, padded to whole words (`unpacked` views them)
                a = np.concatenate([a.ravel().view(np.uint8), np.zeros(-a.size % 8, dtype=np.uint8)])
            words = a.view(np.int64).ravel()
            spec[name] = [dtype, shape, offset, offset + words.size]
            parts.append(words)
            offset += words.size
        return spec, np.concatenate(parts)

    @classmethod
    def unpacked(cls, spec: dict, words: np.ndarray) -> "Layout":
        """The layout of `packed`'s (spec, words), read-only (a remembered layout is shared by the bodies
        made from its data)."""
        words = words.view()
        words.setflags(write=False)  # (its slices are read-only too)
        arrays = {}
        for name, entry in spec.items():
            if name == "dims":
                continue
            dtype, shape, start, end = entry
            a = words[start:end]
            if dtype != "<i8":
                a = a.view(_WORDS[dtype])
                if dtype == "|b1":
                    a = a[: math.prod(shape)]
            arrays[name] = a.reshape(shape)
        maps = {k[5:]: v for k, v in arrays.items() if k.startswith("maps.")}
        if len(maps) != len(NEWTON_MAPS) or any(k not in maps for k in NEWTON_MAPS):
            raise KeyError(f"layout maps {sorted(maps)}, not {sorted(NEWTON_MAPS)}")
        return cls(*spec["dims"], *(arrays[k] for k in cls._ARRAYS), maps)

    def remember(self, data: BodyData) -> None:
        """`of(data)` gives this layout from now on (for as long as data lives)."""
        _KNOWN[data] = self

    def stage(self, xN, x0, eta, v) -> np.ndarray:
        """The stage vector p (ny,) of a configuration: xN, x0, eta, v in their rate slots (lin_slots),
        zero in the rotation slots (the rotations travel as matrices beside it)."""
        p = np.zeros(self.ny)
        p[self.lin_slots] = np.concatenate([np.ravel(xN), np.ravel(x0), np.ravel(eta), np.ravel(v)])
        return p

    def linear(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """xN (N, 3), x0 (E, 3), eta (E, nm), v (E, nv) of a stage vector p (views of one copy of its
        lin_slots): the configuration `stage` puts there."""
        lin = p[self.lin_slots]
        N, E = self.n_nodes, self.n_se
        a, b = 3 * N, 3 * (N + E)
        c = b + E * self.nm
        return lin[:a].reshape(N, 3), lin[a:b].reshape(E, 3), lin[b:c].reshape(E, self.nm), lin[c:].reshape(E, self.nv)


_KNOWN: "weakref.WeakKeyDictionary[BodyData, Layout]" = weakref.WeakKeyDictionary()  # (`Layout.remember`)
_WORDS = {"<i8": np.dtype(np.int64), "<f8": np.dtype(np.float64), "|b1": np.dtype(bool)}  # (`Layout.packed`)

NEWTON_MAPS = ("rows", "cols", "flat_idx", "free_idx", "fixed_idx", "world_free", "world_idx", "newton_order",
               "newton_idx", "newton_flat", "newton_pos", "field_of", "field_perm", "field_starts", "motion_x",
               "motion_R", "motion_x_slots", "motion_T_slots", "stage_mask", "torque_nodes", "torque_pos",
               # the ports' (node, mode, spring) codes (input_rule.port_codes) and the motion-driven node dofs
               "port_node", "port_mode", "port_spring", "motion_parts")


def newton_maps(N, E, nm, ny, cfg_map, vel_map, free, motion_x, motion_R) -> dict[str, np.ndarray]:
    """Index maps of the Newton system (NEWTON_MAPS; integrator.py `_build_newton` sets them on the body as
    `_rows`, `_cols` ...): the unknowns (free rates), their order in the stored factorization, and where every
    local Jacobian entry lands in the iteration matrix. They depend on the body only (its layout and which
    port parts are motion-driven)."""
    m = {}
    # global (row, col) index pairs of every local Jacobian entry, for one scatter-add
    rows = np.concatenate([vel_map, cfg_map], axis=1)
    cols = np.concatenate([cfg_map, vel_map], axis=1)
    m["rows"], m["cols"] = rows, cols
    m["flat_idx"] = (rows[:, :, None] * ny + cols[:, None, :]).ravel()
    m["free_idx"] = free_idx = np.flatnonzero(free)
    m["fixed_idx"] = np.flatnonzero(~free)  # rates prescribed by motion inputs (node rows only)
    # world-axes triplets among the unknowns: node positions, CM positions, CM velocities
    world = np.zeros(ny, dtype=bool)
    world[(6 * np.arange(N)[:, None] + np.arange(3)).ravel()] = True
    world[cfg_map[:, 0:3].ravel()] = True
    world[vel_map[:, 0:3].ravel()] = True
    pos = np.cumsum(free) - 1  # index of each unknown among the free ones
    m["world_free"] = trip = pos[np.flatnonzero(world & free)].reshape(-1, 3)
    m["world_idx"] = np.flatnonzero(world).reshape(-1, 3)  # every world triplet of ydot (predictor)
    # Newton unknowns ordered world triplets first, so that the frame rotation of `_solve` acts on
    # one contiguous block; the stored factorization uses this order
    in_trip = np.zeros(free_idx.size, dtype=bool)  # (a mask, not np.setdiff1d: np.unique imports numpy.ma,
    in_trip[trip.ravel()] = True  # 20 ms of a CLI run's set-up)
    rest = np.flatnonzero(~in_trip)
    m["newton_order"] = order = np.concatenate([trip.ravel(), rest])
    m["newton_idx"] = newton_idx = free_idx[order]
    # every local Jacobian entry -> flat position in the Newton-ordered matrix (nf * nf: not an unknown)
    nf = newton_idx.size
    newton_pos = np.full(ny + 1, nf)
    newton_pos[newton_idx] = np.arange(nf)
    r, c = newton_pos[rows][:, :, None], newton_pos[cols][:, None, :]
    m["newton_flat"] = np.where((r < nf) & (c < nf), r * nf + c, nf * nf).ravel()
    m["newton_pos"] = newton_pos = newton_pos[:ny]
    # fields of the unknowns (`_field_scale`): translation rates, rotation rates, modal rates, CM
    # accelerations, angular accelerations, elastic velocity rates; Newton order
    field = np.zeros(ny, dtype=int)
    field[(6 * np.arange(N)[:, None] + 3 + np.arange(3)).ravel()] = 1
    field[cfg_map[:, 3:6].ravel()] = 1
    field[cfg_map[:, 6 : 6 + nm].ravel()] = 2
    field[vel_map[:, 0:3].ravel()] = 3
    field[vel_map[:, 3:6].ravel()] = 4
    field[vel_map[:, 6:].ravel()] = 5
    f_newton = field[newton_idx]
    present = np.flatnonzero(np.bincount(f_newton, minlength=6))  # the fields that have unknowns (a field may have
    # none, e.g. no modes), sorted; as np.unique, without its import of numpy.ma
    m["field_of"] = field_of = np.searchsorted(present, f_newton)
    m["field_perm"] = newton_idx[np.argsort(field_of, kind="stable")]
    m["field_starts"] = np.searchsorted(np.sort(field_of), np.arange(len(present)))
    node_x = 6 * np.arange(N)[:, None] + np.arange(3)
    # stage: p = c * ydot + P0 with c = beta except on configuration slots set by motion inputs
    m["motion_x"], m["motion_R"] = motion_x, motion_R
    m["motion_x_slots"] = node_x[motion_x].ravel()
    m["motion_T_slots"] = (node_x + 3)[motion_R].ravel()
    stage_mask = np.ones(ny)
    stage_mask[m["motion_x_slots"]] = 0.0
    stage_mask[m["motion_T_slots"]] = 0.0
    m["stage_mask"] = stage_mask
    # the free node rotations (the load term of `_iteration_matrix`): node k, its rows in the Newton order
    torque = [k for k in range(N) if free[6 * k + 3]]
    m["torque_nodes"] = np.array(torque, dtype=int)
    m["torque_pos"] = np.array([newton_pos[6 * k + 3 : 6 * k + 6] for k in torque], dtype=newton_pos.dtype).reshape(-1, 3)
    return m


@dataclass(frozen=True, eq=False)
class SuperelementStack:
    """The reduced matrices of every superelement, stacked on a leading axis E (geradin section 7):
    K_bar, M_bar (76), G_k = Y^T M_k Y (53), mass m, inertia J0 about the CM (13), boundary node
    positions X_B relative to the CM (body axes) and the global indices of the boundary nodes."""

    K: np.ndarray  # (E, n, n)
    M: np.ndarray  # (E, n, n)
    G: np.ndarray  # (E, 3, n, n)
    mass: np.ndarray  # (E,)
    J0: np.ndarray  # (E, 3, 3)
    X_B: np.ndarray  # (E, nb, 3)
    nodes: np.ndarray  # (E, nb) int

    @classmethod
    def of(cls, data: BodyData) -> "SuperelementStack":
        ses = data.superelements  # (np.array of the list: np.stack's Python layer costs 5 us a call)
        return cls(
            K=np.array([se.K for se in ses]), M=np.array([se.M for se in ses]), G=np.array([se.G for se in ses]),
            mass=np.array([se.mass for se in ses]), J0=np.array([se.J0 for se in ses]),
            X_B=np.array([se.X_B for se in ses]), nodes=np.array([se.nodes for se in ses]).astype(int),
        )


def view(a: np.ndarray, shape) -> np.ndarray:
    """a reshaped WITHOUT a copy (writes through the result must reach a); raises if impossible."""
    v = a.reshape(shape)
    if not np.may_share_memory(v, a):
        raise ValueError(f"internal: reshaping {a.shape} to {shape} would copy")
    return v


class Segments:
    """Named consecutive blocks of a flat vector, e.g. Segments(q=18, rho=(2, 3)): `seg["rho"]` is
    the slice, `seg.view(a, "rho")` the block of a (..., size) array as a (..., 2, 3) view."""

    def __init__(self, **shapes):
        self.slices, self.shapes, i = {}, {}, 0
        for name, shape in shapes.items():
            shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
            size = int(math.prod(shape))  # (math: np.prod costs 8 us a call, 50 calls a body's set-up)
            self.slices[name], self.shapes[name] = slice(i, i + size), shape
            i += size
        self.size = i

    def __getitem__(self, name: str) -> slice:
        return self.slices[name]

    def view(self, a: np.ndarray, name: str) -> np.ndarray:
        return view(a[..., self.slices[name]], a.shape[:-1] + self.shapes[name])

