"""Time integration of a body: first-order generalized-alpha on the Lie group, Newton on the rates,
modified Newton with the factorization carried along the rigid rotation (docs/background.md;
docs/equations.md, "Integrator").

Jansen-Whiting-Hulbert generalized-alpha in the linear multistep form of Bruls & Arnold (2008),
equations enforced at t_{n+1}:
    am a_{n+1} + (1 - am) a_n = af ydot_{n+1} + (1 - af) ydot_n
    y_{n+1} = y_n (+) h [(1 - gamma) a_n + gamma a_{n+1}]      (R <- R exp(h Delta) on SO(3))
    F(ydot_{n+1}, y_{n+1}, t_{n+1}) = 0
am = (3 - rho)/(2 (1 + rho)), af = 1/(1 + rho), gamma = 1/2 + am - af. Newton on ydot_{n+1} with
the analytic iteration matrix F_ydot + beta [F_y T, F_v], beta = h gamma af / am, T the SO(3)
tangent operator; the factorization is kept across iterations and steps while Newton contracts and
the predictor hits or misses by far, and rebuilt at the predictor after a step that needed two or
three iterations on a near miss (runtime/newton.py: the iteration, its convergence test and that policy).
The predictor extrapolates the rates with their world-axes triplets carried along with the body.

Within a step, a_{n+1} and the configuration are affine in ydot_{n+1}: p = beta ydot + P0 for
positions, eta and v, R = R_n exp(beta W + ...) for rotations (`_prepare_step` computes P0 and R_n
once), so a Newton iteration is one stage (a multiply-add and the exponentials) and one residual.

`GeneralizedAlpha` is the stepping half of `body.BodySystem` (a mixin: it works on the body's
state and its inputs), over `newton.ModifiedNewton`. This is the numpy path; its equations are the
oracle's (runtime/assembly.py); runtime/native/step.c is the C runtime's twin.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .coupling import add_springs
from .input_rule import extrapolate
from .ports import IterationCapReached, NotConverged, PortValues, StepFailure
from .factorization import is_native
from .newton import KEEPS, SERVES, ModifiedNewton
from .rotation import expm, skew, tangent


def alpha_coefficients(rho_inf: float) -> tuple[float, float, float]:
    """(am, af, gamma) of the first-order generalized-alpha method (JWH 2000) from rho_inf."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf))
    af = 1.0 / (1.0 + rho_inf)
    return am, af, 0.5 + am - af


class GeneralizedAlpha(ModifiedNewton):
    """Stepping of a body (see the module docstring); the state lives on the body."""

    def _build_newton(self):
        """Index maps of the Newton system (runtime/layout.py `newton_maps`, the body's layout's) as the body's
        attributes, and the buffers of a Newton iteration's stage."""
        L, m = self.layout, self.layout.maps
        self._rows, self._cols, self._flat_idx = m["rows"], m["cols"], m["flat_idx"]
        self._free_idx, self._fixed_idx = m["free_idx"], m["fixed_idx"]
        self._world_free, self._world_idx = m["world_free"], m["world_idx"]
        self._newton_order, self._newton_idx, self._newton_flat = m["newton_order"], m["newton_idx"], m["newton_flat"]
        self._newton_pos = m["newton_pos"]
        self._field_of, self._field_perm, self._field_starts = m["field_of"], m["field_perm"], m["field_starts"]
        self._motion_x_slots, self._motion_T_slots = m["motion_x_slots"], m["motion_T_slots"]
        # stage: p = c * ydot + P0 with c = beta except on configuration slots set by motion inputs
        self._stage_mask = m["stage_mask"]
        self._stage_beta = None
        # the stage of a Newton iteration (`_stage_at`): the configuration p in the ydot layout (rotation
        # slots: the increments h Delta), and the rates the Newton iteration updates in place (`_step`)
        self._stage_p, self._newton_yd = np.zeros(L.ny), np.zeros(L.ny)
        self._lu = None
        self._torque_rows = [(int(k), pos) for k, pos in zip(m["torque_nodes"], m["torque_pos"])]

    def step(self, h: float, inputs: Callable[[float], dict[str, PortValues]]) -> int:
        """Advance by one step h; returns the Newton iterations; raises StepFailure."""
        am, af, gamma = self.coefficients
        if self._compiled is not None:
            return self._compiled.step(self, h, inputs, am, af, gamma)
        return self._step(h, inputs, am, af, gamma, commit_config=True)

    def run_schedule(self, h: float, schedule: tuple, rows: np.ndarray, times: np.ndarray):
        """len(rows) steps of h in one call of the C runtime (backend native only), with the inputs a scene's
        schedule tabulates (simulate.scene_schedule) evaluated inside it and every step recorded in
        rows (simulate.record's layout) and times. Returns (steps completed, StepFailure or None)."""
        if self._compiled is None:
            raise ValueError("run_schedule needs the native backend (this body runs on numpy)")
        am, af, gamma = self.coefficients
        return self._compiled.run(self, h, schedule, rows, times, am, af, gamma)

    def run_extrapolated(self, h: float, n: int, t_c: float, values: np.ndarray, row: np.ndarray | None = None) -> int:
        """n steps of h with the inputs extrapolated from the point values at t_c (runtime/input_rule.py; one row of
        `values` per port, input_rule.COLUMNS): an FMU's communication step. On the native backend in ONE call
        of the C runtime with the extrapolation inside; otherwise one `step` call
        per step with input_rule.extrapolate, its numpy twin. Returns the most Newton iterations of a step; raises
        StepFailure (the state then is that of the last completed step). row, if given, receives
        `output_row` at the end."""
        compiled = self._compiled
        if compiled is not None:
            am, af, gamma = self.coefficients
            buf = row if row is not None else np.empty(compiled.row_size)
            done, worst, exc = compiled.run_extrapolated(self, h, n, t_c, values, buf, am, af, gamma)
            if exc is not None:
                raise exc
            return worst
        inputs, worst = extrapolate(self.data.ports, values, t_c), 0
        for _ in range(n):
            worst = max(worst, self.step(h, inputs))
        if row is not None:
            row[:] = self.output_row()
        return worst

    def newton_system(self, yd, h, values, coefficients=None, jacobian=True):
        """(F, J) restricted to the unknowns for rates yd at t + h (J = F_ydot + beta [F_y T, F_v])."""
        am, af, gamma = coefficients or self.coefficients
        self._prepare_step(self.t + h, h, values, am, af, gamma)
        fi = self._free_idx
        if not jacobian:
            return self._residual_at(yd)[fi]
        F, J = self._residual_at(yd, jacobian=True, beta=h * gamma * af / am)
        pos = self._newton_pos[fi]
        return F[fi], J[np.ix_(pos, pos)]

    def _step(self, h, inputs, am, af, gamma, commit_config):
        t1 = self.t + h
        if not (h > 0.0 and np.isfinite(h)):
            raise StepFailure(self.t, f"step size must be positive and finite, got {h}")
        zN_p, f_in, t_in = self._prepare_step(t1, h, inputs(t1), am, af, gamma)
        # predictor: rates extrapolated quadratically from the last three steps, world triplets carried
        # along with the body (`_commit` keeps the history co-rotated; `_predicted_rotation`): in world
        # axes a vector turning with the body is missed by (omega h)^3 |v|, on B1 at 20 ms 1000x the
        # rest of the miss (docs/equations.md, "Integrator"). Newton iterates on yd in place
        yd = self._newton_yd
        beta = h * gamma * af / am
        if commit_config:
            np.subtract(self.yd, self.yd_prev, out=yd)
            yd *= 3.0
            yd += self.yd_prev2
            self._rotate_world(yd, self._predicted_rotation(yd, beta))
        else:
            yd[:] = self.yd
        fixed = self._fixed_idx
        yd[fixed] = zN_p.ravel()[fixed]
        dropped, trusted = False, False  # (REFRESH_AFTER)
        if is_native(self._lu):  # the C runtime's factors are not LAPACK's: a fresh matrix
            self._lu = None
        replay = next(self.newton_replay.decisions) if commit_config and self.newton_replay is not None else None
        if (commit_config and self.REFRESH_AFTER[0] <= self.iterations <= self.REFRESH_AFTER[1] and self._lu is not None
                and self._lu[4] != KEEPS):
            if self._lu[4] == SERVES:
                trusted = True
            else:
                dropped = True
                if replay is None:  # (a replay decides the refresh: `_newton`)
                    self._lu = None
        # the cap (iteration_cap): step.c bounds its loops by it; here a step fails when it needed more, which is
        # the same verdict (a bounded Newton converges exactly when the unbounded one did within the bound)
        cap = self.iteration_cap if commit_config and 0 < self.iteration_cap < 2 * self.max_iter else 0
        try:
            if replay is not None and replay.iterations > self.max_iter:
                raise StepFailure(t1, "the replayed run's first attempt failed")
            F, it = self._newton(yd, beta, t1, dropped, trusted, replay)
        except StepFailure as exc:
            if not commit_config:
                raise
            if 0 < cap <= self.max_iter:  # no iteration left for a retry (step.c: the cap only for not converged)
                self._lu = None
                if isinstance(exc, NotConverged):
                    raise IterationCapReached(t1, cap) from None
                raise
            # one retry from the last step's rates with a fresh matrix: an extrapolation across a jump
            # (a load switched on, unresolved modes at a large step) can start Newton outside its basin
            # (B2 at h = 0.2 s, rho_inf = 0.8: fails at t = 19.6 s without, completes with it)
            yd[:] = self.yd
            yd[fixed] = zN_p.ravel()[fixed]
            self._lu = None
            try:
                F, it = self._newton(yd, beta, t1, replay=replay and replay.retry(self.max_iter))
            except NotConverged:
                if cap:  # the retry ran out within the cap's iterations (step.c FFRF_ITERATION_CAP)
                    raise IterationCapReached(t1, cap) from None
                raise
            it += self.max_iter  # the failed attempt's iterations count
        if 0 < cap < it:
            self._lu = None
            raise IterationCapReached(t1, cap)
        self._check_rotation_increments(t1)
        if not commit_config:
            return yd.copy()
        self._commit(yd.copy())
        self.t, self.iterations = t1, it
        self._update_port_loads(F, f_in, t_in)
        p_new = self._external_power()
        self.work += 0.5 * h * (self.power + p_new)
        self.power = p_new
        return it

    def _check_rotation_increments(self, t1):
        """A rotation increment h Delta of more than pi over one step is beyond the exponential map's
        injectivity: such a Newton root (e.g. after an absurd input) is an alias, not the motion."""
        theta = self._stage_p[self.layout.rot_cols]
        if float(np.max(np.einsum("ij,ij->i", theta, theta))) > np.pi**2:
            self._lu = None
            raise StepFailure(t1, "a rotation increment over the step exceeds pi (step too large for the motion, "
                                  "or an absurd input)")

    def _predicted_rotation(self, yd, beta):
        """World rotation of the first CM frame over the step, from the predicted rates yd:
        R_n exp(h Delta) R_n^T with h Delta = beta ydot + D0 (the stage of `_prepare_step`)."""
        _, P0, _, _, _ = self._stage
        slot = self.layout.rot_cols[self.layout.n_nodes]
        R = self.R0[0]
        return R @ expm((beta * yd[slot] + P0[slot])[None])[0] @ R.T

    def _rotate_world(self, y, Q):
        """Every world-axes triplet of the ydot-layout vector y rotated by Q, in place."""
        w = y[self._world_idx]
        y[self._world_idx] = w @ Q.T

    def _commit(self, yd):
        """The configuration of the last residual evaluation and the rates yd become the state."""
        L, R = self.layout, self._R
        _, _, _, af_am, A0 = self._stage
        self.xN, self.x0, self.eta, self.v = L.linear(self._stage_p)
        Q = R[L.n_nodes] @ self.R0[0].T  # rotation of the first CM frame over the step
        self.RN, self.R0 = R[: L.n_nodes], R[L.n_nodes :]
        # the history of the rates, world triplets carried along with the body (predictor, `_step`)
        self.yd_prev2 = self.yd_prev
        self._rotate_world(self.yd_prev2, Q)
        self.yd_prev = self.yd.copy()
        self._rotate_world(self.yd_prev, Q)
        self.a = af_am * yd + A0
        self.yd = yd

    def _configuration(self, xN_pres, RN_pres, delta_h):
        """Configuration at t_{n+1} from the increment h*Delta (global ydot layout); prescribed nodes from inputs."""
        L = self.layout
        dN, dS, dv = self.split_rates(delta_h)
        rot = expm(np.concatenate([dN[:, 3:6], dS[:, 3:6]]))
        xN = self.xN + dN[:, 0:3]
        RN = self.RN @ rot[: L.n_nodes]
        xN[self._motion_x] = xN_pres[self._motion_x]
        RN[self._motion_R] = RN_pres[self._motion_R]
        return xN, RN, self.x0 + dS[:, 0:3], self.R0 @ rot[L.n_nodes :], self.eta + dS[:, 6:], self.v + dv

    def _prepare_step(self, t1, h, values, am, af, gamma):
        """Everything of the step t -> t1 = t + h that does not depend on the rates ydot_{n+1}.

        With a_{n+1} = (af/am) ydot + A0 the increment is h Delta = beta ydot + D0, beta = h gamma af/am,
        so the linear part of the configuration is p = beta ydot + P0 (P0 = y_n + D0) and the rotations
        are R = R_n exp(h Delta); configuration slots set by motion inputs get c = 0 and the input.
        Returns the prescribed node rates and the loads (zN, f, t)."""
        xN_p, RN_p, zN_p, f_in, t_in = self._read_inputs(t1, values)
        L = self.layout
        beta = h * gamma * af / am
        # a_{n+1} = (af/am) ydot + A0, A0 = ((1 - af) ydot_n - (1 - am) a_n)/am; h Delta = beta ydot + D0,
        # D0 = h ((1 - gamma) a_n + gamma A0): both linear in (ydot_n, a_n), one 2 x 2 matmul
        c1, c2 = (1.0 - af) / am, -(1.0 - am) / am
        C = np.array([[c1, c2], [h * gamma * c1, h * (1.0 - gamma) + h * gamma * c2]])
        A0, P0 = C @ np.stack([self.yd, self.a])
        P0[L.lin_slots] += np.concatenate([self.xN.ravel(), self.x0.ravel(), self.eta.ravel(), self.v.ravel()])
        P0[self._motion_x_slots] = xN_p[self._motion_x].ravel()
        P0[self._motion_T_slots] = 0.0
        Rn = np.concatenate([RN_p, self.R0])  # RN_p: the inputs on motion nodes, the current frames elsewhere
        if self._stage_beta != beta:
            self._stage_beta, self._stage_c = beta, beta * self._stage_mask
        self._stage = (self._stage_c, P0, Rn, af / am, A0)
        self._step_loads = (f_in, t_in if t_in.any() else None)  # -f, -R^T t on the node rows (`_residual_at`)
        return zN_p, f_in, t_in

    def _stage_at(self, yd):
        """The configuration at the rates ydot_{n+1} = yd of the prepared step, into the stage vector
        `_stage_p` and `self._R`: p = c yd + P0, R = R_n exp(h Delta)."""
        c, P0, Rn, _, _ = self._stage
        p = np.multiply(yd, c, out=self._stage_p)
        p += P0
        theta = p[self.layout.rot_cols]  # h Delta on every rotation (nodes then SEs)
        self._R = R = Rn @ expm(theta)
        return p, theta, R

    def _residual_at(self, yd, jacobian: bool = False, beta: float | None = None):
        """F (ny,) at the rates ydot_{n+1} = yd of the prepared step [and J = F_ydot + beta [F_y T, F_v]].
        Leaves the configuration in the stage vector and `self._R` (for `_commit`)."""
        p, theta, R = self._stage_at(yd)
        F, Fz, Fy = self._oracle().evaluate(p, yd, R, self.gravity, jacobian)
        N = self.layout.n_nodes
        f_in, t_in = self._step_loads
        Fn = F[: 6 * N].reshape(N, 2, 3)
        Fn[:, 0] -= f_in
        if t_in is not None:
            Fn[:, 1] -= (t_in[:, None, :] @ R[:N])[:, 0]  # R^T t
        if not jacobian:
            if self._springs:
                add_springs(self._springs, p, yd, R, F, None, 0.0, None, self._spring_loads)
            return F
        J = self._iteration_matrix(Fz, Fy, beta, theta, R)
        if self._springs:  # compliant ports: spring-damper loads on free nodes (runtime/coupling.py)
            add_springs(self._springs, p, yd, R, F, J, beta, self._newton_pos, self._spring_loads)
        return F, J

    def _iteration_matrix(self, Fz, Fy, beta, theta, R):
        """J = F_ydot + beta [F_y T, F_v] on the unknowns, assembled in the Newton order:
        d(config) = beta T(h Delta) d(zdot) on rotations, d(v) = beta d(vdot)."""
        L = self.layout
        N, nf = L.n_nodes, len(self._newton_idx)
        T = tangent(theta)
        TN, Tl = T[:N], T[N:]
        Fy = Fy * beta
        Fy[:, :, 3:6] = Fy[:, :, 3:6] @ Tl
        TNl = TN[self.se_nodes]
        for p in range(L.nb):
            c = slice(6 + L.nm + 6 * p + 3, 6 + L.nm + 6 * p + 6)
            Fy[:, :, c] = Fy[:, :, c] @ TNl[:, p]
        Fy += Fz
        J = np.bincount(self._newton_flat, Fy.ravel(), minlength=nf * nf + 1)[:-1].reshape(nf, nf)
        # load term -R^T t on free node rotations: d = -skew(R^T t) dTheta
        t_in = self._step_loads[1]
        if t_in is not None:
            RtT = (t_in[:, None, :] @ R[:N])[:, 0]
            for k, pos in self._torque_rows:
                J[np.ix_(pos, pos)] += -beta * skew(RtT[k]) @ TN[k]
        return J

