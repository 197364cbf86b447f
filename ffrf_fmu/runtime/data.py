"""Reduced body data: everything a body needs at run time, nothing of the FE model.

This is what an FMU carries in its resources (saved with `save`/`load` as one .npz): a partner
receives reduced matrices only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .damping import Damping


@dataclass(frozen=True, eq=False)
class SuperelementData:
    """One reduced superelement (geradin section 7), body axes = model axes, origin at its CM.

    Reduced coordinates q_bar = [q_B; eta] (eq. 76): q_B holds 6 dofs per boundary node
    (d_x, d_y, d_z, alpha_x, alpha_y, alpha_z), nodes in the order of `nodes`, then the modal
    amplitudes eta.
    """

    mass: float
    J0: np.ndarray  # (3, 3) inertia about the CM, eq. (13)
    x_cm: np.ndarray  # (3,) reference CM position in world axes
    X_B: np.ndarray  # (nb, 3) boundary node positions relative to the CM
    nodes: np.ndarray  # (nb,) global boundary node indices
    K: np.ndarray  # (n, n) K_bar = Y^T K Y
    M: np.ndarray  # (n, n) M_bar = Y^T M Y
    G: np.ndarray  # (3, n, n) G_k = Y^T M_k Y, M_k = int N^T skew(e_k) N rho dV
    frequencies_hz: np.ndarray  # (n_modes,) free-free frequencies of the kept modes
    # geometric stiffening (docs/equations.md, "Geometric stiffening"); None when built without it.
    # The last n_correction columns of eta are then static correction modes, not vibration modes.
    W1: np.ndarray | None = None  # (n, 3, 3) Witteveen W1_j: inertia I0 + sum_j q_j W1_j, load f0_j = w^T W1_j w / 2
    vk_a: np.ndarray | None = None  # (r, n) membrane strain eps_k = a_k q + 1/2 q^T B_k q, r strain shapes
    vk_B: np.ndarray | None = None  # (r, n, n)
    W2: np.ndarray | None = None  # (n, n, 3, 3) Witteveen W2_jl (term set `full`): inertia + q^T W2 q

    @property
    def n_boundary(self) -> int:
        return 6 * len(self.nodes)

    @property
    def n(self) -> int:
        return self.K.shape[0]

    @property
    def stiffening(self) -> bool:
        return self.vk_a is not None


_OPTIONAL = ("W1", "vk_a", "vk_B", "W2")  # stiffening data, present only when built with it


@dataclass(frozen=True)
class PortData:
    name: str
    node: int
    translation: str  # "motion" | "force" | "compliant" (runtime/coupling.py)
    rotation: str
    compliance: tuple = ()  # compliant parts: 12 floats K_t, C_t, K_r, C_r (3 each), else ()


@dataclass(frozen=True, eq=False)
class BodyData:
    name: str
    superelements: tuple[SuperelementData, ...]
    node_positions: np.ndarray  # (n_nodes, 3) reference boundary node positions, world axes
    ports: tuple[PortData, ...]
    damping: Damping | None = None  # structural damping (runtime/damping.py), from the model file

    def port(self, name: str) -> PortData:
        for p in self.ports:
            if p.name == name:
                return p
        raise KeyError(f"body {self.name!r} has no port {name!r}; ports: {[p.name for p in self.ports]}")

    def save(self, path) -> None:
        import json

        arrays, meta = self.arrays()
        np.savez(path, meta=np.array(json.dumps(meta)), **arrays)

    @classmethod
    def load(cls, path) -> "BodyData":
        import json

        with np.load(path, allow_pickle=False) as z:
            return cls.from_arrays(z, json.loads(str(z["meta"])))

    def arrays(self) -> tuple[dict[str, np.ndarray], dict]:
        """The body as named arrays and a JSON-able meta dict (`save`'s .npz, body_cache's file)."""
        arrays = {"node_positions": self.node_positions}
        for i, se in enumerate(self.superelements):
            for key in ("J0", "x_cm", "X_B", "nodes", "K", "M", "G", "frequencies_hz") + _OPTIONAL:
                if getattr(se, key) is not None:
                    arrays[f"se{i}_{key}"] = getattr(se, key)
            arrays[f"se{i}_mass"] = np.asarray(se.mass, dtype=float).reshape(())  # one value (a stiffened body's is (1,))
        meta = {
            "name": self.name,
            "n_se": len(self.superelements),
            "ports": [[p.name, p.node, p.translation, p.rotation, list(p.compliance)] for p in self.ports],
            "damping": self.damping.as_meta() if self.damping is not None else None,
        }
        return arrays, meta

    @classmethod
    def from_arrays(cls, z, meta: dict) -> "BodyData":
        """The body of `arrays` (z: a mapping of the names to arrays) and its meta."""
        ses = tuple(
            SuperelementData(
                mass=float(np.ravel(z[f"se{i}_mass"])[0]),
                **{k: z[f"se{i}_{k}"] for k in ("J0", "x_cm", "X_B", "nodes", "K", "M", "G", "frequencies_hz")},
                **{k: z[f"se{i}_{k}"] for k in _OPTIONAL if f"se{i}_{k}" in z},
            )
            for i in range(meta["n_se"])
        )
        return cls(
            name=meta["name"],
            superelements=ses,
            node_positions=z["node_positions"],
            ports=tuple(PortData(n, int(k), t, r, tuple(float(x) for x in (c[0] if c else ())))
                        for n, k, t, r, *c in meta["ports"]),
            damping=Damping.from_meta(meta.get("damping")),
        )


@dataclass(frozen=True, eq=False)
class ReducedBody:
    """A body reduced (reduction.reduce_body): `data` what the runtime steps (BodyData), `reductions` one
    reduction per superelement (reduction.Reduction, a solid's reduction_sparse.SolidReduction: its basis
    Y, rigid modes U and the checks of its reduction)."""

    data: BodyData
    reductions: tuple
