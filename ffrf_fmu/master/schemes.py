"""The master: fixed communication step, Jacobi or Gauss-Seidel sweeps, held-input extrapolation,
implicit coupling (FMU state rollback, IQN-ILS); linearly implicit coupling comes from
`interface.InterfaceJacobian` (see the package docstring for the schemes)."""
from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np

from ..runtime.rotation import expm
from .instance import CoSimulationError, FmuInstance
from .interface import InterfaceJacobian
from .links import Motion, Signal, _split, body_port_links, port_causality


class _IQN:
    """Interface quasi-Newton with an inverse Jacobian from least squares (IQN-ILS, Degroote,
    Bathe and Vierendeels 2009) for the fixed point x = G(x), reusing the differences of the
    last `reuse` communication steps."""

    def __init__(self, reuse: int):
        self.reuse = reuse
        self.old: list[tuple[list, list]] = []  # per past step: (V columns, W columns)
        self.V: list = []
        self.W: list = []
        self.last = None

    def new_step(self):
        self.V, self.W, self.last = [], [], None

    def end_step(self):
        if self.V and self.reuse > 0:
            self.old = ([(self.V, self.W)] + self.old)[: self.reuse]

    def update(self, x: np.ndarray, xt: np.ndarray) -> np.ndarray:
        r = xt - x
        if self.last is not None:
            r0, xt0 = self.last
            self.V.insert(0, r - r0)
            self.W.insert(0, xt - xt0)
        self.last = (r, xt)
        V = self.V + [c for v, _ in self.old for c in v]
        W = self.W + [c for _, w in self.old for c in w]
        if not V:
            return x + 0.1 * r  # first sweep ever: a small relaxation
        Vm, Wm = np.array(V).T, np.array(W).T
        c, *_ = np.linalg.lstsq(Vm, -r, rcond=1e-12)
        return xt + Wm @ c



@dataclass
class Result:
    t: np.ndarray
    columns: dict[str, np.ndarray]
    wall_time: float
    stopped_early: str = ""  # the failure message when the run did not reach stop_time
    messages: dict[str, list] = field(default_factory=dict)  # per instance: (status, category, text)
    sweeps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # per step (1: explicit)
    jacobian: str = ""  # interface-Jacobian runs: "fmu" (directional derivatives) or "fd" (finite differences)


class CoSimulation(InterfaceJacobian):
    """Fixed-step master: Jacobi or Gauss-Seidel, optional held-input extrapolation."""

    SCHEMES = ("jacobi", "gauss-seidel")
    JACOBIANS = ("auto", "fmu", "fd")

    def __init__(self, fmus: dict, *, step: float, scheme: str = "gauss-seidel", extrapolation: bool = False,
                 order: Iterable[str] | None = None, start_values: dict | None = None, iterations: int = 1,
                 tolerance: float = 1e-6, abs_tolerance: float = 1e-8, reuse: int = 8,
                 interface_jacobian: bool = False, fd_step: float = 1e-6, jacobian: str = "auto"):
        """iterations: sweeps per step; 1 = explicit coupling, > 1 = implicit coupling (FMU state
        rollback until the iterated inputs converge, IQN-ILS). Converged when the largest change
        of an iterated input is <= tolerance * (largest |input| so far in the run) + abs_tolerance;
        keep it above the noise of the FMUs' own Newton tolerance.
        interface_jacobian: linearly implicit coupling (module docstring), exclusive with
        iterations > 1. jacobian: where its coupling Jacobian comes from: "fmu" (the FMUs' directional
        derivatives chained through the sweep), "fd" (finite differences of sweeps), "auto" (fmu when
        every FMU provides directional derivatives, else fd). fd_step: the finite-difference step,
        relative to the largest iterated input so far (absolute floor abs_tolerance * 100)."""
        if interface_jacobian and int(iterations) > 1:
            raise CoSimulationError("interface_jacobian is one linearly implicit step: use iterations=1 with it")
        if jacobian not in self.JACOBIANS:
            raise CoSimulationError(f"jacobian must be one of {self.JACOBIANS}, got {jacobian!r}")
        self.interface_jacobian, self.fd_step, self.jacobian = bool(interface_jacobian), float(fd_step), jacobian
        self.iterations, self.max_iterations = int(iterations), int(iterations)
        self.tolerance, self.abs_tolerance, self.reuse = float(tolerance), float(abs_tolerance), int(reuse)
        if scheme not in self.SCHEMES:
            raise CoSimulationError(f"scheme must be one of {self.SCHEMES}, got {scheme!r}")
        if not step > 0.0:
            raise CoSimulationError(f"communication step must be positive, got {step!r}")
        self.step, self.scheme, self.extrapolation = float(step), scheme, bool(extrapolation)
        sv: dict[str, dict] = {}
        for full, value in (start_values or {}).items():
            inst, var = _split(full)
            sv.setdefault(inst, {})[var] = value
        self.instances: dict[str, FmuInstance] = {}
        try:
            for name, path in fmus.items():
                self.instances[name] = (path if isinstance(path, FmuInstance)
                                        else FmuInstance(name, path, start_values=sv.get(name)))
        except Exception:
            self.close()
            raise
        self.order = list(order) if order is not None else list(self.instances)
        if sorted(self.order) != sorted(self.instances):
            raise CoSimulationError(f"order {self.order} must name every instance {list(self.instances)} once")
        self.links: list = []

    # -------------------------------------------------------------- wiring
    def _check(self, full: str, causality: str) -> None:
        inst, var = _split(full)
        if inst not in self.instances:
            raise CoSimulationError(f"{full!r}: no FMU instance named {inst!r} (instances: {list(self.instances)})")
        v = self.instances[inst].variable(var)
        if causality == "input" and v.causality != "input":
            raise CoSimulationError(f"{full!r} is not an input (causality {v.causality})")
        if causality == "output" and v.causality not in ("output", "local"):
            raise CoSimulationError(f"{full!r} is not an output (causality {v.causality})")

    def connect(self, src: str, dst: str, gain: float = 1.0) -> None:
        """dst <- gain * src, a held signal."""
        self._check(src, "output")
        self._check(dst, "input")
        self.links.append(Signal(src, dst, float(gain)))

    def connect_ports(self, a: str, port_a: str, b: str, port_b: str | None = None, *,
                      accelerations: bool = False) -> None:
        """Join a body port of FMU a to a body port of FMU b (both parts; docs/fmu.md causality).
        accelerations: the motion-driven side also gets the force-driven side's P.a, P.dw for its
        second-order extrapolation (docs/cosim.md, "Acceleration links"); off: as docs/stability.md ran."""
        port_b = port_b or port_a
        ca = port_causality(self.instances[a], port_a)
        cb = port_causality(self.instances[b], port_b)
        for link in body_port_links(a, port_a, b, port_b, ca, cb, accelerations):
            for n in link.src if isinstance(link, Motion) else ():
                self._check(n, "output")
            for n in link.dst if isinstance(link, Motion) else (link.dst,):
                self._check(n, "input")
            self.links.append(link)

    def connect_by_name(self) -> int:
        """Connect every input to the output of the same variable name in exactly one other FMU
        (gain 1, held). Returns the number of connections made."""
        n = 0
        taken = {l.dst for l in self.links if isinstance(l, Signal)}
        for l in self.links:
            if isinstance(l, Motion):
                taken.update(l.dst)
        for dname, dst in self.instances.items():
            for var in dst.names("input"):
                if f"{dname}.{var}" in taken:
                    continue
                srcs = [s for s, inst in self.instances.items() if s != dname and var in inst.names("output")]
                if len(srcs) > 1:
                    raise CoSimulationError(f"input {dname}.{var}: outputs of the same name in {srcs}; connect explicitly")
                if srcs:
                    self.links.append(Signal(f"{srcs[0]}.{var}", f"{dname}.{var}"))
                    n += 1
        return n

    # -------------------------------------------------------------- running
    def _sources_of(self):
        """Every output read by a link, grouped per instance."""
        need: dict[str, list[str]] = {k: [] for k in self.instances}
        for l in self.links:
            names = l.src if isinstance(l, Motion) else (l.src,)
            for full in names:
                inst, var = _split(full)
                if var not in need[inst]:
                    need[inst].append(var)
        return need

    def _read(self, need) -> dict[str, float]:
        out = {}
        for inst, names in need.items():
            if names:
                out.update(zip((f"{inst}.{n}" for n in names), self.instances[inst].get(names)))
        return out

    # values a link gives its receiver ---------------------------------------------------------
    def _stale(self, link, H: float, prev: dict, cur: dict) -> dict:
        """The source has not stepped yet: its values at t_c (held: optionally extrapolated to
        the middle of the step from t_c - H and t_c)."""
        if isinstance(link, Signal):
            y = cur[link.src]
            if self.extrapolation and prev:
                y = y + 0.5 * (y - prev[link.src])
            return {link.dst: link.gain * y}
        return dict(zip(link.dst, (cur[n] for n in link.src)))

    def _fresh(self, link, H: float, cur: dict, fresh: dict) -> dict:
        """The source has reached t_c + H. Signal: the end value (its midpoint with the t_c value
        when extrapolating, explicit scheme only). Motion: the frame and rate at t_c + H, given as
        (r_end - v_end H, v_end) / (expm(-H w_end) R_end, w_end): the receiver's extrapolation
        then ends exactly on the source's frame and rate."""
        if isinstance(link, Signal):
            y = fresh[link.src]
            if self.extrapolation and self.iterations == 1:
                y = 0.5 * (cur[link.src] + y)
            return {link.dst: link.gain * y}
        p1 = np.array([fresh[n] for n in link.src_pos])
        rate = np.array([fresh[n] for n in link.src_rate])
        acc = np.array([fresh[n] for n in link.src_acc]) if link.src_acc else np.zeros(3)
        # r_0 + v_0 s + a s^2/2 (R: expm(w_0 s + dw s^2/2) R_0) ends on r_1, v_1: v_0 = v_1 - a H, r_0 = r_1 - (v_1 H - a H^2/2)
        rate0, back = rate - H * acc, H * rate - 0.5 * H * H * acc
        if link.kind == "translation":
            p0 = p1 - back
        else:
            p0 = (expm(-back) @ p1.reshape(3, 3)).ravel()
        out = dict(zip(link.dst_pos, p0))
        out.update(zip(link.dst_rate, rate0))
        out.update(zip(link.dst_acc, acc))
        return out

    def _links_into(self, inst: str) -> list:
        return [l for l in self.links if _split(l.dst if isinstance(l, Signal) else l.dst_pos[0])[0] == inst]

    @staticmethod
    def _src_inst(link) -> str:
        return _split(link.src if isinstance(link, Signal) else link.src_pos[0])[0]

    # one sweep over the FMUs -----------------------------------------------------------------
    def _sweep(self, t: float, H: float, ext: dict, prev: dict, cur: dict, guess: dict, need: dict) -> dict:
        """Step every FMU once from t to t + H; `guess` overrides the inputs of iterated links.
        Returns the fresh (t + H) values of every linked output."""
        fresh: dict = {}
        done: set = set()

        def inputs(name):
            vals = {k: v for k, v in ext.items() if _split(k)[0] == name}
            for l in self._links_into(name):
                vals.update(self._fresh(l, H, cur, fresh) if self._src_inst(l) in done else
                            self._stale(l, H, prev, cur))
            vals.update({k: v for k, v in guess.items() if _split(k)[0] == name})
            return vals

        self._applied = {}  # per FMU: the inputs it stepped with (for `_step_derivative`)
        if self.scheme == "jacobi":
            for name in self.order:
                self._applied[name] = inputs(name)
                self._apply(self._applied[name])
            for name in self.order:
                self._do_step(name, t, H)
            return self._read(need)
        for name in self.order:
            self._applied[name] = inputs(name)
            self._apply(self._applied[name])
            self._do_step(name, t, H)
            done.add(name)
            fresh.update(self._read({name: need[name]}))
        return fresh

    def _iterated_links(self) -> list:
        """Links whose source steps after (GS) or together with (Jacobi) the receiver: the
        values iterated on in implicit coupling (Signal links only; motion links follow the
        latest sweep)."""
        pos = {n: i for i, n in enumerate(self.order)}
        out = []
        for l in self.links:
            if not isinstance(l, Signal):
                continue
            src, dst = self._src_inst(l), _split(l.dst)[0]
            if self.scheme == "jacobi" or pos[src] >= pos[dst]:
                out.append(l)
        return out

    def _apply(self, values: dict) -> None:
        per: dict[str, tuple[list, list]] = {}
        for full, value in values.items():
            inst, var = _split(full)
            names, vals = per.setdefault(inst, ([], []))
            names.append(var)
            vals.append(value)
        for inst, (names, vals) in per.items():
            self.instances[inst].set(names, vals)

    def run(self, stop_time: float, *, start_time: float = 0.0, sources: Callable[[float], dict] | None = None,
            record: Iterable[str] | None = None, init_passes: int = 3) -> Result:
        """Initialize, step to stop_time, return the recorded outputs.

        sources(t) -> {"<instance>.<input>": value}: external signals (e.g. drives), values at t
        (set before each step; body FMUs treat them as values at t_c). record: names to record
        (default: every output of every instance). A refused step or an implicit step that does
        not converge ends the run early: `Result.stopped_early` says why (never raised)."""
        wall0 = _time.perf_counter()
        H = self.step
        if record is None:
            record = [f"{k}.{n}" for k, inst in self.instances.items() for n in inst.names("output")]
        record = list(record)
        rec_by: dict[str, list[str]] = {k: [] for k in self.instances}
        for full in record:
            inst, var = _split(full)
            rec_by[inst].append(var)
        need = self._sources_of()
        iterated = self._iterated_links() if (self.iterations > 1 or self.interface_jacobian) else []
        source = self._jacobian_source() if (iterated and self.interface_jacobian) else ""

        # initialization: start values, then a few passes of output -> input propagation
        for inst in self.instances.values():
            inst.fmu.setupExperiment(startTime=start_time)
            inst.set_start_values()
            inst.fmu.enterInitializationMode()
        if sources:
            self._apply(sources(start_time))
        for _ in range(max(1, init_passes)):
            cur = self._read(need)
            for name in self.order:
                for l in self._links_into(name):
                    self._apply(self._stale(l, H, {}, cur))
        for inst in self.instances.values():
            inst.fmu.exitInitializationMode()

        times = [start_time]
        rows = [self._read(rec_by)]
        prev: dict = {}
        cur = self._read(need)
        t, n = start_time, 0
        stopped = ""
        iters: list[int] = []
        accel = _IQN(self.reuse) if iterated else None
        self._scale = 0.0  # largest iterated input magnitude so far (tolerance scale)
        while t < stop_time - 1e-9 * max(1.0, abs(stop_time)):
            t_next = min(start_time + (n + 1) * H, stop_time)
            h = t_next - t
            ext = sources(t) if sources else {}
            try:
                if not iterated:
                    self._sweep(t, h, ext, prev, cur, {}, need)
                    iters.append(1)
                elif self.interface_jacobian:
                    iters.append(self._linearly_implicit_step(t, h, ext, prev, cur, need, iterated, source))
                else:
                    iters.append(self._implicit_step(t, h, ext, prev, cur, need, iterated, accel))
            except CoSimulationError as e:
                stopped = str(e)
                break
            prev, cur = cur, self._read(need)
            t = t_next
            n += 1
            times.append(t)
            rows.append(self._read(rec_by))
        columns = {name: np.array([r[name] for r in rows]) for name in record}
        messages = {k: list(inst.messages) for k, inst in self.instances.items()}
        return Result(np.array(times), columns, _time.perf_counter() - wall0, stopped, messages, np.array(iters),
                      source)

    def _implicit_step(self, t, h, ext, prev, cur, need, iterated, accel) -> int:
        """Repeat the sweep from saved FMU states until the iterated inputs equal what their
        sources give at t + H (IQN-ILS acceleration, Degroote et al. 2009). Returns the sweeps."""
        keys = [l.dst for l in iterated]
        x = np.array([self._stale(l, h, prev, cur)[l.dst] for l in iterated])
        states = {k: inst.fmu.getFMUstate() for k, inst in self.instances.items()}
        accel.new_step()
        try:
            for k in range(1, self.max_iterations + 1):
                if k > 1:
                    for name, inst in self.instances.items():
                        inst.fmu.setFMUstate(states[name])
                fresh = self._sweep(t, h, ext, prev, cur, dict(zip(keys, x)), need)
                xt = np.array([l.gain * fresh[l.src] for l in iterated])
                r = xt - x
                self._scale = max(self._scale, float(np.max(np.abs(xt))))
                limit = self.tolerance * self._scale + self.abs_tolerance
                if np.max(np.abs(r)) <= limit:
                    accel.end_step()
                    return k
                x = accel.update(x, xt)
            raise CoSimulationError(
                f"implicit coupling did not converge at t = {t:.6g} s in {self.max_iterations} sweeps "
                f"(largest change of an iterated input {np.max(np.abs(r)):.3g} > {limit:.3g} = "
                f"tolerance {self.tolerance:g} x {self._scale:.3g} + abs_tolerance {self.abs_tolerance:g})"
            )
        finally:
            for name, inst in self.instances.items():
                inst.fmu.freeFMUstate(states[name])

    def _do_step(self, name: str, t: float, h: float) -> None:
        from fmpy.fmi1 import FMICallException

        inst = self.instances[name]
        try:
            inst.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        except FMICallException as e:
            raise CoSimulationError(f"{name}: doStep({t:.6g}, {h:.6g}) returned status {e.status}: "
                                    f"{inst.last_message()}") from None

    def close(self) -> None:
        for inst in self.instances.values():
            inst.close()
        self.instances = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
