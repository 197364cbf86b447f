"""Interface frames of a solid: a frame attached to a node set, coupled rigidly or by averaging.

Node sets (`select`): a named set of the mesh or export, or a geometric selection of FE nodes:
    plane    {point, normal, tol}        |(X - point) . n| <= tol
    cylinder {point, axis, radius, tol}  | |(X - point) x a| - radius | <= tol
    box      {min, max}                  min <= X <= max (componentwise)
    near     {point | set, radius, normal}  within radius of the point (of any node of the named set);
                                         with normal: only in the plane through it (the first set node)
Coupling (docs/solids.md):
    rigid      (RBE2): the set moves as a rigid body with the frame, u_i = u_f + theta_f x (X_i - X_f);
               stiffens the body near the port.
    averaging  (RBE3): the frame follows the weighted least-squares rigid fit of the set's motion,
               (u_f, theta_f) = (A^T D A)^-1 A^T D u_S, A_i = [I, -(X_i - X_f)~], D = diag(weights);
               the set deforms freely; the frame's load is spread on the set as W^T f (same virtual work).
Both reproduce a rigid motion of the set exactly (the frame then moves with it).
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from ..runtime.rotation import skew

COUPLINGS = ("rigid", "averaging")
SELECTIONS = ("set", "plane", "cylinder", "box", "near")


@dataclass(frozen=True)
class Frame:
    """One interface frame: its name (the port's), node indices of the set, coupling, origin X_f."""

    name: str
    nodes: np.ndarray  # (k,) FE node indices
    coupling: str  # "rigid" | "averaging"
    point: np.ndarray  # (3,) frame origin [m], model axes


def _unit(v, what):
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v)
    if v.shape != (3,) or n == 0.0:
        raise ValueError(f"{what}: expected 3 numbers, not all zero")
    return v / n


def select_nodes(coords: np.ndarray, node_sets: dict, select: dict, scale: float) -> np.ndarray:
    """Node indices of a selection (module doc). scale: the body size [m] for the default tolerance
    1e-6 scale. Raises ValueError naming the selection when it is unknown or empty."""
    kinds = [k for k in SELECTIONS if k in select]
    if len(kinds) != 1:
        raise ValueError(f"expected exactly one of {', '.join(SELECTIONS)} in a selection, got {sorted(select)}")
    kind, v = kinds[0], select[kinds[0]]
    X = np.asarray(coords, dtype=float)
    tol = float(v.get("tol", 1e-6 * scale)) if isinstance(v, dict) else 0.0
    if kind == "set":
        if v not in node_sets:
            raise ValueError(f"no node set {v!r} (sets of this mesh: {sorted(node_sets) or 'none'})")
        idx = np.asarray(node_sets[v], dtype=int)
    elif kind == "plane":
        n = _unit(v["normal"], "plane.normal")
        idx = np.flatnonzero(np.abs((X - np.asarray(v["point"], float)) @ n) <= tol)
    elif kind == "cylinder":
        a = _unit(v["axis"], "cylinder.axis")
        r = np.linalg.norm(np.cross(X - np.asarray(v["point"], float), a), axis=1)
        idx = np.flatnonzero(np.abs(r - float(v["radius"])) <= tol)
    elif kind == "box":
        lo, hi = np.asarray(v["min"], float), np.asarray(v["max"], float)
        idx = np.flatnonzero(np.all((X >= lo - tol) & (X <= hi + tol), axis=1))
    else:  # near
        if "set" in v:
            if v["set"] not in node_sets:
                raise ValueError(f"near.set: no node set {v['set']!r} (sets: {sorted(node_sets) or 'none'})")
            centres = X[np.asarray(node_sets[v["set"]], dtype=int)]
        else:
            centres = np.asarray(v["point"], float)[None]
        d = np.min(np.linalg.norm(X[:, None, :] - centres[None], axis=2), axis=1) if len(centres) < 64 else \
            np.array([np.linalg.norm(centres - x, axis=1).min() for x in X])
        near = d <= float(v["radius"]) + tol
        if "normal" in v:  # only in the plane through the centre(s) with this normal (a face around a named node)
            n = _unit(v["normal"], "near.normal")
            near &= np.abs((X - centres[0]) @ n) <= tol
        idx = np.flatnonzero(near)
    if idx.size == 0:
        raise ValueError(f"selection {kind} = {v!r} holds no node")
    return np.unique(idx)


def check_set(frame: Frame, coords: np.ndarray, rotations: bool = False) -> None:
    """A frame needs a set that fixes 6 rigid dofs: at least 3 nodes, not on one line (else its
    rotation about that line is undetermined, for either coupling). rotations: the set's nodes have
    rotation dofs and the link is rigid (they take the frame's rotation): any set will do."""
    if rotations and len(frame.nodes) and frame.coupling == "rigid":
        return
    X = coords[frame.nodes] - frame.point
    A = np.concatenate([np.tile(np.eye(3), (len(X), 1)), -skew(X).reshape(-1, 3)], axis=1)
    s = np.linalg.svd(A, compute_uv=False)
    if len(frame.nodes) < 3 or s[-1] < 1e-8 * s[0]:
        raise ValueError(f"port {frame.name!r}: its node set ({len(frame.nodes)} node(s)) does not fix a frame's "
                         "rotation; select at least 3 nodes not on one line (a face, a seat)")


def averaging_weights(coords: np.ndarray, frame: Frame, weights=None) -> np.ndarray:
    """W (6, 3k): (u_f, theta_f) = W u_S, the weighted least-squares rigid fit (module doc); weights
    (k,) default 1. W A = I: a rigid motion of the set is reproduced exactly."""
    X = coords[frame.nodes] - frame.point
    k = len(X)
    A = np.concatenate([np.tile(np.eye(3), (k, 1)), -skew(X).reshape(-1, 3)], axis=1)  # (3k, 6)
    w = np.ones(k) if weights is None else np.asarray(weights, dtype=float)
    Dw = np.repeat(w, 3)
    return np.linalg.solve(A.T @ (Dw[:, None] * A), (A * Dw[:, None]).T)


def solid_frames(spec, fe) -> tuple[Frame, ...]:
    """The port frames of a SolidSpec (model/solid.py) on its FE model (a SolidFE): node selections, link, origin."""
    scale = float(np.linalg.norm(fe.coords.max(0) - fe.coords.min(0)))
    out = []
    for f in spec.frames:
        try:
            nodes = select_nodes(fe.coords, fe.node_sets, json.loads(f.select), scale)
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"port {f.port!r}: {e}") from None
        point = np.asarray(f.point, dtype=float) if f.point is not None else fe.coords[nodes].mean(0)
        out.append(Frame(f.port, nodes, f.link, point))
    return tuple(out)
