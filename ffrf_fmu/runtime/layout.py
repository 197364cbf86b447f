"""Where the unknowns of a body live: the global vector, each superelement's local slots, the
superelement matrices stacked, and small helpers for named blocks of flat buffers.

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

    @classmethod
    def of(cls, data: BodyData) -> "Layout":
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
        return cls(N, E, nb, nm, n, nc, nv, ny, cfg_map, vel_map, free, rot_cols, lin_slots)

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
        ses = data.superelements
        return cls(
            K=np.stack([se.K for se in ses]), M=np.stack([se.M for se in ses]), G=np.stack([se.G for se in ses]),
            mass=np.array([se.mass for se in ses]), J0=np.stack([se.J0 for se in ses]),
            X_B=np.stack([se.X_B for se in ses]), nodes=np.stack([se.nodes for se in ses]).astype(int),
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

