"""A body's initial state (BodySystem.initialize): the reference configuration moved rigidly onto the
motion inputs, a rigid velocity field, optional port displacements relaxed to a static shape (a bordered
Newton system), and consistent rates ydot_0 from a backward-Euler micro-step. A mixin of
runtime/body.py's BodySystem, whose arrays (xN, RN, x0, R0, eta, v, yd) it sets. On the C runtime the
whole of it is one call (runtime/native/initial.c `ffrf_body_initialize`, the FMU's too) after the
inputs are read here; the steps below are the numpy path's, the oracle.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .coupling import add_springs
from .ports import PortValues, StepFailure
from .rotation import cross

# the backward-Euler micro-step of the consistent rates and the relaxation's Newton iterations at most (the C
# runtime's FFRF_MICRO_STEP in ffrf_runtime.h and FFRF_RELAX_MAX_ITER in initial.h: the same values)
MICRO_STEP = 1e-6
RELAX_MAX_ITER = 30


def no_equilibrium(t: float, displaced, max_iter: int, last: float) -> StepFailure:
    """The failure of a relaxation that found no static shape (numpy path and C runtime alike)."""
    return StepFailure(t, f"initial port displacements {sorted(displaced)}: no static equilibrium of the deformed "
                          f"body found ({max_iter} Newton iterations, last correction {last:.3g}); smaller "
                          "displacements, or ports whose displacements the body can hold")


class InitialConditions:
    """BodySystem's initial state; every attribute it reads and writes is BodySystem's."""

    def initialize(
        self,
        t0: float,
        inputs: dict[str, PortValues] | Callable[[float], dict[str, PortValues]],
        velocity=(0.0, 0.0, 0.0),
        angular_velocity=(0.0, 0.0, 0.0),
        port_displacements: dict[str, np.ndarray] | None = None,
        origin=(0.0, 0.0, 0.0),
    ) -> None:
        """Reference configuration moved rigidly onto the motion inputs, rigid velocity field
        v + w x (x - origin) (or the motion inputs' velocities), optional port offsets (an initial
        elastic deformation), then consistent rates ydot_0 from a backward-Euler micro-step."""
        fn = inputs if callable(inputs) else (lambda t, _v=inputs: _v)
        if self._compiled is not None:  # the whole of it in one call of the C runtime (runtime/native/initial.c)
            self._compiled.initialize(self, float(t0), fn, velocity, angular_velocity, origin, port_displacements)
            return
        self.reset_reference()
        self.t = float(t0)
        values = fn(t0)
        xN_p, RN_p, zN_p, f_in, t_in = self._read_inputs(t0, values)
        # rigid placement on the first motion-driven rotation (then translation) input
        R_rig, c_ref, c_new = np.eye(3), np.zeros(3), np.zeros(3)
        v_lin, w = np.asarray(velocity, float), np.asarray(angular_velocity, float)
        o = np.asarray(origin, float)
        for p in self.data.ports:
            if p.rotation == "motion":
                R_rig = RN_p[p.node]
                w = RN_p[p.node] @ zN_p[p.node, 3:6]
                break
        for p in self.data.ports:
            if p.translation == "motion":
                c_ref = self.data.node_positions[p.node]
                c_new = xN_p[p.node]
                v_lin, o = zN_p[p.node, 0:3], c_new
                break
        place = lambda X: c_new + (np.asarray(X) - c_ref) @ R_rig.T
        self.xN = place(self.xN)
        self.x0 = place(self.x0)
        self.RN = np.repeat(R_rig[None], len(self.xN), 0)
        self.R0 = np.repeat(R_rig[None], len(self.x0), 0)
        for name, u in (port_displacements or {}).items():
            self.xN[self.data.port(name).node] += np.asarray(u, float)
        if port_displacements:
            self._relax({name: np.asarray(u, float) for name, u in port_displacements.items()})
        vel = lambda x: v_lin + cross(w, x - o)
        zN, zS, v = self.split_rates(self.yd)  # views into self.yd
        zN[:, 0:3] = vel(self.xN)
        zN[:, 3:6] = w @ self.RN  # R^T w, body-axes rates of the rigid field
        zS[:, 0:3] = vel(self.x0)
        zS[:, 3:6] = w @ self.R0
        self.v[:, 0:3] = zS[:, 0:3]
        self.v[:, 3:6] = zS[:, 3:6]
        # r_bar = q_dot_bar of the rigid field (zero unless ports were displaced)
        self.v[:, 6:] = self.elastic_rates()
        if self.layout.nm:  # modal rates: the last nm entries of r_bar (kinematic rows k_q)
            zS[:, 6:] = self.v[:, -self.layout.nm :]
        n_cfg = zN.size + zS.size
        cfg_rates = self.yd[:n_cfg].copy()  # the rates of the configuration at t0, exact
        self.fN, self.tN = f_in.copy(), t_in.copy()
        # consistent ydot_0: a backward-Euler micro-step (am = af = gamma = 1) from the initial state
        delta = MICRO_STEP
        saved = self.get_state()
        yd0 = self._step(delta, fn, 1.0, 1.0, 1.0, commit_config=False)
        self.set_state(saved)
        # the micro-step's configuration rates are the velocities at t0 + delta, off by delta times the
        # acceleration (a body at rest under an initial tip load seemed to move, 1.76e-4 m/s per N on
        # B1): keep its velocity rates (accelerations), take the configuration rates at t0
        yd0[:n_cfg] = cfg_rates
        self.yd = yd0
        self.yd_prev = yd0.copy()
        self.yd_prev2 = yd0.copy()
        self.a = yd0.copy()
        F = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, self.v, self.yd, False)
        F[: 6 * self.layout.n_nodes] += self._loads(self.RN, f_in, t_in).ravel()
        if self._springs:
            self._read_inputs(t0, values)
            self._spring_loads[...] = 0.0
            p = np.zeros(self.layout.ny)
            p[: 6 * self.layout.n_nodes] = np.concatenate([self.xN, np.zeros_like(self.xN)], axis=1).ravel()
            add_springs(self._springs, p, self.yd, self.RN, F, None, 0.0, None, self._spring_loads)
        self._update_port_loads(F, f_in, t_in)
        self.power = self._external_power()
        self.work = 0.0
        self._lu = None

    def _relax(self, displaced: dict[str, np.ndarray], tol: float = 1e-12, max_iter: int = RELAX_MAX_ITER) -> None:
        """Static equilibrium (no inertia, no loads) with every undisplaced port's translation and rotation
        fixed, and each displaced port fixed only along its displacement u (a force along u moved it by
        |u|; across u it is free): the smooth deformed shape through displaced ports (for a free beam with
        its far end displaced, the cantilever shape), instead of a kink of the attachment modes at the
        displaced node. Holding a displaced port's whole translation would keep its distance to the other
        ports: a sideways u then stretches the body (B4, 1 SE: 0.0151 J of strain energy, the cantilever's
        bending being 0.0048 J), and the stretch rings the axial modes after the release.
        The constraints u.(x - x_start) = 0 enter as Lagrange multipliers (a bordered Newton system)."""
        L = self.layout
        relax = np.zeros(L.ny, dtype=bool)
        relax[: 6 * L.n_nodes + L.n_se * (6 + L.nm)] = True
        rows = []  # one constraint row per displaced port: its displacement direction
        for p in self.data.ports:
            u = np.asarray(displaced.get(p.name, np.zeros(3)), float)
            if np.linalg.norm(u) == 0.0:
                relax[6 * p.node : 6 * p.node + 3] = False
            else:
                c = np.zeros(L.ny)
                c[6 * p.node : 6 * p.node + 3] = u / np.linalg.norm(u)
                rows.append(c)
            if np.linalg.norm(u) == 0.0 or p.rotation == "motion":  # an undisplaced port, listed with zeros or not
                relax[6 * p.node + 3 : 6 * p.node + 6] = False
        idx = np.flatnonzero(relax)
        C = np.array(rows).reshape(len(rows), L.ny)[:, idx]
        zero_v, zero_yd = np.zeros_like(self.v), np.zeros(L.ny)
        delta = np.zeros(L.ny)
        for _ in range(max_iter):
            F, _, Fy = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, zero_v, zero_yd, True, gravity=False)
            J = np.bincount(self._flat_idx, Fy.ravel(), minlength=L.ny * L.ny).reshape(L.ny, L.ny)
            A = np.block([[J[np.ix_(idx, idx)], C.T], [C, np.zeros((len(C), len(C)))]])
            delta = np.zeros(L.ny)
            try:
                delta[idx] = np.linalg.solve(A, np.concatenate([-F[idx], np.zeros(len(C))]))[: len(idx)]
            except np.linalg.LinAlgError:  # the fixed parts leave the body a mechanism: no unique shape
                delta[:] = np.inf
            if not np.all(np.isfinite(delta)):
                break
            self.xN, self.RN, self.x0, self.R0, self.eta, _ = self._configuration(self.xN, self.RN, delta)
            if np.max(np.abs(delta)) < tol:
                return
        raise no_equilibrium(self.t, displaced, max_iter, float(np.max(np.abs(delta))))
