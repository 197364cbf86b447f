"""The `numba` backend: loading the compiled step (runtime/kernel.py) and calling it for a body.

numba is optional where the runtime runs (an FMU's host may not have it): `load_kernel` returns None
with the reason when numba is missing or the term set is not covered by the kernel, and the body
falls back to the numpy backend, saying so (`BodySystem.backend_note`).

Compiled code is cached on disk in a user cache directory keyed by the kernel's content:
kernel.py is copied to <cache>/kernels/<sha256 prefix>/ and imported from there, with numba's
cache=True next to it. A second process or FMU instantiation (an FMU's resources are unpacked to a
fresh directory each time, so a cache keyed by the file's path would miss) loads the machine code
instead of compiling. <cache> is $FFRF_FMU_CACHE_DIR, else $XDG_CACHE_HOME/ffrf-fmu, else
~/.cache/ffrf-fmu; if it cannot be written, a temporary directory (compiled once per process).

numba's cache keys an entry by the source file's content hash, the signature, the CPU and numba's
version, so the copy in an FMU's resources, a spawned worker or a second checkout of the same source
all load the same entry. What it does not do is coordinate processes: two that start on an empty
cache both compile (minutes each on a busy machine). The first call of each entry point therefore
holds an exclusive lock on <cache>/kernels/<sha256 prefix>/.compile.lock (released by the OS if the
process dies): a second process waits for the first one's compilation and then loads it from disk.

Each kernel version's directory holds about 6 MB of machine code. Loading a version marks it used
(`.last-used`); caching a new version removes the versions unused for STALE_AFTER_DAYS, skipping
any whose compile lock another process holds.
"""
from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import logging
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .held import WIDTH as HELD_WIDTH
from .ports import StepFailure

KERNEL_TERM_SETS = ("linear", "gyroscopic", "full")  # term sets runtime/kernel.py computes, each with or without stiffening


def _read_kernel_source() -> bytes | None:
    try:
        return (Path(__file__).resolve().parent / "kernel.py").read_bytes()
    except OSError:
        return None


# read at import: an FMU's unpacked resources may be deleted while its package stays imported
# (a second instance of the same FMU then reuses the module)
KERNEL_SOURCE = _read_kernel_source()
_LOADED: dict[str, object] = {}  # kernel modules by content hash: compiled code, no body state


def cache_root() -> Path:
    env = os.environ.get("FFRF_FMU_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "ffrf-fmu"


STALE_AFTER_DAYS = 30.0  # an installed FMU of an older version loads its kernel at least this often, or recompiles


def prune_stale(kernels: Path, keep: str, now: float | None = None) -> list[str]:
    """Remove kernel version directories under `kernels` not used for STALE_AFTER_DAYS (their
    `.last-used` stamp, else the directory's mtime), except `keep` and any whose compile lock is held.
    Returns the removed digests; a directory that cannot be removed is left."""
    import shutil

    now = time.time() if now is None else now
    removed = []
    for d in kernels.iterdir() if kernels.is_dir() else ():
        if d.name == keep or not d.is_dir():
            continue
        stamp = d / ".last-used"
        try:
            used = (stamp if stamp.exists() else d).stat().st_mtime
        except OSError:
            continue
        if now - used < STALE_AFTER_DAYS * 86400.0 or _locked(d):
            continue
        shutil.rmtree(d, ignore_errors=True)
        if not d.exists():
            removed.append(d.name)
    if removed:
        logging.getLogger("ffrf_fmu").info("kernel cache %s: removed %d version(s) unused for %g days", kernels, len(removed), STALE_AFTER_DAYS)
    return removed


def _locked(d: Path) -> bool:
    """Whether another process holds d's compile lock (it is compiling or loading that version)."""
    try:
        import fcntl
        with open(d / ".compile.lock", "ab") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            fcntl.flock(fh, fcntl.LOCK_UN)
        return False
    except BlockingIOError:
        return True
    except (ImportError, OSError):
        return False


def _kernel_file(src: bytes, digest: str) -> Path:
    """The source at its content-keyed place, created if absent and never replaced while intact: numba
    before 0.68 stamped its cache with the file's mtime, which a racing rewrite would change."""
    for root in (cache_root(), Path(tempfile.gettempdir()) / f"ffrf-fmu-{os.getuid() if hasattr(os, 'getuid') else 0}"):
        d = root / "kernels" / digest
        f = d / f"ffrf_kernel_{digest}.py"
        try:
            if f.exists() and f.read_bytes() == src:
                (d / ".last-used").touch()
                return f
            d.mkdir(parents=True, exist_ok=True)
            (d / ".last-used").touch()
            prune_stale(d.parent, digest)
            tmp = d / f".{f.name}.{os.getpid()}.tmp"
            tmp.write_bytes(src)
            try:
                if f.exists():  # damaged: replaced
                    os.replace(tmp, f)
                else:
                    os.link(tmp, f)  # atomic create-if-absent: a process that lost the race keeps the winner's file
            except FileExistsError:
                pass
            finally:
                tmp.unlink(missing_ok=True)
            if f.read_bytes() == src:
                return f
        except OSError:
            continue
    raise OSError("no writable cache directory for the compiled kernel")


def import_by_content(src: bytes):
    """The module of source `src`, imported from its content-keyed file (once per process)."""
    digest = hashlib.sha256(src).hexdigest()[:16]
    if digest not in _LOADED:
        path = _kernel_file(src, digest)
        name = f"ffrf_kernel_{digest}"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # numba's cache locator looks the module up by name
        spec.loader.exec_module(module)
        _LOADED[digest] = module
    return _LOADED[digest]


@contextlib.contextmanager
def compile_lock(kernel_file: Path):
    """Exclusive lock on the kernel's cache directory while a first call compiles or loads it.
    Without fcntl (Windows) or a writable lock file, no lock: each process may then compile."""
    try:
        import fcntl
        fh = open(Path(kernel_file).parent / ".compile.lock", "ab")
    except (ImportError, OSError):
        yield
        return
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)  # blocks while another process compiles this kernel
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def load_kernel(terms: str):
    """(module, None) or (None, reason): the compiled kernel module, compiled or loaded from the cache."""
    if terms not in KERNEL_TERM_SETS:
        return None, f"the numba kernel does not cover term set {terms!r} (it covers {', '.join(KERNEL_TERM_SETS)})"
    try:
        import numba  # noqa: F401
    except ImportError:
        return None, "numba is not installed"
    src = KERNEL_SOURCE
    if src is None:
        return None, f"{Path(__file__).resolve().parent / 'kernel.py'} could not be read"
    try:
        return import_by_content(src), None
    except Exception as exc:  # a broken numba install must not take the body down: numpy still works
        return None, f"the numba kernel could not be loaded ({type(exc).__name__}: {exc})"


_REPORT = "numba kernel: {seconds:.3f} s in this body's first kernel calls ({how})"
_REPORT_RE = re.compile(r"numba kernel: ([0-9.]+) s in this body's first kernel calls \((compiled|loaded from the disk cache)\)")


def kernel_report(step: "CompiledStep | None") -> str | None:
    """One line for a log (an FMU logs it at fmi2Terminate): the seconds of the body's first kernel
    calls and whether they compiled or loaded from the disk cache; None before any kernel call."""
    if step is None or step.compile_seconds is None:
        return None
    return _REPORT.format(seconds=step.compile_seconds, how="compiled" if step.compiled else "loaded from the disk cache")


def parse_kernel_report(lines) -> tuple[float, bool] | None:
    """(seconds, compiled) of the last kernel_report line among `lines`, None if there is none."""
    for line in reversed(list(lines)):
        m = _REPORT_RE.search(line)
        if m:
            return float(m.group(1)), m.group(2) == "compiled"
    return None


class CompiledStep:
    """The compiled step of one body: its constant arrays in the kernel's argument order, the state
    buffers the kernel updates in place (the body's state attributes are these buffers), the LU
    buffers kept across steps."""

    def __init__(self, system, module):
        self.module = module
        L = system.layout
        i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
        f64 = lambda x: np.ascontiguousarray(x, dtype=np.float64)  # noqa: E731
        gyro = (module.CORIOLIS if system.coriolis else 0) | (module.COUPLING if system.coupling else 0)
        G = system.G if gyro else np.zeros((L.n_se, 3, 1, 1))  # not read by the linear set
        nf = len(system._newton_idx)
        K, M, mass, J0, X_B, se_nodes = (f64(system.K), f64(system.M), f64(system.mass), f64(system.J0), f64(system.X_B),
                                         i64(system.se_nodes))
        # the deformation-dependent inertia (stiffening or `full`), its quadratic part, the membrane strain
        inertia = (
            1 if system.W1 is not None else 0,
            f64(system.W1) if system.W1 is not None else np.zeros((L.n_se, 0, 3, 3)),
            f64(system.W2) if system.W2 is not None else np.zeros((L.n_se, 0, 0, 3, 3)),
            *((f64(system.vk_a), f64(system.vk_B)) if system.stiffening else
              (np.zeros((L.n_se, 0, L.n)), np.zeros((L.n_se, 0, L.n, L.n)))),
        )
        self.const = (
            gyro, K, M, f64(G), *inertia, mass, J0, X_B, se_nodes, i64(L.cfg_map), i64(L.vel_map), f64(system.gravity),
            i64(system.fused.rot_slots), i64(system._newton_idx), i64(system._newton_pos), 3 * len(system._world_free),
            i64(system._field_of), float(system.THETA_REFRESH),
            float(system.KEEP_CONTRACTION), float(system.KEEP_MISS), *(int(k) for k in system.REFRESH_AFTER), i64(system._world_idx),
            i64(system.fused.lin_slots), i64(system._fixed_idx), i64(system._motion_x), i64(system._motion_x_slots),
            i64(system._motion_T_slots), f64(system._stage_mask), f64(system._motion_parts),
        )
        # compliant ports (runtime/coupling.py), in the order `_read_inputs` lists them; their stiffness,
        # damping and far-end inputs are copied in at every step (the compliance is settable)
        ports = [p for p in system.data.ports if p.name in system.compliant]
        ns = len(ports)
        self.springs = (
            i64([p.node for p in ports]), i64([p.translation == "compliant" for p in ports]),
            i64([p.rotation == "compliant" for p in ports]), np.zeros((ns, 4, 3)), np.zeros((ns, 3)), np.zeros((ns, 3)),
            np.repeat(np.eye(3)[None], ns, 0), np.zeros((ns, 3)), system._spring_loads,
        )
        self.spring_ports = [p.name for p in ports]
        N = L.n_nodes
        self.inputs = (np.zeros((N, 3)), np.zeros((N, 3, 3)), np.zeros((N, 6)), np.zeros((N, 3)), np.zeros((N, 3)))
        self.energy_data = (K, M, mass, J0, X_B, se_nodes, *inertia)  # kernel._energy_data(const), for `_record`
        self.ports = tuple(i64(x) for x in system._held_codes)  # (node, mode, spring): runtime/held.py port_codes
        # simulate.record's row: port_array raveled, the energies, iterations
        self.row_size = system.OUTPUT_WIDTH * len(system.data.ports) + len(system.ENERGY_FIELDS) + 1
        self.record_fn = None
        self.state = {k: np.zeros_like(np.asarray(getattr(system, k), dtype=float), order="C") for k in system._STATE_FIELDS}
        self.energy = np.zeros(2)  # work, power
        self.state_args = (*self.state.values(), self.energy)  # the kernel's `state`: BodySystem._STATE_FIELDS' order, energy
        self.ydw, self.p = np.zeros(L.ny), np.zeros(L.ny)
        self._set_lu(np.zeros((nf, nf)), np.zeros(nf, dtype=np.int32))
        self.lu_meta = np.zeros(12)  # [valid, beta, R_ref (9), serves]: the numpy path's `_lu` after the arrays
        self.info = np.zeros(2, dtype=np.int64)
        self.F = np.zeros(L.ny)
        self.R = np.zeros((L.n_nodes + L.n_se, 3, 3))
        self.work = (self.ydw, self.p, self.R, self.F)
        # what a call of `advance` does not read (the schedule of a scene's run after its ports' codes,
        # simulate.scene_schedule; an FMU's held values; the recorded rows and times): empty arrays of
        # the types of the used ones, so that every call has the same types (ONE compiled specialization)
        self.no_schedule = (np.zeros((0, 3)), np.zeros((0, 2), dtype=np.int64), np.zeros((0, 2, 3)), np.zeros((0, 2, 3)),
                            np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros((0, 2, 3)))
        self.no_values = np.zeros((0, HELD_WIDTH))
        self.no_rows, self.no_times = np.zeros((0, self.row_size)), np.zeros(0)
        self.fn = None  # the compiled entry point `advance`, once known (calling it skips numba's type dispatch)
        self.compile_seconds = None  # seconds of the first calls in this process (compilation or cache load)
        self.compile_cpu_seconds = None  # this process's CPU seconds in them
        self.compiled = None  # True: a first call compiled (empty cache); False: every one loaded from disk
        self.verified = False  # the first step is checked against the numpy path (`step`)

    def _first_call(self, dispatcher, args):
        """dispatcher(*args) compiled or loaded from the disk cache, under the kernel's compile lock; its
        seconds added to compile_seconds (CPU: compile_cpu_seconds), and whether it compiled (numba's dispatcher statistics)."""
        t0, c0 = time.perf_counter(), time.process_time()
        with compile_lock(self.module.__file__):
            out = dispatcher(*args)
        self.compile_seconds = (self.compile_seconds or 0.0) + time.perf_counter() - t0
        self.compile_cpu_seconds = (self.compile_cpu_seconds or 0.0) + time.process_time() - c0
        self.compiled = bool(self.compiled) or bool(sum(dispatcher.stats.cache_misses.values()))
        return out

    def _adopt(self, system):
        """The body's state in the kernel's buffers (after set_state, initialize or a numpy step)."""
        for k, buf in self.state.items():
            arr = getattr(system, k)
            if arr is not buf:
                buf[...] = arr
                setattr(system, k, buf)
        lu, m = system._lu, self.lu_meta
        if lu is None:
            m[0] = 0.0
            return
        if lu[0] is not self.lu:  # a factorization from set_state, a snapshot or the numpy path: shared, not copied
            self._set_lu(np.ascontiguousarray(lu[0].T), np.ascontiguousarray(lu[1], dtype=np.int32))
            m[2:11] = np.ravel(lu[3])
        # the scalars also for the kernel's own matrix: a restored snapshot may hold it with another serves flag,
        # or valid where a failed step had dropped it (and put its last increment into m[1])
        m[0], m[1], m[11] = 1.0, lu[2], lu[4]

    def _set_lu(self, luT, piv):
        """The factorization the kernel reads (it never writes into it: a refresh returns new arrays)."""
        self.luT, self.piv = luT, piv
        self.lu = luT.T  # Fortran-ordered view: the array scipy's lu_factor would return

    def step(self, system, h, inputs, am, af, gamma) -> int:
        """BodySystem.step on the compiled kernel; raises StepFailure with the numpy path's messages.

        The first step that the numpy path completes is also taken by it, from the same state, and
        the rates compared: a body whose equations hold a term the kernel lacks (added to the numpy
        path without a refusal in BodySystem) then runs on numpy with a note instead of computing
        something else. Both paths agree to ~1e-10 (tests/test_backends.py); the check allows 1e-6."""
        if not self.verified:
            return self._verified_step(system, h, inputs, am, af, gamma)
        return self._kernel_step(system, h, inputs, am, af, gamma)

    def _verified_step(self, system, h, inputs, am, af, gamma) -> int:
        saved = system.get_state()
        try:
            system._step(h, inputs, am, af, gamma, commit_config=True)
        except StepFailure:
            system.set_state(saved)
            return self._kernel_step(system, h, inputs, am, af, gamma)  # nothing to compare: next step
        reference, yd_ref = system.get_state(), system.yd.copy()
        system.set_state(saved)
        it = self._kernel_step(system, h, inputs, am, af, gamma)
        if system._compiled is None:  # the kernel did not compile: numpy already took over
            return it
        scale = float(np.max(np.abs(yd_ref))) or 1.0
        if float(np.max(np.abs(system.yd - yd_ref))) > 1e-6 * scale:
            system.set_state(reference)
            system._compiled, system.backend = None, "numpy"
            system.backend_note = ("the numba kernel disagrees with the numpy equations of this body at its first "
                                   "step (a term the kernel does not cover): running on numpy")
            logging.getLogger("ffrf_fmu").warning(system.backend_note)
            return system.iterations
        self.verified = True
        return it

    def _advance(self, system, kind, n, h, am, af, gamma, inputs, schedule, values, t_c, rows, times):
        """(steps completed, the most iterations of a step, the iterations of the last one) of the kernel's
        `advance` (its arguments there), the factorization taken over; None if the kernel failed to compile
        (the body then runs on numpy, with a note). The first call compiles or loads it (`_first_call`)."""
        args = (kind, n, self.const, self.state_args, inputs, self.springs, self.ports, schedule, values, float(h), float(am),
                float(af), float(gamma), float(system.tol), int(system.max_iter), int(system.iterations), self.work, self.luT,
                self.piv, self.lu_meta, self.info, float(system.t), float(t_c), rows, times)
        if self.fn is None:
            try:  # compiled (or loaded from the disk cache) with no step to take: compile_seconds holds no step
                self._first_call(self.module.advance, (kind, 0, *args[2:]))
            except Exception as exc:  # compilation failed (a broken numba install): numpy from here on
                system._compiled, system.backend = None, "numpy"
                system.backend_note = f"numba backend failed to compile ({type(exc).__name__}: {exc}): running on numpy"
                logging.getLogger("ffrf_fmu").warning(system.backend_note)
                return None
            self.fn = self.module.advance.overloads[self.module.advance.signatures[0]].entry_point
        done, worst, last_it, luT, piv = self.fn(*args)
        self._set_lu(luT, piv)
        return done, worst, last_it

    def _prepare(self, system):
        """The body's state, energy and compliances into the kernel's buffers before a call."""
        self._adopt(system)
        KC = self.springs[3]
        for i, name in enumerate(self.spring_ports):
            KC[i] = system.compliance[name]
        self.energy[0], self.energy[1] = system.work, system.power

    def _kernel_step(self, system, h, inputs, am, af, gamma) -> int:
        t1 = system.t + h
        if not (h > 0.0 and np.isfinite(h)):
            raise StepFailure(system.t, f"step size must be positive and finite, got {h}")
        read = system._read_inputs(t1, inputs(t1))
        self._adopt(system)
        if system._springs:
            _, _, _, KC, r_in, v_in, R_in, w_in, _ = self.springs
            for i, (_, _, _, kc, (r, v, R, w)) in enumerate(system._springs):
                KC[i] = kc
                if r is not None:
                    r_in[i], v_in[i] = r, v
                if R is not None:
                    R_in[i], w_in[i] = R, w
        self.energy[0], self.energy[1] = system.work, system.power
        out = self._advance(system, self.module.GIVEN, 1, h, am, af, gamma, read, self.no_schedule, self.no_values, 0.0,
                            self.no_rows, self.no_times)
        if out is None:
            return system._step(h, inputs, am, af, gamma, commit_config=True)
        failure = self._outcome(system, t1)
        if failure is not None:
            raise failure
        system.t, system.iterations = t1, int(self.info[1])
        system.work, system.power = float(self.energy[0]), float(self.energy[1])
        return system.iterations

    def _outcome(self, system, t1) -> StepFailure | None:
        """The factorization back to the body; the failure of the step ending at t1, if it failed,
        with the numpy path's messages."""
        status, m = int(self.info[0]), self.lu_meta
        system._lu = (self.lu, self.piv, m[1], m[2:11].reshape(3, 3).copy(), bool(m[11])) if m[0] else None
        if status == self.module.NOT_FINITE:
            return StepFailure(t1, "the residual is not finite (NaN or overflow)")
        if status == self.module.NOT_CONVERGED:
            return StepFailure(t1, f"Newton did not converge in {system.max_iter} iterations "
                                   f"(last increment {m[1]:.3g} of the tolerance)")
        if status == self.module.ROTATION_ALIAS:
            return StepFailure(t1, "a rotation increment over the step exceeds pi (step too large for the motion, "
                                   "or an absurd input)")
        if status == self.module.NOT_FACTORED:
            return StepFailure(t1, "iteration matrix cannot be factored (not finite or singular)")
        return None

    def record(self, system) -> np.ndarray:
        """simulate.record's row at the current state (port_array, energies, iterations), computed by the
        kernel's `_record` (the numpy twins: BodySystem.port_array, energies), called directly: the
        function `advance` calls, compiled once for both."""
        self._adopt(system)
        s, row = self.state, np.empty(self.row_size)
        args = (row, self.ports[0], self.energy_data, s["xN"], s["RN"], s["x0"], s["R0"], s["eta"], s["v"], s["yd"], s["fN"], s["tN"],
                float(system.work), int(system.iterations))
        if self.record_fn is None:  # compiled (or loaded from the disk cache) on first use
            self._first_call(self.module._record, args)
            self.record_fn = self.module._record.overloads[self.module._record.signatures[-1]].entry_point
        else:
            self.record_fn(*args)
        return row

    def run(self, system, h, schedule, rows, times, am, af, gamma):
        """len(rows) steps of h in ONE kernel call (runtime/kernel.py `advance`), the inputs evaluated from the
        scene's schedule (simulate.scene_schedule; its first three arrays are the ports' codes, held.port_codes,
        which the kernel reads from self.ports) and every step recorded into rows (simulate.record's layout)
        and times. Returns (steps completed, StepFailure of the next step or None)."""
        if not (h > 0.0 and np.isfinite(h)):
            return 0, StepFailure(system.t, f"step size must be positive and finite, got {h}")
        self._prepare(system)
        out = self._advance(system, self.module.SCHEDULED, rows.shape[0], h, am, af, gamma, self.inputs, schedule[3:],
                            self.no_values, 0.0, rows, times)
        if out is None:
            return 0, None
        done = out[0]
        if done:
            system.t, system.iterations = float(times[done - 1]), int(rows[done - 1, -1])
        system.work, system.power = float(self.energy[0]), float(self.energy[1])
        return done, self._outcome(system, system.t + h)  # (also hands the factorization back to the body)

    def run_held(self, system, h, n, t_c, held, row, am, af, gamma):
        """n steps of h in ONE kernel call (runtime/kernel.py `advance`), the inputs extrapolated from the
        values held at t_c (runtime/held.py; held = (node, mode, spring, values)), the output row of the
        last step into row (simulate.record's layout). Returns (steps completed, the most Newton iterations
        of a step, StepFailure of the next step or None)."""
        if not (h > 0.0 and np.isfinite(h)):
            return 0, 0, StepFailure(system.t, f"step size must be positive and finite, got {h}")
        self._prepare(system)
        out = self._advance(system, self.module.HELD, int(n), h, am, af, gamma, self.inputs, self.no_schedule, held[3], t_c,
                            row.reshape(1, -1), self.no_times)
        if out is None:
            return 0, 0, None
        done, worst, last_it = out
        t = system.t
        for _ in range(done):  # the clock of `step`, one addition per step
            t += h
        system.t, system.iterations = t, int(last_it)
        system.work, system.power = float(self.energy[0]), float(self.energy[1])
        return done, int(worst), self._outcome(system, system.t + h)  # (also hands the factorization back)
