"""A small fixed-step co-simulation master over fmpy's FMU2Slave.

Over 400 lines: the instance wrapper, the links and the coupling schemes in one module until it
is split into a package (issue 11).

    sim = CoSimulation({"A": "a.fmu", "B": "b.fmu"}, step=1e-3, scheme="gauss-seidel")
    sim.connect_ports("A", "cut", "B", "cut")        # body port to body port, both parts
    sim.connect("ctrl.torque", "A.hub.t[3]")         # any output to any input, held
    result = sim.run(stop_time=2.0, sources=lambda t: {"A.hub.R[1,1]": ...})

Names are "<instance>.<variable>". Each communication step [t_c, t_c + H]:

- `jacobi`: every FMU gets its inputs from values at t_c, then every FMU steps.
- `gauss-seidel`: the FMUs step one after the other in `order`; an FMU whose source has
  already stepped gets the source's fresh values at t_c + H, otherwise the values at t_c.

Two kinds of connection:
- `Held`: dst <- gain * src; the receiver keeps the value over the step. Stale (source not yet
  stepped): the value at t_c, or with `extrapolation=True` the value at t_c + H/2 of the line
  through the source's values at t_c - H and t_c. Fresh: the value at t_c + H (with
  extrapolation, explicit coupling: the mean of the values at t_c and t_c + H).
- `Motion`: a frame with its rate, (r, v) or (R, w), for body FMUs, which extrapolate
  r_c + v_c (t - t_c) and expm((t - t_c) skew(w_c)) R_c (docs/fmu.md). Stale: the source's
  frame and rate at t_c. Fresh: (r_1 - H v_1, v_1) and (expm(-H w_1) R_1, w_1) from the
  source's frame and rate at t_c + H, so that the receiver's extrapolation ends exactly on the
  source's frame and rate.

`iterations > 1` makes the coupling implicit: the FMU states are saved at t_c and the sweep is
repeated from them until the held inputs that came from stale sources equal what their sources
give at t_c + H (relative `tolerance`), with IQN-ILS acceleration. For two bodies joined at a
node this solves the same discrete equations as the one-body run (the node equilibrium at
t_c + H), which explicit coupling cannot: its one-step lag of the interface force makes the
split beam unstable (added-mass effect) whatever the step.

`interface_jacobian=True` is linearly implicit coupling (Kuebler and Schiehlen 2000; Sadjina et
al. 2017): no iteration to convergence but one Newton step on the same interface equations. At
t_c the FMU states are saved; the sweep from them is a map x -> G(x) of the iterated held inputs
(the implicit scheme's unknowns); its coupling Jacobian J = dG/dx over the step (outputs at
t_c + H w.r.t. inputs held over [t_c, t_c + H], chained through the receivers in the sweep) is
taken by forward finite differences, one sweep per input from the restored states; one linear
solve (I - J) dx = G(x_0) - x_0 gives the interface inputs and the real step is the sweep at
x_0 + dx: n + 2 sweeps for n iterated inputs. For linear subsystems this is the converged
implicit step; the FMUs' nonlinearity over one step leaves a residual that is not iterated away.

`body_port_links` wires two body ports (ports.md): the motion-driven side receives the frame of
the force-driven side; the force-driven side receives minus the reaction of the motion-driven
side (the force on one body is the opposite of the force on the other).
"""
from __future__ import annotations

import shutil
import time as _time
from ctypes import byref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from .fmu.variables import port_variables
from .runtime.rotation import expm


class CoSimulationError(RuntimeError):
    """An FMU refused a step (discard/error) or the setup is inconsistent."""


# ---------------------------------------------------------------------------------------------
# one FMU instance


_LIVE: dict[str, "FmuInstance"] = {}  # instanceName -> instance, for the shared log dispatcher


def _dispatch_log(component, instance_name, status, category, message):
    """fmpy's native logger proxy keeps ONE Python logger for the whole process (the last one
    registered): every instance registers this same dispatcher, which routes by instance name."""
    dec = lambda b: b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b)
    inst = _LIVE.get(dec(instance_name))
    if inst is not None:
        inst.messages.append((int(status), dec(category), dec(message)))


class FmuInstance:
    """An FMU2Slave instance with name-based access and the messages it logged."""

    _count = 0

    def __init__(self, name: str, path, *, start_values: dict | None = None):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
        from fmpy.fmi1 import calloc, free
        from fmpy.logging import addLoggerProxy

        self.name = name
        self.path = str(path)
        self.md = read_model_description(self.path)
        if self.md.coSimulation is None:
            raise CoSimulationError(f"{path}: not a co-simulation FMU")
        self.messages: list[tuple[int, str, str]] = []  # (status, category, message)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.start_values = dict(start_values or {})
        FmuInstance._count += 1
        self.instance_name = f"{name}#{FmuInstance._count}"
        self.unzipdir = extract(self.path)
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(_dispatch_log)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(cb))
        self._callbacks = cb  # keep alive
        _LIVE[self.instance_name] = self
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=self.instance_name)
        self.fmu.instantiate(callbacks=cb, loggingOn=True)

    def variable(self, name: str):
        try:
            return self.vars[name]
        except KeyError:
            raise CoSimulationError(f"FMU {self.name!r} ({Path(self.path).name}) has no variable {name!r}") from None

    def names(self, causality: str) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == causality]

    def _vrs(self, names) -> list[int]:
        return [self.variable(n).valueReference for n in names]

    def get(self, names: list[str]) -> np.ndarray:
        """Values as floats (Integer and Boolean variables converted)."""
        out = np.empty(len(names))
        real = [i for i, n in enumerate(names) if self.variable(n).type == "Real"]
        other = [i for i in range(len(names)) if i not in set(real)]
        if real:
            out[real] = self.fmu.getReal([self.variable(names[i]).valueReference for i in real])
        for i in other:
            v = self.variable(names[i])
            if v.type in ("Integer", "Enumeration"):
                out[i] = self.fmu.getInteger([v.valueReference])[0]
            elif v.type == "Boolean":
                out[i] = float(self.fmu.getBoolean([v.valueReference])[0])
            else:
                raise CoSimulationError(f"{self.name}.{names[i]} is a {v.type}: not a number")
        return out

    def set(self, names: list[str], values) -> None:
        if names:
            self.fmu.setReal(self._vrs(names), [float(x) for x in values])

    def set_start_values(self) -> None:
        for name, value in self.start_values.items():
            v = self.variable(name)
            if v.type == "Real":
                self.fmu.setReal([v.valueReference], [float(value)])
            elif v.type in ("Integer", "Enumeration"):
                self.fmu.setInteger([v.valueReference], [int(value)])
            elif v.type == "Boolean":
                self.fmu.setBoolean([v.valueReference], [bool(value)])
            else:
                self.fmu.setString([v.valueReference], [str(value)])

    def last_message(self) -> str:
        return self.messages[-1][2] if self.messages else "(no message logged)"

    def close(self) -> None:
        try:
            self.fmu.terminate()
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass
        try:
            self.fmu.freeInstance()
        finally:
            _LIVE.pop(self.instance_name, None)
            shutil.rmtree(self.unzipdir, ignore_errors=True)


# ---------------------------------------------------------------------------------------------
# connections


@dataclass(frozen=True)
class Held:
    """dst <- gain * src, held by the receiver over the step."""

    src: str
    dst: str
    gain: float = 1.0


@dataclass(frozen=True)
class Motion:
    """A frame and its rate: positions (3 names, r or R flattened) and rates (3 names, v or w)."""

    kind: str  # "translation" | "rotation"
    src_pos: tuple[str, ...]
    src_rate: tuple[str, ...]
    dst_pos: tuple[str, ...]
    dst_rate: tuple[str, ...]


def _split(full: str) -> tuple[str, str]:
    inst, sep, var = full.partition(".")
    if not sep:
        raise CoSimulationError(f"{full!r}: expected '<instance>.<variable>'")
    return inst, var


def body_port_links(a: str, port_a: str, b: str, port_b: str, causality_a: dict, causality_b: dict) -> list:
    """Connections joining port_a of body FMU a to port_b of body FMU b (rigid joint of the frames).

    causality_x: {"translation": "motion"|"force", "rotation": ...} of each port. Each part must be
    motion-driven on exactly one side."""
    links: list = []
    for part, (pos, rate, load) in {"translation": ("r", "v", "f"), "rotation": ("R", "w", "t")}.items():
        ca, cb = causality_a[part], causality_b[part]
        if ca == cb:
            raise CoSimulationError(
                f"{a}.{port_a} and {b}.{port_b}: the {part} is {ca}-driven on both sides; one side must be "
                "motion-driven and the other force-driven"
            )
        (m, pm), (s, ps) = ((a, port_a), (b, port_b)) if ca == "motion" else ((b, port_b), (a, port_a))
        # the motion-driven side m follows the frame of the force-driven side s ...
        links.append(Motion(part,
                            tuple(f"{s}.{n}" for n in port_variables(ps, pos)), tuple(f"{s}.{n}" for n in port_variables(ps, rate)),
                            tuple(f"{m}.{n}" for n in port_variables(pm, pos)), tuple(f"{m}.{n}" for n in port_variables(pm, rate))))
        # ... and s receives minus the reaction on m
        for src, dst in zip(port_variables(pm, load), port_variables(ps, load)):
            links.append(Held(f"{m}.{src}", f"{s}.{dst}", -1.0))
    return links


def port_causality(inst: FmuInstance, port: str) -> dict:
    """Part causalities of a body port, read from the FMU variables."""
    out = {}
    for part, pos in (("translation", "r"), ("rotation", "R")):
        v = inst.variable(port_variables(port, pos)[0])
        out[part] = "motion" if v.causality == "input" else "force"
    return out


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


# ---------------------------------------------------------------------------------------------
# the master


@dataclass
class Result:
    t: np.ndarray
    columns: dict[str, np.ndarray]
    wall_time: float
    stopped_early: str = ""  # the failure message when the run did not reach stop_time
    messages: dict[str, list] = field(default_factory=dict)  # per instance: (status, category, text)
    sweeps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # per step (1: explicit)


class CoSimulation:
    """Fixed-step master: Jacobi or Gauss-Seidel, optional held-input extrapolation."""

    SCHEMES = ("jacobi", "gauss-seidel")

    def __init__(self, fmus: dict, *, step: float, scheme: str = "gauss-seidel", extrapolation: bool = False,
                 order: Iterable[str] | None = None, start_values: dict | None = None, iterations: int = 1,
                 tolerance: float = 1e-6, abs_tolerance: float = 1e-8, reuse: int = 8,
                 interface_jacobian: bool = False, fd_step: float = 1e-6):
        """iterations: sweeps per step; 1 = explicit coupling, > 1 = implicit coupling (FMU state
        rollback until the iterated inputs converge, IQN-ILS). Converged when the largest change
        of an iterated input is <= tolerance * (largest |input| so far in the run) + abs_tolerance;
        keep it above the noise of the FMUs' own Newton tolerance.
        interface_jacobian: linearly implicit coupling (module docstring), exclusive with
        iterations > 1; fd_step: its finite-difference step, relative to the largest iterated
        input so far (absolute floor abs_tolerance * 100)."""
        if interface_jacobian and int(iterations) > 1:
            raise CoSimulationError("interface_jacobian is one linearly implicit step: use iterations=1 with it")
        self.interface_jacobian, self.fd_step = bool(interface_jacobian), float(fd_step)
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
        self.links.append(Held(src, dst, float(gain)))

    def connect_ports(self, a: str, port_a: str, b: str, port_b: str | None = None) -> None:
        """Join a body port of FMU a to a body port of FMU b (both parts; ports.md causality)."""
        port_b = port_b or port_a
        ca = port_causality(self.instances[a], port_a)
        cb = port_causality(self.instances[b], port_b)
        for link in body_port_links(a, port_a, b, port_b, ca, cb):
            for n in (link.dst_pos + link.dst_rate) if isinstance(link, Motion) else (link.dst,):
                self._check(n, "input")
            self.links.append(link)

    def connect_by_name(self) -> int:
        """Connect every input to the output of the same variable name in exactly one other FMU
        (gain 1, held). Returns the number of connections made."""
        n = 0
        taken = {l.dst for l in self.links if isinstance(l, Held)}
        for l in self.links:
            if isinstance(l, Motion):
                taken.update(l.dst_pos + l.dst_rate)
        for dname, dst in self.instances.items():
            for var in dst.names("input"):
                if f"{dname}.{var}" in taken:
                    continue
                srcs = [s for s, inst in self.instances.items() if s != dname and var in inst.names("output")]
                if len(srcs) > 1:
                    raise CoSimulationError(f"input {dname}.{var}: outputs of the same name in {srcs}; connect explicitly")
                if srcs:
                    self.links.append(Held(f"{srcs[0]}.{var}", f"{dname}.{var}"))
                    n += 1
        return n

    # -------------------------------------------------------------- running
    def _sources_of(self):
        """Every output read by a link, grouped per instance."""
        need: dict[str, list[str]] = {k: [] for k in self.instances}
        for l in self.links:
            names = (l.src_pos + l.src_rate) if isinstance(l, Motion) else (l.src,)
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
        if isinstance(link, Held):
            y = cur[link.src]
            if self.extrapolation and prev:
                y = y + 0.5 * (y - prev[link.src])
            return {link.dst: link.gain * y}
        out = dict(zip(link.dst_pos, (cur[n] for n in link.src_pos)))
        out.update(zip(link.dst_rate, (cur[n] for n in link.src_rate)))
        return out

    def _fresh(self, link, H: float, cur: dict, fresh: dict) -> dict:
        """The source has reached t_c + H. Held: the end value (its midpoint with the t_c value
        when extrapolating, explicit scheme only). Motion: the frame and rate at t_c + H, given as
        (r_end - v_end H, v_end) / (expm(-H w_end) R_end, w_end): the receiver's extrapolation
        then ends exactly on the source's frame and rate."""
        if isinstance(link, Held):
            y = fresh[link.src]
            if self.extrapolation and self.iterations == 1:
                y = 0.5 * (cur[link.src] + y)
            return {link.dst: link.gain * y}
        p1 = np.array([fresh[n] for n in link.src_pos])
        rate = np.array([fresh[n] for n in link.src_rate])
        if link.kind == "translation":
            p0 = p1 - H * rate
        else:
            p0 = (expm(-H * rate) @ p1.reshape(3, 3)).ravel()
        out = dict(zip(link.dst_pos, p0))
        out.update(zip(link.dst_rate, rate))
        return out

    def _links_into(self, inst: str) -> list:
        return [l for l in self.links if _split(l.dst if isinstance(l, Held) else l.dst_pos[0])[0] == inst]

    @staticmethod
    def _src_inst(link) -> str:
        return _split(link.src if isinstance(link, Held) else link.src_pos[0])[0]

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

        if self.scheme == "jacobi":
            for name in self.order:
                self._apply(inputs(name))
            for name in self.order:
                self._do_step(name, t, H)
            return self._read(need)
        for name in self.order:
            self._apply(inputs(name))
            self._do_step(name, t, H)
            done.add(name)
            fresh.update(self._read({name: need[name]}))
        return fresh

    def _iterated_links(self) -> list:
        """Links whose source steps after (GS) or together with (Jacobi) the receiver: the
        values iterated on in implicit coupling (held links only; motion links follow the
        latest sweep)."""
        pos = {n: i for i, n in enumerate(self.order)}
        out = []
        for l in self.links:
            if not isinstance(l, Held):
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
                    iters.append(self._linearly_implicit_step(t, h, ext, prev, cur, need, iterated))
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
        return Result(np.array(times), columns, _time.perf_counter() - wall0, stopped, messages, np.array(iters))

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

    def _coupling_jacobian(self, t, h, ext, prev, cur, need, iterated, x0, g0, restore) -> np.ndarray:
        """J = dG/dx of the sweep map at x0 (G(x0) = g0 given), by forward differences, one sweep
        from the saved states per iterated input. The place where FMU directional derivatives
        (fmi2GetDirectionalDerivative of each FMU's outputs at t_c + H w.r.t. its held inputs,
        chained through the sweep) would replace the differences."""
        keys = [l.dst for l in iterated]
        J = np.empty((len(x0), len(x0)))
        for j in range(len(x0)):
            d = self.fd_step * max(self._scale, float(np.max(np.abs(x0)))) + 100.0 * self.abs_tolerance
            x = x0.copy()
            x[j] += d
            restore()
            fresh = self._sweep(t, h, ext, prev, cur, dict(zip(keys, x)), need)
            J[:, j] = (np.array([l.gain * fresh[l.src] for l in iterated]) - g0) / d
        return J

    def _linearly_implicit_step(self, t, h, ext, prev, cur, need, iterated) -> int:
        """One linearly implicit step (module docstring): predictor x0 = the stale inputs, G(x0)
        and J = dG/dx from the saved states, x = x0 + (I - J)^-1 (G(x0) - x0), the real sweep at
        x. Returns the sweeps done (n + 2)."""
        keys = [l.dst for l in iterated]
        x0 = np.array([self._stale(l, h, prev, cur)[l.dst] for l in iterated])
        states = {k: inst.fmu.getFMUstate() for k, inst in self.instances.items()}

        def restore():
            for name, inst in self.instances.items():
                inst.fmu.setFMUstate(states[name])

        try:
            fresh = self._sweep(t, h, ext, prev, cur, dict(zip(keys, x0)), need)
            g0 = np.array([l.gain * fresh[l.src] for l in iterated])
            self._scale = max(self._scale, float(np.max(np.abs(g0))))
            J = self._coupling_jacobian(t, h, ext, prev, cur, need, iterated, x0, g0, restore)
            A = np.eye(len(x0)) - J
            try:
                x = x0 + np.linalg.solve(A, g0 - x0)
            except np.linalg.LinAlgError:
                raise CoSimulationError(f"interface Jacobian at t = {t:.6g} s: I - dG/dx is singular") from None
            restore()
            self._sweep(t, h, ext, prev, cur, dict(zip(keys, x)), need)
            return len(x0) + 2
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
