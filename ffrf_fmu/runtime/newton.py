"""Modified Newton of a generalized-alpha step (runtime/integrator.py `GeneralizedAlpha._step`): the
iteration on the rates, its convergence test per field, the factorization of the iteration matrix carried
along the rigid rotation, and the policy of keeping it within a step and across steps (the verdicts SERVES,
KEEPS; docs/equations.md, "Integrator"). runtime/native/step.c `newton_step` is its C twin; the C runtime
reads the policy's constants from the body (runtime/native/image.py).

`ModifiedNewton` is a mixin of `integrator.GeneralizedAlpha` (so of `body.BodySystem`): it works on the
step the integrator prepared (`_residual_at`, the stage) and on the body's factorization `_lu`. A replay
(`NewtonDecisions`, `NewtonReplay`) takes another run's decisions instead of its own (tests only).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from .ports import NotConverged, StepFailure

# The verdict a step leaves on its factorization (its fifth entry) for the rule REFRESH_AFTER of the next
# step (`_newton`): 0.0 drop it (rebuild at the predictor), SERVES keep it and trust it, KEEPS keep it.
SERVES, KEEPS = 1.0, 2.0


def zero_or_nan(x: np.ndarray, zeros: np.ndarray) -> float:
    """0.0 if every entry of x is finite, NaN otherwise (0 * x is 0 for finite x, NaN for inf or NaN;
    one dot product, cheaper than isfinite().all() on the hot path)."""
    return float(x @ zeros)


@dataclass(frozen=True)
class NewtonDecisions:
    """The Newton decisions of one step as another run of the same body took them (`GeneralizedAlpha.
    newton_replay`): its iterations (a retry's counted after the failed attempt's max_iter, as
    `iterations`) and the iterations at which it built the iteration matrix."""

    iterations: int
    refreshed: frozenset[int]

    def retry(self, max_iter: int) -> "NewtonDecisions":
        """The decisions of the retry that followed a failed first attempt of max_iter iterations."""
        return NewtonDecisions(self.iterations - max_iter, frozenset(i - max_iter for i in self.refreshed if i > max_iter))


@dataclass
class NewtonReplay:
    """Newton decisions to replay, one NewtonDecisions per step (`GeneralizedAlpha.newton_replay`), and
    where this run's own rules would have decided otherwise (one line each: time, iteration, which
    decision): the replayed run's policy checked against this one's, decision by decision."""

    decisions: Iterator[NewtonDecisions]
    disagreements: list[str] = field(default_factory=list)


class ModifiedNewton:
    """Newton on the rates of a prepared step (see the module docstring); the state lives on the body."""

    # Tests only: Newton then builds the matrix and accepts the iterate where the replayed run did, instead
    # of following its own convergence and refresh rules (REFRESH_AFTER included; they are still evaluated,
    # and where they differ it is logged), so that two runs compared to round-off (the C runtime against
    # this path) cannot part at a test that round-off tips (a count one apart moves the rates by up to the
    # tolerance).
    newton_replay: NewtonReplay | None = None

    def _newton(self, yd, beta, t1, dropped=False, trusted=False, replay=None):
        """Newton on the rates yd (updated in place) of the prepared step; returns the residual of the
        last evaluation and the iterations (residual evaluations, each followed by one solve).
        runtime/native/step.c `newton_step` is its C twin.

        Increments are measured per field (`_field_scale`): |dx_i| / (tol/beta + tol S_f), S_f the
        largest rate of the field of unknown i, so that a modal acceleration and a node velocity
        are each compared with their own kind. With theta the contraction of successive increments,
        the iterate after increment k is accepted when the error it leaves, estimated as
        theta/(1 - theta) |dx_k| (the increments shrink geometrically), is within the tolerance, or
        when the increment itself is 10x below it; the first increment is accepted when it is within
        the tolerance. The accepted iterate is not evaluated again: its configuration is staged
        (`_stage_at`) and the residual of the last evaluation, one increment within the tolerance,
        serves for the reactions. Within the step, the factorization is kept while theta <= THETA_REFRESH
        and the contraction would reach the tolerance within 3 more iterations (theta^4/(1 - theta)
        |dx_k| <= 1); not judged so is the second increment of a matrix kept from an earlier step after a
        first increment of more than KEEP_MISS/tol tolerances (`far`, the predictor's miss), when three
        more increments at KEPT_RADIUS would reach KEPT_ACCEPT: a matrix some steps old is good in the
        spectral sense, but its error is a stiff direction that the second increment brings out (as large
        as the first, on B1 at 40 ms) and the third has left (1e-2 of it): that ratio is the transient of
        the matrix's error, not its contraction. So that second iterate is accepted on the tolerance only
        after a first increment beyond WIDE_MISS/tol tolerances (`wide`), not after a smaller far one (its
        estimate is of the transient, and the error it left added up: KEPT_AGE). From the third
        increment on, such an iterate is accepted at KEPT_ACCEPT of the tolerance (estimate and the 10x
        rule alike; the refresh rule aims there too): a kept matrix converges linearly to its estimate,
        not far below it as a fresh one, and the runs' Newton error would add up. `_step` drops the matrix
        before the step by the rule REFRESH_AFTER.

        The step also records on the factorization whether it serves the next step as it is (its fifth
        entry, read by REFRESH_AFTER): SERVES after a far first increment, whatever built the matrix (a
        second iteration follows whatever the matrix, and one more on an older matrix costs less than a
        refresh: ~4 iterations on the C runtime for 1 SE x 2 modes, ~15 for 4 x 6); after one not wide,
        only while the second increment was within KEPT_AGE tolerances (the matrix's age). A matrix that
        REFRESH_AFTER kept on that verdict (`trusted`) and that the step does not accept after its second
        increment (after a far miss: its third) serves no more: it is rebuilt there (an FMU's matrix kept
        950 steps took 5-6 iterations otherwise). Or that REFRESH_AFTER keeps it without trust (KEEPS): a
        step whose first increment was within NEAR_MISS tolerances and whose second contracted by theta <=
        NEAR_CONTRACTION took its second iteration for a near miss of the predictor with a matrix that
        still contracts; the next step runs on the in-step rules.
        dropped: `_step` dropped the matrix by REFRESH_AFTER (a replay's own verdict);
        replay: NewtonDecisions to take instead (`newton_replay`)."""
        order = self._newton_idx
        nrm_prev = np.inf
        kept, far, late = True, False, False  # kept: no matrix built in this step (yet); late: one built after the first
        second = 0.0  # (the second increment: on a kept matrix, its age, KEPT_AGE)
        drop = replay is not None and dropped  # (a replay's own verdict: `_step` dropped the matrix)
        for it in range(1, self.max_iter + 1):
            # a matrix built for a step within 1e-6 of this one serves as well (modified Newton); an FMU's
            # communication grid repeats its step only up to round-off
            refresh = self._lu is None or abs(self._lu[2] - beta) > 1e-6 * beta
            if replay is not None:
                self._replay_verdict(t1, it, "refresh", refresh or drop, it in replay.refreshed)
                drop = False
                if self._lu is None and it not in replay.refreshed:
                    raise ValueError(f"Newton replay at t = {t1}: the replayed run kept a matrix at iteration {it}, "
                                     "this one has none")
                refresh = it in replay.refreshed
            if refresh:
                F, J = self._residual_at(yd, jacobian=True, beta=beta)
                kept, late = False, it > 1
            else:
                F = self._residual_at(yd)
            if zero_or_nan(F, self._zeros_ny) != 0.0:
                self._lu = None
                raise StepFailure(t1, "the residual is not finite (NaN or overflow)")
            R_now = self._R[self.layout.n_nodes]  # first CM frame
            if refresh:
                self._factor(J, beta, t1, R_now)
            dx = self._solve(F, R_now)
            yd[order] -= dx
            scale = self._field_scale(yd, beta)
            nrm = float(np.max(np.abs(dx) / scale))
            theta = nrm / nrm_prev
            if it == 1:
                far = nrm * self.tol > self.KEEP_MISS  # (the predictor's miss: only then may a matrix serve)
                wide = nrm * self.tol > self.WIDE_MISS  # (beyond it a kept matrix's iterates go by KEPT_ACCEPT)
                near = nrm <= self.NEAR_MISS
            elif it == 2:
                second = nrm
            # the error an iterate on an older matrix may leave (see KEPT_ACCEPT, WIDE_MISS; 0: not accepted)
            lim = 1.0 if not (kept and far) or it == 1 else self.KEPT_ACCEPT if it > 2 else 1.0 if wide else 0.0
            accept = nrm <= 1.0 if it == 1 else nrm <= 0.1 * lim or (theta < 1.0 and theta / (1.0 - theta) * nrm <= lim)
            if replay is not None:
                self._replay_verdict(t1, it, "accept", accept, it == replay.iterations)
                accept = it == replay.iterations
            if accept:
                self._stage_at(yd)
                keeps = it == 2 and near and theta <= self.NEAR_CONTRACTION
                serves = far and not late and (wide or second <= self.KEPT_AGE)
                self._lu = (*self._lu[:4], SERVES if serves else KEEPS if keeps else 0.0)
                return F, it
            # slow contraction, or too slow to reach the tolerance in 3 more iterations: refresh; not on the second
            # increment of a kept matrix after a far miss (the transient of its error, see the docstring)
            if (it > 1 and not (it == 2 and kept and far and self.KEPT_RADIUS**3 * nrm <= self.KEPT_ACCEPT)
                    and (theta > self.THETA_REFRESH or theta**4 / (1.0 - theta) * nrm > lim or (trusted and kept))):
                if replay is None:
                    self._lu = None
                else:
                    drop = True
            nrm_prev = nrm
        self._lu = None
        raise NotConverged(t1, f"Newton did not converge in {self.max_iter} iterations "
                              f"(last increment {nrm_prev:.3g} of the tolerance)")

    def _replay_verdict(self, t1, it, decision, own, replayed):
        """Log where this run's own rule decides otherwise than the replayed run (`newton_replay`)."""
        if own != replayed:
            self.newton_replay.disagreements.append(f"t = {t1}, iteration {it}: {decision} {replayed} replayed, {own} by this run's rule")

    # contraction beyond which the kept iteration matrix is rebuilt (besides: when the contraction would not
    # reach the tolerance within 3 more iterations; not at a kept matrix's second increment after a far miss,
    # `_newton`). Measured on B1 with benchmarks/newton_policy.py before REFRESH_AFTER: 0.25, 0.5 and 0.9
    # gave the same iterations and factorizations at 20 and 50 ms; at 2 ms (4 SE, 6 modes) 0.9 cost
    # iterations (1.91 against 1.85 solves)
    THETA_REFRESH = 0.5
    # the matrix is rebuilt at the predictor when the last step took REFRESH_AFTER[0] to REFRESH_AFTER[1]
    # iterations: the predictor misses at this step size, and a matrix built at it converges in two increments
    # where a kept one needs three (B1 at 20 ms: 2.00 against 2.4-2.9 iterations; benchmarks/
    # newton_iterations.py). Not after a harder step: there the predictor is far off (unresolved modes ringing
    # undamped), a matrix built at it is a poor one, and the kept matrix with the in-step rules does better
    # (B4 at h = 10 ms, rho_inf = 1: 4-6 iterations per step; rebuilt after every step of 2 or more, Newton
    # failed at t = 0.16 s). Nor when the last step showed that the matrix serves as it is (`_newton`: its
    # first increment was far, KEEP_MISS): a predictor can miss by far more than the tolerance while the
    # matrix stays good, or costs one iteration more than a fresh one, less than a refresh. An FMU's inputs do that: the extrapolation from the point values jumps back onto the signal at
    # every communication point (acceleration by ~jerk H), which sets the beam's elastic modes vibrating; their
    # accelerations are 1e4-1e8 tolerances (tol/beta) at B1's h = 2 ms, H = 5-100 h, a quadratic rate predictor
    # cannot follow them, and every internal step takes 2 iterations whatever the matrix (a kept one contracts
    # by 1e-7-1e-3). Rebuilding there bought nothing: 0.99 factorizations per internal step, now 0.006-0.012
    # (docs/benchmarks.md, "Newton iterations under the FMU's input rule"). B1 at 40 ms with stiffening does it
    # too, with a matrix whose error is a transient (`_newton`): 2.00 iterations and 0.98 factorizations per
    # step rebuilt, 3.38 and 0.27 kept (docs/benchmarks.md, "Newton at large steps")
    REFRESH_AFTER = (2, 3)
    # the error estimate (in tolerances) up to which an iterate is accepted from the third increment of a
    # matrix kept from an earlier step after a far miss, and that the in-step refresh rule then aims at
    # (`_newton`). A matrix built at the predictor converges quadratically and leaves 1e-3-1e-5 of the
    # tolerance after its accepted increment; a kept one contracts linearly and leaves about the estimate
    # itself, and that Newton error adds up over a run. B1 at 40 ms (1 SE x 2 modes; numpy), the maximum tip
    # deflection against the run at tol = 1e-11: +3.7e-7 of itself at 1, +9.0e-8 at 0.1, +1.4e-8 at 3e-2,
    # +1.3e-8 at 1e-2 (a matrix built at every step's predictor: +8.6e-10); with stiffening, 3.09 / 3.20 /
    # 3.35 / 3.23 iterations and 0.21 / 0.29 / 0.32 / 0.41 factorizations per step (fresh: 2.00 and 0.98).
    # 1e-2 also tipped C-against-numpy decisions in a first version of the rule (tests/test_native_runs.py: at
    # 1e-11 of the rates the increments are round-off). Not at the second increment: B2 took 2.16 iterations
    # per step there against 2.03
    KEPT_ACCEPT = 3e-2
    # the spectral radius taken for a kept matrix's error propagator after its transient (measured on B1 at
    # 20-40 ms: 0.004-0.03, docs/equations.md): its second increment is not judged when KEPT_RADIUS^3 of it is
    # within KEPT_ACCEPT (three more increments would reach the tolerance), i.e. below 3e4 tolerances. Larger
    # second increments come from a miss the problem is not linear over (B1 stiffened at 80 ms from t = 16 s,
    # 1e7-1e9 tolerances: the unstable elastic velocity mode, docs/benchmarks.md), where waiting a third
    # increment before the refresh failed Newton without this bound (C runtime: 2 and 4 SE x 2 modes at 80
    # ms, 1 SE at 90-100 ms, which complete with it and with the rule before). 2e-2 and 3e-2 (bounds of 3.8e3
    # and 1.1e3 tolerances) gave 2.93 / 0.53 and 2.62 / 0.78 iterations / factorizations per step at 40 ms
    KEPT_RADIUS = 1e-2
    # a matrix serves the next step (SERVES) after a first increment of more than KEEP_MISS in the per-field
    # scale (KEEP_MISS/tol tolerances, 1e3 at tol = 1e-9; a bound of its own, so that a tighter tolerance keeps
    # its super-converged fresh matrices), where a second increment follows whatever the matrix (an FMU's extrapolated inputs: 1e4-1e8
    # tolerances; B1's standalone run at 20 ms: ~130). Near the tolerance the iteration count hinges on the
    # matrix: without this bound B1 at 2 ms (1 SE x 2 modes, 20 s) fell into a run of 2-iteration steps on
    # kept matrices from t = 10 s (1.42 iterations per step against 1.03), and a 1e-11 tolerance at 20 ms moved
    # the tip deflection by 1.8e-10 (kept matrices converge to the tolerance, fresh ones far below it). 1e-8 (10
    # tolerances; 1e-6 before) takes in B1 at 10-20 ms (first increments of 15-800 tolerances), with WIDE_MISS
    # and KEPT_AGE; B1 at 2 ms keeps its counts (1.04 iterations and 0.006 factorizations per step)
    KEEP_MISS = 1e-8
    # WIDE_MISS, KEPT_AGE: after a first increment of KEEP_MISS to WIDE_MISS (the old KEEP_MISS, 1e3 tolerances)
    # a kept matrix's second iterate is not accepted: accepted on its estimate (the transient's) it moved the
    # unstiffened 20 ms run's deflection by +9.5e-9 of itself, not accepted by 1e-12. And the matrix serves the
    # next step only while its second increment is within KEPT_AGE tolerances: a kept matrix ages (on B1 at
    # 15 ms and the disk rotor the second increment grows by 1-10 tolerances a step, the third with it), and
    # an old one's third increments are of a size whose acceptance the round-off of tests/test_native_runs.py's
    # disk rotor tips between the C runtime and numpy (8-13 of its 400 steps, against none here; its increments
    # carry ~1e-2 tolerances of round-off). B1 1 SE x 2 modes stiffened, iterations / factorizations per step:
    # 10 ms 2.01 / 0.96 -> 2.81 / 0.21, 15 ms 2.00 / 1.00 -> 2.64 / 0.37, 20 ms 2.00 / 0.99 -> 2.56 / 0.44, 40 ms
    # 3.35 / 0.32 -> 3.40 / 0.29 (docs/benchmarks.md, "Kept matrices at 10-20 ms")
    WIDE_MISS = 1e-6
    KEPT_AGE = 10.0
    # A step of two iterations whose first increment was within NEAR_MISS tolerances (the per-field scale) and
    # whose second contracted by NEAR_CONTRACTION or better keeps its matrix for the next step (KEEPS): the
    # matrix still contracts, the second iteration was the predictor's near miss. On the C runtime a refresh of
    # B1's 4 SE x 6 modes costs some 15 iterations; at h = 2 ms REFRESH_AFTER rebuilt it after every such step,
    # 0.20 matrices per step at 1.20 iterations, now 0.044 at 1.245 (8 SE x 2 modes: 0.25 at 1.25, now 0.051 at
    # 1.27; 1 SE x 2 modes 0.02 at 1.02, now 0.006 at 1.04). NEAR_CONTRACTION 0.1 kept more (4 SE: 0.011
    # matrices at 1.61 iterations), 1e-3 fewer (0.099 at 1.21); NEAR_MISS 3, 10, 30 gave the same decisions at
    # 2 ms and left the runs at 20 and 40 ms unchanged (first increments of ~130 tolerances there); 1e3 took
    # B1 at 20 ms to 2.27 iterations per step (benchmarks/native_step.py, docs/runtime.md)
    NEAR_MISS = 10.0
    NEAR_CONTRACTION = 1e-2


    def _field_scale(self, yd, beta):
        """Tolerance of each unknown's increment, Newton order: tol/beta + tol S_f (see `_newton`)."""
        S = np.maximum.reduceat(np.abs(yd[self._field_perm]), self._field_starts)
        return self.tol / beta + self.tol * S[self._field_of]

    def _factor(self, J, beta, t, R_ref):
        """LU of the iteration matrix (unknowns in the Newton order), with the rotation of the first CM
        frame it was built at; not yet known to serve the next step (`_newton`)."""
        try:
            from scipy.linalg import lu_factor  # (the numpy path only: a native run never imports scipy here)

            lu, piv = lu_factor(J, overwrite_a=True, check_finite=True)  # J is not used afterwards
        except (ValueError, np.linalg.LinAlgError) as exc:
            self._lu = None
            raise StepFailure(t, f"iteration matrix cannot be factored: {exc}")
        self._lu = (lu, piv, beta, R_ref.copy(), 0.0)

    def _solve(self, F, R_now, factorization=None):
        """J^-1 F on the unknowns in the Newton order (the increment is minus this), with the stored
        factorization (or the given one) carried along the rigid rotation; F is not modified.

        The equations are frame-indifferent: rotating every world-axes vector (node and CM positions,
        CM velocities, forces) by a rigid rotation P maps J to P J P^T. So the matrix factored at the
        orientation R_ref serves at R_now through P = R_now R_ref^T, and modified Newton keeps its
        contraction while the body spins."""
        lu, piv, _, R_ref, _ = factorization or self._lu
        P = R_now @ R_ref.T
        k3 = 3 * len(self._world_free)
        F = F[self._newton_idx]  # world triplets first
        Fw = F[:k3].reshape(-1, 3)
        Fw[...] = Fw @ P  # P^T F on each triplet
        from scipy.linalg.lapack import dgetrs

        dx, info = dgetrs(lu, piv, F, overwrite_b=1)  # LAPACK directly: scipy's lu_solve wrapper costs more than the solve
        dw = dx[:k3].reshape(-1, 3)
        dw[...] = dw @ P.T  # P J_ref^-1 P^T F
        return dx
