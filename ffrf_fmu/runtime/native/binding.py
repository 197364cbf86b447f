"""The C runtime called from Python (ctypes): a body's `NativeStep`, the fast path of BodySystem.

The body's state arrays ARE the C body's memory (numpy views of it), as BodySystem's attributes: a step
writes them in place and Python reads them without a copy. What BodySystem replaces (set_state,
a step of the numpy path) is copied in before the next call (`_adopt`). The factorization
of the iteration matrix lives in the C body; BodySystem's `_lu` gets a copy of it after a refresh only
(its version changes), so a rollback snapshot keeps the matrix it was taken with.
"""
from __future__ import annotations

import ctypes as C
import logging
from functools import cached_property

import numpy as np

from ..ports import IterationCapReached, StepFailure
from . import build
from ..factorization import NativeFactor
from ..initial_conditions import MICRO_STEP, RELAX_MAX_ITER, no_equilibrium
from .image import body_image

GIVEN, SCHEDULED, EXTRAPOLATED = 0, 1, 2  # ffrf_runtime.h: where a step's inputs come from
OK, NOT_FINITE, NOT_CONVERGED, NOT_FACTORED, ROTATION_ALIAS, BAD_STEP, ITERATION_CAP = range(7)
NO_EQUILIBRIUM, NO_MEMORY = -1, -2  # ffrf_body_initialize's own failures

_LIB: dict[bool, C.CDLL] = {}

# out-arguments are void pointers (C.byref of a scalar): POINTER types cost 10 us each to make in a process
_p, _d, _i, _sz = C.c_void_p, C.c_double, C.c_int, C.c_size_t
_SIGNATURES = {
    "ffrf_body_create": (_p, [C.c_char_p, _sz, _p, _sz]),
    "ffrf_image_checksum": (C.c_uint64, [C.c_char_p, C.c_uint64]),
    "ffrf_body_free": (None, [_p]),
    "ffrf_body_array": (_p, [_p, C.c_char_p, _p, _p]),
    "ffrf_body_get_scalar": (_i, [_p, C.c_char_p, _p]),
    "ffrf_body_set_scalar": (_i, [_p, C.c_char_p, _d]),
    "ffrf_body_set_schedule": (None, [_p, _p, _p, _p, _p, _p, _p, _p, _i]),
    "ffrf_body_advance": (_i, [_p, _i, _i, _d, _d, _p, _p, _p, _p]),
    "ffrf_body_record": (None, [_p, _p]),
    "ffrf_body_state_size": (_sz, [_p]),
    "ffrf_body_get_state": (None, [_p, _p]),
    "ffrf_body_set_state": (_i, [_p, _p, _sz]),
    "ffrf_body_residual": (_i, [_p, _p, _p, _p, _i, _p, _p, _p]),
    "ffrf_status_text": (C.c_char_p, [_i]),
    "ffrf_body_initialize": (_i, [_p, _d, _p, _p, _p, _p, _i, _p, _p]),
}


def load(sanitize: bool = False) -> C.CDLL:
    """The runtime library, compiled into the cache on first use (runtime/native/build.py)."""
    if sanitize not in _LIB:
        lib = C.CDLL(build.library_path(sanitize))
        for name, (res, args) in _SIGNATURES.items():
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
        _LIB[sanitize] = lib
    return _LIB[sanitize]


_KINDS = {b"d": np.dtype(np.float64), b"q": np.dtype(np.int64), b"i": np.dtype(np.intc)}


class _Memory:
    """Memory of the C body as numpy's array interface describes it (NativeBody.array)."""

    __slots__ = ("__array_interface__",)

    def __init__(self, interface: dict):
        self.__array_interface__ = interface


class NativeBody:
    """One C body made from an image: its named arrays as numpy views, its scalars, its state."""

    def __init__(self, image: bytes, sanitize: bool = False):
        self.lib = lib = load(sanitize)
        err = np.zeros(512, dtype=np.uint8)  # (a ctypes string buffer's type costs 10 us to make)
        self._image = image
        self._count, self._kind = _sz(), C.c_char()  # (`array`'s out-arguments)
        self._out = C.byref(self._count), C.byref(self._kind)
        self.ptr = lib.ffrf_body_create(image, len(image), err.ctypes.data, err.size)
        if not self.ptr:
            why = err.tobytes().partition(b"\0")[0].decode(errors="replace")
            raise ValueError(f"C runtime refused the body image: {why}")

    def __del__(self):
        if getattr(self, "ptr", None):
            self.lib.ffrf_body_free(self.ptr)
            self.ptr = None

    def array(self, name: str, shape=None) -> np.ndarray:
        """The body's array `name` as a writable numpy view (reshaped to shape)."""
        count = self._count
        addr = self.lib.ffrf_body_array(self.ptr, name.encode(), *self._out)
        if addr is None and count.value:
            raise KeyError(f"the C body has no array {name!r}")
        dtype = _KINDS[self._kind.value]
        if count.value == 0:
            a = np.zeros(0, dtype=dtype)
        else:  # the memory by its address (numpy's array interface: a third of a ctypes buffer's cost)
            a = np.asarray(_Memory({"data": (addr, False), "shape": (count.value,), "typestr": dtype.str,
                                    "version": 3}))
        return a.reshape(shape) if shape is not None else a

    def get(self, name: str) -> float:
        v = _d()
        if self.lib.ffrf_body_get_scalar(self.ptr, name.encode(), C.byref(v)):
            raise KeyError(f"the C body has no scalar {name!r}")
        return v.value

    def set(self, name: str, value: float) -> None:
        if self.lib.ffrf_body_set_scalar(self.ptr, name.encode(), float(value)):
            raise KeyError(f"the C body has no settable scalar {name!r}")

    def advance(self, kind: int, n: int, h: float, t_c: float, rows: np.ndarray | None, times: np.ndarray | None):
        """ffrf_body_advance: (steps completed, status, the most iterations of a step)."""
        status, worst = _i(), _i()
        done = self.lib.ffrf_body_advance(self.ptr, kind, n, h, t_c, None if rows is None else rows.ctypes.data,
                                          None if times is None else times.ctypes.data, C.byref(status), C.byref(worst))
        return done, status.value, worst.value

    def record(self, row: np.ndarray) -> None:
        self.lib.ffrf_body_record(self.ptr, row.ctypes.data)

    def residual(self, p: np.ndarray, yd: np.ndarray, R: np.ndarray, F: np.ndarray, Fz=None, Fy=None) -> None:
        """ffrf_body_residual: the residual without loads into F [ny] at the stage p, yd [ny], R [N + E, 3, 3]
        (C-contiguous float64) and, when Fz, Fy [E, nv + nc, nc + nv] are given, the local blocks into them."""
        jac = Fz is not None
        address = lambda a: None if a is None else a.ctypes.data  # noqa: E731
        if self.lib.ffrf_body_residual(self.ptr, p.ctypes.data, yd.ctypes.data, R.ctypes.data, int(jac), F.ctypes.data,
                                       address(Fz), address(Fy)):
            raise ValueError("the C body refused the residual's arrays")

    def get_state(self) -> np.ndarray:
        out = np.empty(self.lib.ffrf_body_state_size(self.ptr))
        self.lib.ffrf_body_get_state(self.ptr, out.ctypes.data)
        return out

    def set_state(self, state: np.ndarray) -> None:
        state = np.ascontiguousarray(state, dtype=float)
        code = self.lib.ffrf_body_set_state(self.ptr, state.ctypes.data, state.size)
        if code == -1:
            raise ValueError(f"state has {state.size} entries, this body needs {self.lib.ffrf_body_state_size(self.ptr)}")
        if code:
            raise ValueError("state refused: its pivots or iteration count are not those of a factorization")


def failure(lib, status: int, t1: float, max_iter: int, iteration_cap: int, last_increment: float) -> StepFailure | None:
    """The StepFailure of a step's status (None for OK): the C runtime's words (ffrf_status_text, the numpy
    path's messages), with the iterations and the last increment of a Newton that did not converge; the
    IterationCapReached of a step over the body's iteration cap."""
    if status == OK:
        return None
    if status == ITERATION_CAP:
        return IterationCapReached(t1, iteration_cap)
    text = lib.ffrf_status_text(status).decode()
    if status == NOT_CONVERGED:
        text += f" in {max_iter} iterations (last increment {last_increment:.3g} of the tolerance)"
    return StepFailure(t1, text)


class NativeStep:
    """The C runtime's step for one BodySystem (its `_compiled`): BodySystem.step, run_schedule, run_extrapolated
    and output_row call it, and BodySystem._local its equations at a given state."""

    def __init__(self, system, sanitize: bool = False):
        lib = load(sanitize)  # the image's checksum by the C runtime (image.py pack); no basis unless damped
        image = body_image(system, basis=False,
                           checksum_of=lambda payload: lib.ffrf_image_checksum(payload, len(payload)))
        self.body = B = NativeBody(image, sanitize)
        L = system.layout
        N = L.n_nodes
        self.state = {k: B.array(k, np.shape(getattr(system, k))) for k in system._STATE_FIELDS}
        self.energy = B.array("energy")
        self.inputs = tuple(B.array(k, s) for k, s in (("xN_p", (N, 3)), ("RN_p", (N, 3, 3)), ("zN_p", (N, 6)),
                                                         ("f_in", (N, 3)), ("t_in", (N, 3))))
        self._ns, self._n_ports = len(system.compliant), len(system.data.ports)  # (the lazy views')
        self.KC = B.array("KC", (self._ns, 4, 3))
        self.spring_ports = [p.name for p in system.data.ports if p.name in system.compliant]
        loads = B.array("spring_loads", (N, 2, 3))
        loads[...] = system._spring_loads
        system._spring_loads = loads  # the springs' loads: written by the C steps, read by the numpy path
        nf = len(system._newton_idx)
        self.luT, self.piv, self.meta = B.array("luT", (nf, nf)), B.array("piv"), B.array("lu_meta")
        # the factorization last handed to system._lu (copies of the C body's), and the C version they copy
        self._lu_out, self._piv_out, self._lu_version = None, None, -1.0
        self.row_size = system.OUTPUT_WIDTH * len(system.data.ports) + len(system.ENERGY_FIELDS) + 1
        self._schedule = None  # the arrays of the schedule set in the C body (kept alive while it may read them)
        self._settings = None  # the integrator's settings last set in the C body (`_prepare`)
        self.ny, self.block = L.ny, (L.n_se, L.nv + L.nc, L.nc + L.nv)  # (`local`)
        self._pristine = True  # the C body's state as created, BodySystem.reset_reference's (until `_adopt`)

    # views that only some bodies or one way to step use: made on first use (a step of a body with compliant
    # ports, `run_extrapolated`)
    @cached_property
    def spring_inputs(self) -> tuple[np.ndarray, ...]:
        """r_in, v_in, R_in, w_in of the compliant ports."""
        ns, B = self._ns, self.body
        return B.array("r_in", (ns, 3)), B.array("v_in", (ns, 3)), B.array("R_in", (ns, 3, 3)), B.array("w_in", (ns, 3))

    @cached_property
    def point_values(self) -> np.ndarray:
        return self.body.array("point_values", (self._n_ports, -1))

    # ---------------------------------------------------------------- state in, results out
    def _adopt(self, system):
        """The body's state in the C body's memory (after set_state, reset_reference or a numpy step)."""
        self._pristine = False
        for k, buf in self.state.items():
            arr = getattr(system, k)
            if arr is not buf:
                buf[...] = arr
                setattr(system, k, buf)
        m, lu = self.meta, system._lu
        if lu is None:
            m[0] = 0.0
            return
        if not isinstance(lu[0], NativeFactor):  # the numpy path's dense LU is not the C runtime's: a fresh matrix
            m[0] = 0.0
            return
        if lu[0] is not self._lu_out:  # from set_state or an older snapshot
            self.luT[...] = lu[0]
            self.piv[...] = lu[1]
            m[2:11] = np.ravel(lu[3])
            self._lu_out, self._piv_out, self._lu_version = lu[0], lu[1], self.body.get("lu_version")
        m[0], m[1], m[11] = 1.0, lu[2], lu[4]

    _SETTINGS = ("am", "af", "gamma", "tol", "max_iter", "iteration_cap")  # (`_prepare`: set when they change)

    def _prepare(self, system, am, af, gamma):
        self._adopt(system)
        B = self.body
        B.set("t", system.t)
        B.set("iterations", system.iterations)
        settings = (am, af, gamma, system.tol, system.max_iter, system.iteration_cap)
        if settings != self._settings:
            for name, value in zip(self._SETTINGS, settings):
                B.set(name, value)
            self._settings = settings
        for i, name in enumerate(self.spring_ports):
            self.KC[i] = system.compliance[name]
        self.energy[0], self.energy[1] = system.work, system.power

    def _finish(self, system, status: int) -> StepFailure | None:
        """Time, iterations, energy and the factorization back to the body; the failure of the next step."""
        B, m = self.body, self.meta
        system.t, system.iterations = B.get("t"), int(B.get("iterations"))
        system.work, system.power = float(self.energy[0]), float(self.energy[1])
        if m[0]:
            version = B.get("lu_version")
            if version != self._lu_version:  # refreshed: a copy, so that snapshots keep theirs
                self._lu_out, self._lu_version = self.luT.copy().view(NativeFactor), version
                self._piv_out = self.piv.copy()
            system._lu = (self._lu_out, self._piv_out, float(m[1]), m[2:11].reshape(3, 3).copy(), float(m[11]))
        else:
            system._lu = None
        return failure(B.lib, status, system.t + self._h, system.max_iter, system.iteration_cap, float(m[1]))

    # ---------------------------------------------------------------- the three ways to step
    def step(self, system, h, inputs, am, af, gamma) -> int:
        """BodySystem.step on the C runtime (inputs read and checked by BodySystem._read_inputs)."""
        if not (h > 0.0 and np.isfinite(h)):
            raise StepFailure(system.t, f"step size must be positive and finite, got {h}")
        read = system._read_inputs(system.t + h, inputs(system.t + h))
        for dst, src in zip(self.inputs, read):
            dst[...] = src
        self._prepare(system, am, af, gamma)
        if system._springs:
            r_in, v_in, R_in, w_in = self.spring_inputs
        for i, (_, _, _, kc, (r, v, R, w)) in enumerate(system._springs):
            self.KC[i] = kc
            if r is not None:
                r_in[i], v_in[i] = r, v
            if R is not None:
                R_in[i], w_in[i] = R, w
        self._h = h
        _, status, _ = self.body.advance(GIVEN, 1, h, 0.0, None, None)
        exc = self._finish(system, status)
        if exc is not None:
            raise exc
        return system.iterations

    def _spring_ends(self, system) -> list[np.ndarray]:
        """The compliant ports' far ends r_in, v_in, R_in, w_in as system._springs (last `_read_inputs`) has
        them, the C body's where it has none (BodySystem.step's copy-in, as copies)."""
        ends = [a.copy() for a in self.spring_inputs] if system._springs else []
        for i, (_, _, _, _, values) in enumerate(system._springs):
            for a, value in zip(ends, values):
                if value is not None:
                    a[i] = value
        return ends

    def initialize(self, system, t0, inputs, velocity, angular_velocity, origin, port_displacements) -> None:
        """BodySystem.initialize in ONE call of the C runtime (ffrf_body_initialize, FFRF_GIVEN) from the body's
        reference state (BodySystem.reset_reference's: a C body as created holds it, its views become system's
        arrays): the inputs at t0 and those of the micro-step at t0 + delta read by `_read_inputs` from
        inputs(t), as the numpy path reads them. The state is the C body's memory after it."""
        if self._pristine:
            for k, buf in self.state.items():
                setattr(system, k, buf)
            system.work, system.power = 0.0, 0.0
        else:
            system.reset_reference()
        system.t, system._lu = t0, None
        read = system._read_inputs(t0, inputs(t0))
        ends0, springs0 = self._spring_ends(system), system._springs
        for dst, src in zip(self.inputs, read):
            dst[...] = src
        for dst, src in zip(self.spring_inputs if ends0 else (), ends0):
            dst[...] = src
        t1 = system.t + MICRO_STEP  # (the numpy path's micro-step time, as `step` makes it)
        nxt = system._read_inputs(t1, inputs(t1))
        ends1 = self._spring_ends(system)
        system._springs = springs0  # (the springs' ends at t0, as the numpy path leaves them)
        nxt = np.concatenate([a.ravel() for a in (*nxt, *ends1)])
        disp = None
        if port_displacements:
            names = [p.name for p in system.data.ports]
            disp = np.zeros((len(names), 3))
            for name, u in port_displacements.items():
                disp[names.index(system.data.port(name).name)] += np.asarray(u, float)
        self._prepare(system, 1.0, 1.0, 1.0)
        args = np.array([*velocity, *angular_velocity, *origin], dtype=float)
        last, a = _d(), args.ctypes.data
        B = self.body
        status = B.lib.ffrf_body_initialize(B.ptr, float(t0), a, a + 24, a + 48, None if disp is None else disp.ctypes.data,
                                            GIVEN, nxt.ctypes.data, C.byref(last))
        if status == NO_EQUILIBRIUM:
            raise no_equilibrium(system.t, port_displacements, RELAX_MAX_ITER, last.value)
        if status == NO_MEMORY:
            raise MemoryError("the C runtime's initialization: out of memory")
        if status != OK:
            raise failure(B.lib, status, t1, system.max_iter, system.iteration_cap, last.value)
        system.work, system.power = 0.0, float(self.energy[1])

    def run(self, system, h, schedule, rows, times, am, af, gamma):
        """len(rows) steps of h in ONE call, the inputs from the scene's schedule (simulate.scene_schedule;
        its first three arrays are the ports' codes, in the image) and every step recorded into rows
        (simulate.record's layout) and times. Returns (steps completed, StepFailure of the next step or None)."""
        if not (h > 0.0 and np.isfinite(h)):
            return 0, StepFailure(system.t, f"step size must be positive and finite, got {h}")
        r0, kind, prm, axis, load_port, load_window, load_fm = (np.ascontiguousarray(a) for a in schedule[3:])
        self._schedule = (r0, kind.astype(np.int64), prm, axis, load_port.astype(np.int64), load_window, load_fm)
        s = self._schedule
        self.body.lib.ffrf_body_set_schedule(self.body.ptr, *(a.ctypes.data for a in s), len(s[4]))
        self._prepare(system, am, af, gamma)
        self._h = h
        done, status, _ = self.body.advance(SCHEDULED, rows.shape[0], h, 0.0, rows, times)
        return done, self._finish(system, status)

    def run_extrapolated(self, system, h, n, t_c, values, row, am, af, gamma):
        """n steps of h in ONE call, the inputs extrapolated from the point values at t_c (runtime/input_rule.py),
        the last step's output row into row. Returns (steps completed, the most Newton iterations of a
        step, StepFailure of the next step or None)."""
        if not (h > 0.0 and np.isfinite(h)):
            return 0, 0, StepFailure(system.t, f"step size must be positive and finite, got {h}")
        self.point_values[...] = values
        self._prepare(system, am, af, gamma)
        self._h = h
        done, status, worst = self.body.advance(EXTRAPOLATED, int(n), h, t_c, row.reshape(1, -1), None)
        return done, worst, self._finish(system, status)

    def local(self, p, yd, R, jacobian: bool):
        """BodySystem._local on the C runtime: (F, F_ydot, F_y) at the stage p, yd, R (runtime/layout.py
        `stage`); (F, None, None) without jacobian."""
        F = np.empty(self.ny)
        if not jacobian:
            self.body.residual(p, yd, R, F)
            return F, None, None
        Fz, Fy = np.empty(self.block), np.empty(self.block)
        self.body.residual(p, yd, R, F, Fz, Fy)
        return F, Fz, Fy

    def record(self, system) -> np.ndarray:
        """simulate.record's row at the current state (BodySystem.port_array, energies, iterations)."""
        self._adopt(system)
        self.body.set("iterations", system.iterations)
        self.energy[0], self.energy[1] = system.work, system.power
        row = np.empty(self.row_size)
        self.body.record(row)
        return row


def native_step(system, sanitize: bool = False) -> tuple[NativeStep | None, str | None]:
    """(NativeStep, None), or (None, why) when the runtime cannot be compiled or loaded here."""
    try:
        return NativeStep(system, sanitize), None
    except (build.BuildError, OSError) as e:  # OSError: a library that does not load here (a shipped one)
        logging.getLogger("ffrf_fmu").warning("C runtime not available: %s", e)
        return None, str(e)
