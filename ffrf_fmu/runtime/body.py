"""A flexible body: a chain of two-field superelements joined by spatial coordinates
(geradin eqs. 69, 77-80, 89-91), its state, initial conditions and
outputs. The equations run in the C runtime (runtime/native, backend native) or in the plain oracle
runtime/equations.py, one superelement at a time (runtime/assembly.py, backend numpy); the time step in
runtime/integrator.py; where each unknown lives in runtime/layout.py; its initial state (rigid
placement, relaxed port displacements, consistent rates) in runtime/initial_conditions.py.

Over 400 lines: one class, the body's state and everything read from or written into it (state and
snapshots, inputs, initial conditions, outputs, energies, mass properties), which share its arrays; its
equations, layout and step live in the modules named above.
"""
from __future__ import annotations

import logging
from functools import cached_property
from typing import Callable

import numpy as np

from .accelerations import port_accelerations
from .damping import Damping, body_basis, damping_matrices, is_damped
from .data import BodyData
from . import outputs, stiffening
from .initial_conditions import InitialConditions
from .integrator import GeneralizedAlpha, alpha_coefficients
from .newton import zero_or_nan
from .layout import Layout, Segments, SuperelementStack
from .factorization import STATE_FLAG, NativeFactor, is_native
from .coupling import add_springs
from .ports import PortValues, StepFailure
from .rotation import ROTATION_TOL, cross, is_rotation, vect, vect_tangent
from .terms import FULL_TERMS, TERM_SETS

BACKENDS = ("native", "numpy")
# (np.array of a list, not np.stack, and this constant, not np.eye: their Python layers are most of a set-up's
# small steps)
_EYE3 = np.eye(3)
_EYE3.setflags(write=False)
# backends that were replaced, and by what (a request for one is refused with this message)
RETIRED_BACKENDS = {"numba": "the numba backend was replaced by the C runtime: use backend 'native' (the default)"}


def check_backend(backend: str) -> None:
    """Refuse an unknown or retired backend with a message naming the replacement."""
    if backend in RETIRED_BACKENDS:
        raise ValueError(RETIRED_BACKENDS[backend])
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")


def _input(values: PortValues, field: str, port: str, t: float) -> np.ndarray:
    """One input array of a port, checked: present, the right shape, finite."""
    val = getattr(values, field)
    if val is None:
        raise StepFailure(t, f"port {port!r}: input {field} is missing")
    val = np.asarray(val, dtype=float)
    shape = (3, 3) if field == "R" else (3,)
    if val.shape != shape or not np.isfinite(val).all():
        raise StepFailure(t, f"port {port!r}: input {field} is not a finite array of shape {shape}: {val!r}")
    return val


def _value(values: PortValues, field: str, port: str, t: float) -> np.ndarray:
    """An input array as given when it already is a float array of the right shape (its finiteness is
    checked later, for all inputs at once), else through the full check of `_input`."""
    val = getattr(values, field)
    if type(val) is np.ndarray and val.dtype == np.float64 and val.shape == ((3, 3) if field == "R" else (3,)):
        return val
    return _input(values, field, port, t)


def _not_a_rotation(t: float, port: str) -> StepFailure:
    """The failure of an input R that is not a rotation (rotation.is_rotation), for a motion or compliant port."""
    return StepFailure(t, f"port {port!r}: input R is not a rotation matrix (|R^T R - I| > {ROTATION_TOL:g} or det < 0)")


class BodySystem(InitialConditions, GeneralizedAlpha):
    """One flexible body and its integrator state. Instances share nothing (FMU-safe)."""

    def __init__(
        self,
        data: BodyData,
        *,
        terms: str = "linear",
        full_terms=FULL_TERMS,
        rho_inf: float = 0.8,
        gravity=(0.0, 0.0, 0.0),
        tol: float = 1e-9,
        max_iter: int = 25,
        iteration_cap: int = 0,
        backend: str = "native",
        damping: Damping | None = None,
    ):
        """backend: "native" (the C runtime, runtime/native; compiled into the user cache on first use)
        or "numpy" (the plain reference path). When the C runtime cannot be compiled here, the body runs
        on numpy, says why in `backend_note` and logs it (logger "ffrf_fmu"). `backend` is the one in use."""
        if terms not in TERM_SETS:
            raise ValueError(f"unknown term set {terms!r}; choose one of {TERM_SETS}")
        check_backend(backend)
        # structural damping (runtime/damping.py): the model file's, or the one given (an FMU's parameters)
        self.damping = data.damping if damping is None else damping
        self.data, self.terms, self.rho_inf = data, terms, float(rho_inf)
        self.coefficients = alpha_coefficients(self.rho_inf)
        self.gravity = np.asarray(gravity, dtype=float)
        self.tol, self.max_iter = tol, max_iter
        self.iteration_cap = int(iteration_cap)  # a step's Newton iterations at most (0: none; IterationCapReached)
        self.layout = L = Layout.of(data)
        self.stack = S = SuperelementStack.of(data)
        # the stacked superelement matrices, under the names of the equations
        self.K, self.M, self.G, self.mass, self.J0, self.X_B = S.K, S.M, S.G, S.mass, S.J0, S.X_B
        self.se_nodes = S.nodes
        unknown = set(full_terms) - set(FULL_TERMS)
        if unknown:
            raise ValueError(f"unknown full_terms {sorted(unknown)}; choose from {FULL_TERMS}")
        self.full_terms = tuple(full_terms)
        # the gyroscopic set's two parts: the S(q) coupling (55) in (77), the G(W0) Coriolis (53) in (78)-(79)
        self.inertia_coupling = terms == "gyroscopic" or (terms == "full" and "inertia_coupling" in self.full_terms)
        self.coriolis = terms == "gyroscopic" or (terms == "full" and "coriolis" in self.full_terms)
        self.gyro = self.inertia_coupling and self.coriolis  # the whole gyroscopic set
        # geometric stiffening (runtime/stiffening.py): on when the reduced data carries it; the
        # deformation-dependent inertia (Witteveen's I0 + W1 q + q W2 q) with the `full` term set
        ses = data.superelements
        self.stiffening = all(se.stiffening for se in ses)
        use_W1 = self.stiffening or (terms == "full" and "inertia_W1" in self.full_terms)
        use_W2 = terms == "full" and "inertia_W2" in self.full_terms
        self.W1 = self.W2 = self.vk_a = self.vk_B = None
        if (use_W1 or use_W2) and any(se.W1 is None or (use_W2 and se.W2 is None) for se in ses):
            raise ValueError("term set 'full' needs the inertia data W1, W2 in the reduced body "
                             "(reduction.reduce_body(..., inertia=True))")
        if use_W1 or use_W2:
            self.W1 = np.array([se.W1 for se in ses]) * (1.0 if use_W1 else 0.0)
        if use_W2:
            self.W2 = np.array([se.W2 for se in ses])
            if self.coriolis:  # G(W0) in (79) holds G^T M^-1 G of the softening already
                self.W2 = self.W2 - stiffening.gyroscopic_part_of_W2(self.G, self.M)
        if self.stiffening:
            self.vk_a = np.array([se.vk_a for se in ses])
            self.vk_B = np.array([se.vk_B for se in ses])
        self.D = damping_matrices(self.damping, self.damping_basis) if is_damped(self.damping) else None  # (E, n, n)
        self._motion_x, self._motion_R = L.maps["motion_x"], L.maps["motion_R"]  # motion-driven nodes (translation, rotation)
        # compliant port parts (runtime/coupling.py): free nodes loaded by a spring-damper to the input
        self.compliant = {p.name: (p.node, p.translation == "compliant", p.rotation == "compliant")
                          for p in data.ports if "compliant" in (p.translation, p.rotation)}
        self.compliance = {name: np.asarray(data.port(name).compliance, dtype=float).reshape(4, 3)
                           for name in self.compliant}  # K_t, C_t, K_r, C_r per port (settable)
        self._springs: list = []  # per step: the compliant parts with their inputs at t_{n+1}
        self._spring_loads = np.zeros((data.node_positions.shape[0], 2, 3))  # force, moment (world)
        self._build_newton()
        N, E, n, nv, ny = L.n_nodes, L.n_se, L.n, L.nv, L.ny
        self._zeros_ny = np.zeros(ny)
        self._assembly = None  # (`_oracle`)
        self._motion_parts = L.maps["motion_parts"]  # 1 on motion-driven node dofs
        self._port_nodes = L.maps["port_node"]
        self._port_codes = L.maps["port_node"], L.maps["port_mode"], L.maps["port_spring"]  # (of `run_extrapolated`)
        # energies: [v0, Omega0, r, q] of each SE with blockdiag(m I, J0, M, K), then 1/2 the sums per part
        self._energy_op = np.zeros((E, nv + n, nv + n))
        for e in range(E):
            self._energy_op[e, 0:3, 0:3] = self.mass[e] * _EYE3
            self._energy_op[e, 3:6, 3:6] = self.J0[e]
            self._energy_op[e, 6:nv, 6:nv] = self.M[e]
            self._energy_op[e, nv:, nv:] = self.K[e]
        self._energy_split = np.zeros((nv + n, 3))
        self._energy_split[0:6, 0], self._energy_split[6:nv, 1], self._energy_split[nv:, 2] = 0.5, 0.5, 0.5
        # input buffer of `_read_inputs`: [xN (N, 3) | RN (N, 3, 3) | zN (N, 6) | f (N, 3) | t (N, 3)]
        inp = Segments(xN=(N, 3), RN=(N, 3, 3), zN=(N, 6), f=(N, 3), t=(N, 3))
        self._input_views = [(inp[k], inp.shapes[k]) for k in ("xN", "RN", "zN", "f", "t")]
        self._zeros_inputs = np.zeros(inp.size - inp["zN"].start)
        self._zeros_input_buf = np.zeros(inp.size)
        self.t = 0.0
        self.iterations = 0
        self.reset_reference()
        self._compiled, self.backend, self.backend_note = None, "numpy", None
        if backend == "native":
            from .native.binding import native_step  # (ctypes: imported when a body asks for it)

            self._compiled, why = native_step(self)
            if self._compiled is None:
                self.backend_note = f"C runtime not available ({why}): running on numpy"
                logging.getLogger("ffrf_fmu").warning(self.backend_note)
            else:
                self.backend = "native"

    @cached_property
    def damping_basis(self):
        """The elastic modes D is built on (damping.py body_basis, of K and M as set up): computed on first
        use, by a damped body or an FMU's image (its damping parameters), not by an undamped run."""
        return body_basis(self.damping, self.K, self.M)

    # ------------------------------------------------------------------ state
    def reset_reference(self):
        """The reference state: undeformed, at rest, motion-driven parts at their reference frames, t kept."""
        L, d = self.layout, self.data
        self.xN = np.array(d.node_positions, dtype=float)
        self.RN = np.repeat(_EYE3[None], L.n_nodes, axis=0)
        self.x0 = np.array([se.x_cm for se in d.superelements], dtype=float)
        self.R0 = np.repeat(_EYE3[None], L.n_se, axis=0)
        self.eta = np.zeros((L.n_se, L.nm))
        self.v = np.zeros((L.n_se, L.nv))
        self.yd = np.zeros(L.ny)
        self.yd_prev = np.zeros(L.ny)
        self.yd_prev2 = np.zeros(L.ny)
        self.a = np.zeros(L.ny)
        self.fN = np.zeros((L.n_nodes, 3))  # force on each boundary node (load or reaction), world
        self.tN = np.zeros((L.n_nodes, 3))
        self.work = 0.0
        self.power = 0.0

    _STATE_FIELDS = ("xN", "RN", "x0", "R0", "eta", "v", "yd", "yd_prev", "yd_prev2", "a", "fN", "tN")

    def get_state(self) -> np.ndarray:
        """Flat copy of everything the next step depends on, the Newton iteration matrix included
        (modified Newton reuses it, so a restored state must continue with the same one to give
        bit-identical steps)."""
        return self._flat_state(with_lu=True)

    def _flat_state(self, with_lu: bool) -> np.ndarray:
        parts = [getattr(self, k).ravel() for k in self._STATE_FIELDS]  # (the method: np.ravel costs 1 us more each)
        has_lu = 0.0 if not with_lu or self._lu is None else STATE_FLAG if is_native(self._lu) else 1.0
        scalars = np.array([self.t, self.work, self.power, self.iterations, has_lu])
        if with_lu and self._lu is not None:
            lu, piv, beta, R_ref, serves = self._lu
            parts += [lu.ravel(), piv.astype(float), [beta], R_ref.ravel(), [serves]]
        return np.concatenate([scalars] + parts)

    def snapshot(self):
        """A rollback point for `restore` (an FMU's doStep): get_state without the iteration matrix,
        copied, and the factorization by reference, which costs nothing: a factorization is never
        modified in place (numpy's `_factor` makes new arrays; the C runtime's is copied out after a refresh)."""
        return self._flat_state(with_lu=False), self._lu

    def restore(self, snapshot) -> None:
        """Back to a `snapshot` of this body."""
        state, lu = snapshot
        self.set_state(state)
        self._lu = lu

    def set_state(self, state: np.ndarray) -> None:
        state = np.asarray(state, dtype=float)
        n = self._free_idx.size
        sizes = [getattr(self, k).size for k in self._STATE_FIELDS]
        expected = 5 + sum(sizes) + (n * n + n + 11 if state.size > 4 and state[4] else 0)
        if state.size != expected:
            raise ValueError(f"state has {state.size} entries, this body needs {expected}")
        self.t, self.work, self.power = state[0], state[1], state[2]
        self.iterations, has_lu = int(state[3]), state[4]
        i = 5
        for k, size in zip(self._STATE_FIELDS, sizes):
            setattr(self, k, state[i : i + size].reshape(getattr(self, k).shape).copy())
            i += size
        self._lu = None
        if has_lu:
            lu = state[i : i + n * n].reshape(n, n)
            lu = lu.copy().view(NativeFactor) if has_lu == STATE_FLAG else np.asfortranarray(lu)
            piv = state[i + n * n : i + n * n + n].astype(np.int32)
            beta, R_ref = state[i + n * n + n], state[i + n * n + n + 1 : i + n * n + n + 10].reshape(3, 3).copy()
            self._lu = (lu, piv, beta, R_ref, float(state[i + n * n + n + 10]))

    # ------------------------------------------------------------- equations
    def split_rates(self, yd):
        """Global ydot -> node (N, 6) rates, SE (E, 6 + nm) rates, SE (E, nv) velocity rates."""
        L = self.layout
        nN, nS = 6 * L.n_nodes, L.n_se * (6 + L.nm)
        return yd[:nN].reshape(L.n_nodes, 6), yd[nN : nN + nS].reshape(L.n_se, 6 + L.nm), yd[nN + nS :].reshape(L.n_se, L.nv)

    def _elastic(self, xP, RP, x0, R0T, eta):
        """q_bar of eq. (89): d_P = R0^T (x_P - x0) - X_P, alpha_P = vect(R0^T R_P), then eta.
        Matmul forms used throughout: (x @ R) = R^T x and (x @ R^T) = R x for stacks of row vectors."""
        rho = (xP - x0[:, None]) @ np.swapaxes(R0T, -1, -2)  # X_P + d_P
        Q = R0T[:, None] @ RP  # R0^T R_P
        alpha = vect(Q)
        E = len(x0)
        q = np.concatenate([np.concatenate([rho - self.X_B, alpha], axis=2).reshape(E, -1), eta], axis=1)
        return q, rho, Q, alpha

    def _local(self, xN, RN, x0, R0, eta, v, yd, jacobian: bool, gravity: bool = True):
        """Assembled residual WITHOUT loads F (ny,) at an explicit configuration and rates yd and, with
        jacobian, (F, F_ydot, F_y): F_ydot (E, nrow, nc + nv) w.r.t. local (zdot, vdot); F_y w.r.t. local
        configuration variations (dx world, dTheta body, deta) and velocities, rows and columns in the
        local layout of `_rows`, `_cols`. On the C runtime (`ffrf_body_residual`) when the body runs
        there, else through the oracle (runtime/assembly.py). gravity=False: without the weight -m g
        (its rows are the CM translations')."""
        p, R = self.layout.stage(xN, x0, eta, v), np.concatenate([RN, R0])
        yd = np.ascontiguousarray(yd, dtype=float)
        if self._compiled is not None:
            F, Fz, Fy = self._compiled.local(p, yd, R, jacobian)
        else:
            F, Fz, Fy = self._oracle().evaluate(p, yd, R, self.gravity, jacobian)
        if not gravity:
            F[self.layout.cfg_map[:, 0:3]] += self.mass[:, None] * self.gravity
        return (F, Fz, Fy) if jacobian else F

    def _oracle(self):
        """The numpy path's equations (runtime/assembly.py), built on first use: a body on the C runtime
        needs them only for the numpy path's tools (`newton_system`)."""
        if self._assembly is None:
            from .assembly import Assembly

            self._assembly = Assembly(self)
        return self._assembly

    def _loads(self, RN, inputs_f, inputs_t):
        """Node residual rows get -f and -R^T t from force-driven port parts."""
        L = self.layout
        out = np.zeros((L.n_nodes, 6))
        out[:, 0:3] = -inputs_f
        out[:, 3:6] = -np.einsum("nji,nj->ni", RN, inputs_t)
        return out

    # -------------------------------------------------------------- stepping
    def _read_inputs(self, t: float, values: dict[str, PortValues]):
        """Prescribed node frames/rates and applied loads at time t from the port inputs, checked:
        present, the right shape, finite, R a rotation. Returns (xN, RN, zN, f, t), views of one fresh
        buffer; nodes without motion inputs keep the current frame, without loads zero loads."""
        buf = np.concatenate([self.xN.ravel(), self.RN.ravel(), self._zeros_inputs])
        xN, RN, zN, f, tq = (buf[sl].reshape(shape) for sl, shape in self._input_views)
        springs = []
        for p in self.data.ports:
            pv = values.get(p.name)
            if pv is None:
                raise StepFailure(t, f"no input values for port {p.name!r}")
            k = p.node
            if p.name in self.compliant:
                _, ct, cr = self.compliant[p.name]
                ends = (_input(pv, "r", p.name, t) if ct else None, _input(pv, "v", p.name, t) if ct else None,
                        _input(pv, "R", p.name, t) if cr else None, _input(pv, "w", p.name, t) if cr else None)
                if cr and not is_rotation(ends[2]):
                    raise _not_a_rotation(t, p.name)
                springs.append((k, ct, cr, self.compliance[p.name], ends))
            if p.translation == "motion":
                xN[k], zN[k, 0:3] = _value(pv, "r", p.name, t), _value(pv, "v", p.name, t)
            elif pv.f is not None:
                f[k] = _value(pv, "f", p.name, t)
            if p.rotation == "motion":
                R = RN[k] = _value(pv, "R", p.name, t)
                zN[k, 3:6] = _value(pv, "w", p.name, t) @ R  # body-axes rate R^T w
            elif pv.t is not None:
                tq[k] = _value(pv, "t", p.name, t)
        # finiteness of everything at once; on failure the checks field by field name the culprit
        if zero_or_nan(buf, self._zeros_input_buf) != 0.0:
            for p in self.data.ports:
                pv = values[p.name]
                for fld, used in (("r", p.translation == "motion"), ("v", p.translation == "motion"),
                                  ("f", p.translation == "force" and pv.f is not None),
                                  ("R", p.rotation == "motion"), ("w", p.rotation == "motion"),
                                  ("t", p.rotation == "force" and pv.t is not None)):
                    if used:
                        _input(pv, fld, p.name, t)
        for k in self._motion_R:
            if not is_rotation(RN[k]):
                name = next(p.name for p in self.data.ports if p.node == k and p.rotation == "motion")
                raise _not_a_rotation(t, name)
        self._springs = springs
        return xN, RN, zN, f, tq


    def _update_port_loads(self, F, f_in, t_in):
        """Loads on the nodes: the inputs on force-driven parts, reactions (residual without loads) on
        motion parts (where no load is read, so the residual there is the contributions alone)."""
        N = self.layout.n_nodes
        Fn = F[: 6 * N].reshape(N, 2, 3)  # node rows: x, Theta (body axes)
        self.fN = f_in + self._motion_parts[:, 0] * Fn[:, 0] + self._spring_loads[:, 0]
        self.tN = (t_in + self._motion_parts[:, 1] * (Fn[:, 1:2] @ np.swapaxes(self.RN, -1, -2))[:, 0]  # R F_Theta
                   + self._spring_loads[:, 1])

    def _external_power(self) -> float:
        """Power of the port loads and gravity: f . v + t . (R W) on the nodes, m g . v0 on the CMs."""
        N = self.layout.n_nodes
        zN = self.yd[: 6 * N].reshape(N, 2, 3)
        Rt_t = (self.tN[:, None, :] @ self.RN)[:, 0]  # R^T t . W = t . R W
        p_nodes = np.vdot(self.fN, zN[:, 0]) + np.vdot(Rt_t, zN[:, 1])
        return float(p_nodes + (self.mass @ self.v[:, 0:3]) @ self.gravity)

    @property
    def unknowns(self) -> np.ndarray:
        """Indices of the unknowns in the global ydot layout (runtime/layout.py): all but the
        motion-driven node parts. `linearization`, `residual` and `move` work on these."""
        return self._free_idx

    def residual(self, yd: np.ndarray) -> np.ndarray:
        """The body equations without port loads at the current configuration and velocities with the
        rates yd (global ydot layout), on the unknowns: zero on a motion of the unloaded body."""
        return self._local(self.xN, self.RN, self.x0, self.R0, self.eta, self.v, yd, False)[self._free_idx]

    def move(self, d: np.ndarray) -> None:
        """Change the configuration and velocities by d (global ydot layout: positions and eta added,
        rotations R <- R expm(d_Theta), velocities added); motion-driven node parts stay where they are."""
        self.xN, self.RN, self.x0, self.R0, self.eta, self.v = self._configuration(self.xN, self.RN, d)

    def linearization(self) -> tuple[np.ndarray, np.ndarray]:
        """(F_ydot, F_y) of the assembled equations at the current state, restricted to the unknowns:
        small motions obey F_ydot d(ydot) + F_y d(y) = 0, so their frequencies solve
        det(i w F_ydot + F_y) = 0 (a check of the dynamic equations against the modal analysis)."""
        L = self.layout
        _, Fz, Fy = self._local(self.xN, self.RN, self.x0, self.R0, self.eta, self.v, self.yd, True)
        fi = self._free_idx
        scatter = lambda A: np.bincount(self._flat_idx, A.ravel(), minlength=L.ny * L.ny).reshape(L.ny, L.ny)[np.ix_(fi, fi)]
        return scatter(Fz), scatter(Fy)

    # ----------------------------------------------------------------- outputs
    OUTPUT_FIELDS = outputs.OUTPUT_FIELDS  # the columns of `port_array`, 3 or 9 each
    OUTPUT_WIDTH = outputs.OUTPUT_WIDTH  # columns of `port_array` per port
    ENERGY_FIELDS = outputs.ENERGY_FIELDS  # the keys of `energies`, in a row's order

    def port_array(self) -> np.ndarray:
        """(n_ports, 30) port outputs, one row per port in data.ports order: r, R (row-major), v, w, f, t, and
        the node's true accelerations a, dw at the end of the step (runtime/accelerations.py)."""
        k = self._port_nodes
        zN = self.yd[: 6 * self.layout.n_nodes].reshape(-1, 6)[k]
        R = self.RN[k]
        w = (zN[:, None, 3:6] @ np.swapaxes(R, -1, -2))[:, 0]  # R W
        return np.concatenate([self.xN[k], R.reshape(-1, 9), zN[:, 0:3], w, self.fN[k], self.tN[k],
                               port_accelerations(self)], axis=1)

    def output_row(self) -> np.ndarray:
        """One row of a time series (simulate.record's layout): port_array raveled, the energies in
        `energies` order, the Newton iterations of the last step; on the native backend computed by the
        C runtime (advance.c `ffrf_record`, the compiled twin of port_array and energies)."""
        if self._compiled is not None:
            return self._compiled.record(self)
        e = self.energies()
        return np.concatenate([self.port_array().ravel(), [e[k] for k in self.ENERGY_FIELDS], [self.iterations]])

    def outputs(self) -> dict[str, PortValues]:
        rows = self.port_array()
        return {
            p.name: PortValues(**{f: row[cols].reshape(outputs.FIELDS[f][0]) for f, cols in outputs.FIELD_COLUMNS.items()})
            for p, row in zip(self.data.ports, rows)
        }

    def elastic_coordinates(self) -> np.ndarray:
        """q_bar of every superelement (E, n) at the current state, eq. (89)."""
        nodes = self.se_nodes
        return self._elastic(self.xN[nodes], self.RN[nodes], self.x0, np.swapaxes(self.R0, -1, -2), self.eta)[0]

    def energies(self) -> dict[str, float]:
        """The split (20): rigid kinetic, elastic kinetic 1/2 r^T M r, strain 1/2 q^T K q, external work.

        The quadratic forms of every SE are one stacked matmul: [v, q] with blockdiag(m I, J0, M, K)."""
        vq = np.concatenate([self.v, self.elastic_coordinates()], axis=1)  # [v0, Omega0, r, q]
        halves = (vq * (vq[:, None, :] @ self._energy_op)[:, 0]) @ self._energy_split  # (E, 3)
        kr, ke, st = halves.sum(0)
        q, Om = vq[:, self.layout.nv :], self.v[:, 3:6]
        if self.stiffening:  # V2 of the second-order membrane strain
            st += float(stiffening.von_karman(q, self.vk_a, self.vk_B, tangent=False)[0].sum())
        if self.W1 is not None:  # 1/2 Omega0^T (W1 q [+ q W2 q]) Omega0: J0 -> J(q)
            kr += float(stiffening.deformed_inertia(q, q, Om, Om, self.W1, jacobian=False, W2=self.W2)[3].sum())
        return {"kinetic_rigid": float(kr), "kinetic_elastic": float(ke), "strain": float(st), "work_external": float(self.work)}

    def damping_power(self) -> float:
        """The power the structural damping takes out of the body now: sum over the superelements of
        q_bar_dot^T D q_bar_dot (>= 0), with q_bar_dot the co-rotated rates of (91)."""
        if self.D is None:
            return 0.0
        qd = self.elastic_rates()
        return float(np.einsum("ei,eij,ej->", qd, self.D, qd))

    def elastic_rates(self) -> np.ndarray:
        """q_bar_dot of every superelement (E, n) at the current state and rates, eq. (91):
        d_Pdot = R0^T (x_Pdot - x0dot) + rho_P x W0, alpha_Pdot = H(Q_P) (W_P - Q_P^T W0), then etadot."""
        nodes = self.se_nodes
        _, rho, Q, _ = self._elastic(self.xN[nodes], self.RN[nodes], self.x0, np.swapaxes(self.R0, -1, -2), self.eta)
        zN, zS, _ = self.split_rates(self.yd)
        W0 = zS[:, None, 3:6]
        d_dot = (zN[nodes, 0:3] - zS[:, None, 0:3]) @ self.R0 + cross(rho, W0)
        c = zN[nodes, 3:6] - (W0[..., None, :] @ Q)[..., 0, :]  # W_P - Q^T W0
        a_dot = (vect_tangent(Q) @ c[..., None])[..., 0]
        return np.concatenate([np.concatenate([d_dot, a_dot], axis=2).reshape(len(self.x0), -1), zS[:, 6:]], axis=1)

    def mass_properties(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(mass, CM position (3,), inertia tensor about the CM (3, 3)) of the body as its equations
        hold it, world axes: every superelement's mass at its CM x0 and its inertia R0 J R0^T, with
        J = J0 + W1 q [+ q W2 q] when it carries the deformation-dependent inertia (stiffening), J0 else."""
        J = self.J0
        if self.W1 is not None:
            J = J + stiffening.inertia_change(self.elastic_coordinates(), self.W1, self.W2)
        m = float(self.mass.sum())
        c = self.mass @ self.x0 / m
        y = self.x0 - c
        J_cm = np.einsum("eij,ejk,elk->il", self.R0, J, self.R0) + np.einsum("e,eij->ij", self.mass, np.einsum(
            "ek,ek->e", y, y)[:, None, None] * np.eye(3) - y[:, :, None] * y[:, None, :])
        return m, c, J_cm

    def momenta(self) -> tuple[np.ndarray, np.ndarray]:
        """Linear and angular momentum (about the world origin) of the rigid + elastic fields, world axes.

        The elastic velocity field carries no momentum about each CM (69h), so these are sums over CMs."""
        p = self.mass[:, None] * self.v[:, 0:3]
        hc = np.einsum("eij,ejk,ek->ei", self.R0, self.J0, self.v[:, 3:6])
        if self.inertia_coupling:
            q = self.elastic_coordinates()
            s = np.einsum("ei,ekij,ej->ek", self.v[:, 6:], self.G, q)
            hc = hc + np.einsum("eij,ej->ei", self.R0, s)
        if self.W1 is not None:  # (W1 q [+ q W2 q]) Omega0
            q, Om = self.elastic_coordinates(), self.v[:, 3:6]
            h = stiffening.deformed_inertia(q, q, Om, Om, self.W1, jacobian=False, W2=self.W2)[1]
            hc = hc + np.einsum("eij,ej->ei", self.R0, h)
        return p.sum(0), (np.cross(self.x0, p) + hc).sum(0)
