"""What a body FMU does, without pythonfmu: values, initialization, communication steps, state.

The pythonfmu slave (slave_template.py) is a thin shell around `BodyCoSim`; keeping the logic
here makes it testable in-process and the same code runs inside every FMU (the builder copies
this module next to a copy of ffrf_fmu/runtime). Imports: numpy, the standard library and the
runtime package (relative), nothing else.

Inputs between communication points and internal steps: variables.INPUTS_BETWEEN_COMMUNICATION_POINTS
and variables.INTERNAL_STEPS (the one source of the modelDescription text and docs/fmu.md). As
H -> 0 the extrapolated inputs tend to the exact signals, so the FMU run tends to the standalone
run (which evaluates the exact signals at every internal step).

Over 400 lines: one class, the FMU's state machine (values, initialization, communication steps,
saved states); its invariants hold across all of its methods, so it stays in one file. The directional
derivatives of the last step (re-runs of it) are in fmu/derivatives.py.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..runtime import input_rule
from ..runtime.damping import Damping
from ..runtime.data import BodyData
from ..runtime.outputs import FIELD_COLUMNS, output_sources, tip_from_hub
from ..runtime.ports import IterationCapReached, StepFailure
from ..runtime.rotation import ROTATION_TOL, rotation_defect
from ..runtime.terms import TERM_SETS
from ..runtime.body import BodySystem
from .derivatives import LastStep, directional_derivative
from .variables import Variable, body_variables, modal_shape

try:  # the C runtime's binding, imported with the FMU's first instance: a later instance importing it lazily
    # (BodySystem on backend native) would look in the first instance's resources folder, which the host may
    # have deleted (the package stays in sys.modules). A numpy-only FMU ships no runtime/native.
    from ..runtime.native import binding as _native_binding
    from ..runtime.native import build as _native_build

    if (_native_build.HERE / _native_build.PREBUILT).is_dir():  # a shipped copy: its library loads now, too
        _native_binding.load()
except (ImportError, OSError):  # OSError: a shipped library that does not load here (BodySystem then says so)
    _native_binding = None

try:  # optional: one BLAS thread during the FMU's own calls only (docs/fmu.md, BLAS threads)
    from threadpoolctl import ThreadpoolController
except ImportError:  # the slave script then sets OPENBLAS_NUM_THREADS=1 before numpy loads, when it can
    ThreadpoolController = None

ROTATION_EXACT = 1e-12  # re-orthonormalize R (polar factor) when max |R^T R - I| exceeds this
_I3 = np.eye(3)
STATE_VERSION = 1

CONFIG_FILE = "ffrf_fmu.json"
DATA_FILE = "body.npz"


@dataclass
class StepReport:
    """Outcome of a doStep. status: "ok"; "discard" for a numerical failure the master can recover
    from (a StepFailure of the body, a non-finite or non-rotation input: the FMU stays at t_c);
    "error" for everything else (a failed initialization, a call out of sequence, stepping on
    after a discard, a programming error: fmi2Error, the FMU must be reset or freed)."""

    ok: bool
    message: str = ""  # cause of a failure, naming the time
    detail: str = ""  # traceback of an unexpected exception
    iterations: int = 0
    status: str = "ok"


class BodyCoSim:
    """A body behind the FMI co-simulation calls.

    Every variable value lives in one float64 array `values` indexed by value reference
    (Integers stored as floats), so that the FMU state is a few arrays.
    """

    def __init__(self, data: BodyData, config: dict):
        self.data = data
        self.config = config
        self.variables: list[Variable] = body_variables(data.ports, data.node_positions, config["parameters"],
                                                        data.damping, modal_shape(data))
        self.origin = np.asarray(config.get("origin", data.node_positions[0]), dtype=float)
        n = len(self.variables)
        self.values = np.array([v.start if v.start is not None else 0.0 for v in self.variables], dtype=float)
        self.causality = [v.causality for v in self.variables]
        self.is_integer = np.array([v.type == "Integer" for v in self.variables])
        self.index: dict[tuple[str, str], np.ndarray] = {}
        for i, v in enumerate(self.variables):
            # per-port variables (port fields, initial.<port>.d, <port>.coupling.*) by port name, the others by kind
            key = (v.port, v.field) if v.port else (v.kind, v.field)
            self.index.setdefault(key, []).append(i)
        self.index = {k: np.array(ix, dtype=int) for k, ix in self.index.items()}
        self.by_name = {v.name: i for i, v in enumerate(self.variables)}
        self.input_ix = np.array([i for i in range(n) if self.causality[i] == "input"], dtype=int)
        self.param_ix = np.array([i for i in range(n) if self.causality[i] == "parameter"], dtype=int)
        self.output_ix = np.array([i for i in range(n) if self.causality[i] == "output"], dtype=int)
        self._is_output = np.array([c == "output" for c in self.causality])
        self._is_parameter = np.array([c == "parameter" for c in self.causality])
        self._plans: dict[tuple, tuple] = {}  # see _plan
        self._step_vr = int(self.index[("parameter", "step")][0])  # solver.step, read at every doStep
        self.mode = "instantiated"  # -> "initialization" -> "step"
        self.start_time = 0.0
        self.stop_time: float | None = None  # fmi2SetupExperiment's stopTime when defined
        self.system: BodySystem | None = None
        self._system_params: tuple | None = None
        self._initialized_with: np.ndarray | None = None  # inputs + parameters used by the last initialize
        self.failure = ""  # set when initialization failed: every doStep then reports it
        # The body's matrices are a few hundred rows: BLAS threads cost more than they save (B1 FMU
        # 17-21 s with two OpenBLAS threads, 3.2-3.5 s with one). The limit holds during this
        # instance's calls only and is undone on return: the host's own setting stays as it is.
        self._blas = ThreadpoolController() if ThreadpoolController is not None else None
        self.backend_note = None  # why the native backend is not used, when it was asked for
        self._blas_libs = [c for c in self._blas.lib_controllers if c.user_api == "blas"] if self._blas else []
        self._output_map: tuple | None = None  # see _output_values
        self._row = np.empty(BodySystem.OUTPUT_WIDTH * len(data.ports) + len(BodySystem.ENERGY_FIELDS) + 1)  # output_row
        # `_point_values`: per port and column of runtime/input_rule.py, the value reference it reads (0 where the
        # port's causality reads no such input), and the ports with a rotation input
        P, cols = len(data.ports), input_rule.COLUMNS
        ix = np.zeros((P, input_rule.WIDTH), dtype=int)
        for j, p in enumerate(data.ports):
            fields = (("r", "v", "a") if p.translation != "force" else ("f",)) + \
                     (("R", "w", "dw") if p.rotation != "force" else ("t",))
            for f in fields:
                ix[j, cols[f]] = self.index[(p.name, f)]
        self._point_map = (ix, [j for j, p in enumerate(data.ports) if p.rotation != "force"])
        self.discarded = ""  # the last fmi2Discard's message while the FMU stays at its t_c
        self.last_step: LastStep | None = None  # the last successful doStep (directional derivatives)

    def one_blas_thread(self):
        """Context: BLAS limited to one thread (a no-op without threadpoolctl, or when every BLAS
        already runs one thread: reading that costs ~4 us, setting and undoing the limit ~16 us per
        call, 1-2 % of a B1 doStep)."""
        if self._blas is None or all(c.num_threads == 1 for c in self._blas_libs):
            return contextlib.nullcontext()
        return self._blas.limit(limits=1, user_api="blas")

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_resources(cls, resources) -> "BodyCoSim":
        res = Path(resources)
        config = json.loads((res / CONFIG_FILE).read_text(encoding="utf-8"))
        return cls(BodyData.load(res / DATA_FILE), config)

    # ------------------------------------------------------------------ values
    def get(self, vr: int) -> float:
        if self.mode == "initialization" and self.causality[vr] == "output":
            self.refresh_initial_outputs()
        return self.values[vr]

    def _plan(self, vrs) -> tuple[np.ndarray, bool, bool]:
        """(index array, any output, any parameter) of a value-reference list. A host gets and sets the
        same lists at every step: they are kept (up to 256 lists; building them each time cost ~5 us
        of a doStep)."""
        key = tuple(vrs)
        plan = self._plans.get(key)
        if plan is None:
            ix = np.asarray(vrs, dtype=int)
            plan = (ix, bool(self._is_output[ix].any()), bool(self._is_parameter[ix].any()))
            if len(self._plans) >= 256:
                self._plans.clear()
            self._plans[key] = plan
        return plan

    def get_many(self, vrs) -> list[float]:
        """get() of several value references at once (one gather: the FMI getters' path)."""
        ix, outputs, _ = self._plan(vrs)
        if outputs and self.mode == "initialization":
            self.refresh_initial_outputs()
        return self.values[ix].tolist()

    def set_many(self, vrs, values) -> str:
        """set() of several value references: one scatter when every one may be set now; otherwise
        one by one in order up to the first refused (the same outcome as set() in a loop)."""
        ix, outputs, parameters = self._plan(vrs)
        if not (outputs or (parameters and self.mode == "step")):
            self.values[ix] = values
            return ""
        for vr, value in zip(vrs, values):
            problem = self.set(vr, float(value))
            if problem:
                return problem
        return ""

    def set(self, vr: int, value: float) -> str:
        """Set one input or parameter; returns why the call is refused ('' when done)."""
        c = self.causality[vr]
        name = self.variables[vr].name
        if c == "output":
            return f"{name} is an output: it cannot be set"
        if c == "parameter" and self.mode == "step":
            return f"{name} is a fixed parameter: it cannot change after initialization"
        self.values[vr] = value
        return ""

    def parameters(self) -> dict:
        v = self.values
        terms = int(round(v[self.index[("parameter", "terms")][0]]))
        disp = {}
        for p in self.data.ports:
            ix = self.index.get((p.name, "port_displacement"))
            if ix is not None:
                disp[p.name] = v[ix].copy()
        return {
            "step": float(v[self.index[("parameter", "step")][0]]),
            "rho_inf": float(v[self.index[("parameter", "rho_inf")][0]]),
            "terms": terms,
            "max_newton_iterations": float(v[self.index[("parameter", "max_newton_iterations")][0]]),
            "gravity": v[self.index[("parameter", "gravity")]].copy(),
            "initial_velocity": v[self.index[("parameter", "initial_velocity")]].copy(),
            "initial_angular_velocity": v[self.index[("parameter", "initial_angular_velocity")]].copy(),
            "port_displacements": disp,
            "compliance": {p.name: np.concatenate([v[self.index[(p.name, "coupling." + k)]]
                                                   if (p.name, "coupling." + k) in self.index else np.zeros(3)
                                                   for k in ("k", "c", "k_rot", "c_rot")]).reshape(4, 3)
                           for p in self.data.ports if "compliant" in (p.translation, p.rotation)},
            # structural damping: ratios (one for every mode, or one per mode), Rayleigh alpha, beta
            "damping": (v[self.index[("parameter", "damping_ratio")]].copy(),
                        float(v[self.index[("parameter", "damping_alpha")][0]]),
                        float(v[self.index[("parameter", "damping_beta")][0]])),
        }

    def _check_parameters(self, p: dict) -> str:
        """Why the parameters cannot start a run ('' when they can): out of range (min/max of the
        modelDescription), not finite, or implausible (a step longer than the experiment, initial
        values on a part whose motion is driven, which the motion input would override)."""
        if not (p["step"] > 0.0 and math.isfinite(p["step"])):
            return f"parameter solver.step must be positive and finite, got {p['step']!r}"
        span = None if self.stop_time is None else self.stop_time - self.start_time
        if span is not None and span > 0.0 and p["step"] > span:
            return (f"parameter solver.step = {p['step']:g} s is longer than the experiment "
                    f"({self.start_time:g} s to {self.stop_time:g} s)")
        if not 0.0 <= p["rho_inf"] <= 1.0:
            return f"parameter solver.rho_inf must be in [0, 1], got {p['rho_inf']!r}"
        terms = float(self.values[self.index[("parameter", "terms")][0]])
        if terms not in range(len(TERM_SETS)):
            return f"parameter solver.terms must be 0 (linear), 1 (gyroscopic) or 2 (full), got {terms!r}"
        cap = p["max_newton_iterations"]
        if not (cap >= 0.0 and cap == int(cap)):
            return f"parameter solver.max_newton_iterations must be an integer >= 0 (0: no cap), got {cap!r}"
        if TERM_SETS[int(terms)] == "full" and any(se.W2 is None for se in self.data.superelements):
            return ("parameter solver.terms = 2 (full) needs the inertia data W1, W2, which this FMU was built "
                    "without: build it from a scene with terms = \"full\"")
        named = {"gravity": "gravity", "initial_velocity": "initial.v", "initial_angular_velocity": "initial.w"}
        for key, name in named.items():
            if not np.all(np.isfinite(p[key])):
                return f"parameter {name} is not finite: {p[key].tolist()}"
        for port, d in p["port_displacements"].items():
            if not np.all(np.isfinite(d)):
                return f"parameter initial.{port}.d is not finite: {d.tolist()}"
        for key, part, field in (("initial_velocity", "translation", "v"), ("initial_angular_velocity", "rotation", "w")):
            driven = [q.name for q in self.data.ports if getattr(q, part) == "motion"]
            if driven and np.any(p[key] != 0.0):
                return (f"parameter {named[key]} = {p[key].tolist()} is set, but the {part} of port {driven[0]} is "
                        f"motion-driven: its input {driven[0]}.{field} gives the initial rigid "
                        f"{'velocity' if field == 'v' else 'angular velocity'} (set that input instead)")
        ratios, alpha, beta = p["damping"]
        for k, x in zip(self.index[("parameter", "damping_ratio")].tolist() + [self.index[("parameter", key)][0]
                        for key in ("damping_alpha", "damping_beta")], ratios.tolist() + [alpha, beta]):
            if not (x >= 0.0 and math.isfinite(x)):
                return (f"parameter {self.variables[k].name} must be finite and >= 0 (a damping ratio or Rayleigh "
                        f"coefficient), got {x!r}")
        for port, KC in p["compliance"].items():
            if not (np.all(np.isfinite(KC)) and np.all(KC >= 0.0)):
                return f"parameters {port}.coupling.* must be finite and >= 0, got {KC.ravel().tolist()}"
        return ""

    def _make_system(self) -> BodySystem:
        p = self.parameters()
        ratios, alpha, beta = p["damping"]
        damping = Damping(tuple(ratios.tolist()), alpha, beta)
        key = (p["rho_inf"], p["terms"], tuple(p["gravity"]), damping)
        if self.system is None or self._system_params != key:
            self.system = BodySystem(self.data, terms=TERM_SETS[p["terms"]], rho_inf=p["rho_inf"], gravity=p["gravity"],
                                     full_terms=tuple(self.config["parameters"]["full_terms"]),
                                     backend=self.config.get("backend", "numpy"), damping=damping)
            self.backend_note = self.system.backend_note  # native wanted but not usable: the slave logs it
            self._system_params = key
        for port, KC in p["compliance"].items():  # compliant ports: the coupling parameters
            self.system.compliance[port][...] = KC
        self.system.iteration_cap = int(p["max_newton_iterations"])
        return self.system

    # ------------------------------------------------------------------ inputs
    def _point_values(self, t_c: float, values: np.ndarray | None = None, strict: bool = True) -> tuple[np.ndarray, str]:
        """The input values set for t_c (or those of `values`), checked: (one row per port, the columns of
        runtime/input_rule.py, failure text). strict=False projects a rotation input onto the nearest rotation
        however far it is (the perturbed inputs of the directional derivatives: the projection is what the
        FMU does within ROTATION_TOL, and its derivative is the FMU's)."""
        values = self.values if values is None else values
        u = values[self.input_ix]
        if not math.isfinite(u.sum()) and not np.isfinite(u).all():  # a finite sum clears all; names only on failure
            bad = [self.variables[i].name for i in self.input_ix if not math.isfinite(values[i])]
            shown = ", ".join(bad[:6]) + (f" and {len(bad) - 6} more" if len(bad) > 6 else "")
            return None, f"t = {t_c:.6g} s: input(s) {shown} not finite (NaN or inf)"
        ix, turns = self._point_map
        point = values[ix]  # one gather (a column a port does not read holds some other value: never read)
        for k in turns:  # per rotation input, on Python floats: numpy calls on 3 x 3 cost more than they save
            name = self.data.ports[k].name
            defect = rotation_defect(point[k, 9:18].tolist())  # R row-major
            dev, det = defect.orthonormality, defect.det
            if dev > ROTATION_TOL and strict:
                return None, (f"t = {t_c:.6g} s: input {name}.R is not a rotation matrix "
                              f"(not orthonormal: max |R^T R - I| = {dev:.3g} > {ROTATION_TOL:g})")
            if det <= 0.0:
                return None, (f"t = {t_c:.6g} s: input {name}.R is not a rotation matrix (a reflection: "
                              f"det = {det:.6g}, a rotation has det = +1)")
            if dev > ROTATION_EXACT:  # nearest rotation: the polar factor U V^T
                U, _, Vt = np.linalg.svd(point[k, 9:18].reshape(3, 3))
                point[k, 9:18] = (U @ Vt).ravel()
        return point, ""

    # ------------------------------------------------------------------ modes
    def setup_experiment(self, start_time: float, stop_time: float | None = None) -> None:
        self.start_time = float(start_time)
        self.stop_time = None if stop_time is None else float(stop_time)

    def enter_initialization_mode(self) -> None:
        self.mode = "initialization"

    def _initialize(self) -> str:
        """Consistent initial state from the current inputs and parameters; failure text or ''."""
        self.failure = ""
        p = self.parameters()
        msg = self._check_parameters(p)
        if msg:
            self.failure = f"initialization: {msg}"
            return self.failure
        point, msg = self._point_values(self.start_time)
        if msg:
            self.failure = f"initialization: {msg}"
            return self.failure
        try:
            with self.one_blas_thread():
                self._make_system().initialize(
                    self.start_time,
                    input_rule.extrapolate(self.data.ports, point, self.start_time),
                    velocity=p["initial_velocity"],
                    angular_velocity=p["initial_angular_velocity"],
                    port_displacements=p["port_displacements"] or None,
                    origin=self.origin,
                )
            msg = self._start(p, point) if self.config.get("start") else ""
        except StepFailure as e:
            self.failure = f"initialization failed at t = {e.time:.6g} s: {e.cause}"
            return self.failure
        except Exception as e:  # noqa: BLE001 - reported to the host, never raised into it
            self.failure = (f"initialization failed at t = {self.start_time:.6g} s: {type(e).__name__}: {e}\n"
                            f"{traceback.format_exc()}")
            return self.failure
        if msg:
            self.failure = f"initialization failed at t = {self.start_time:.6g} s: {msg}"
            return self.failure
        self._write_outputs(0)
        self._initialized_with = self.values[np.concatenate([self.input_ix, self.param_ix])].copy()
        return ""

    def _start(self, p: dict, point) -> str:
        """The body initialized at the inputs of t0 put in the start state made at build (the scene's static
        equilibrium or steady spin, runtime/start.py), after the checks that it holds for these parameters
        and inputs; '' or why not."""
        from ..runtime import start as st

        start = self.config["start"]
        msg = st.parameter_mismatch(start["state"], start["gravity"], p["gravity"], p["initial_velocity"],
                                    p["initial_angular_velocity"], p["port_displacements"].items())
        arrays = start["terms"].get(TERM_SETS[p["terms"]])
        if msg or arrays is None:
            return msg or f"no start state for term set {TERM_SETS[p['terms']]!r} in this FMU"
        arrays = {k: np.asarray(v, dtype=float) for k, v in arrays.items()}
        msg = st.mismatch(self.system, arrays)
        if not msg:
            inputs = input_rule.extrapolate(self.data.ports, point, self.start_time)
            f_in, t_in = self.system._read_inputs(self.start_time, inputs(self.start_time))[3:5]
            st.adopt(self.system, arrays, f_in, t_in)
        return msg

    def _inputs_changed(self) -> bool:
        now = self.values[np.concatenate([self.input_ix, self.param_ix])]
        return self._initialized_with is None or not np.array_equal(now, self._initialized_with, equal_nan=True)

    def refresh_initial_outputs(self) -> None:
        """Outputs read in initialization mode reflect the inputs and parameters set so far."""
        if self._inputs_changed():
            self._initialize()

    def exit_initialization_mode(self) -> str:
        """'' or the failure text (the slave returns fmi2Error with it logged)."""
        msg = self._initialize() if (self._inputs_changed() or self.failure) else ""
        self.mode = "step"
        self.discarded = ""
        self.last_step = None
        return msg

    # ------------------------------------------------------------------ stepping
    def do_step(self, t_c: float, H: float) -> StepReport:
        """One communication step; never raises (see StepReport for what is Discard, what Error)."""
        self.last_step = None
        try:
            report = self._do_step(t_c, H)
        except Exception as e:  # noqa: BLE001 - a programming error: fmi2Error with the traceback
            return StepReport(False, f"t = {t_c:.6g} s: {type(e).__name__}: {e}", traceback.format_exc(), status="error")
        if report.status == "discard":
            self.discarded = report.message
        elif report.ok:
            self.discarded = ""
        return report

    def _do_step(self, t_c: float, H: float) -> StepReport:
        if self.failure:
            return StepReport(False, f"{self.failure} (doStep needs a successful initialization)", status="error")
        if self.mode != "step" or self.system is None:
            return StepReport(False, f"t = {t_c:.6g} s: doStep before the end of initialization", status="error")
        system = self.system
        h = float(self.values[self._step_vr])
        t_end = t_c + H
        tol = 1e-9 * max(1.0, abs(t_c)) + 1e-6 * h
        if not (H > 0.0 and math.isfinite(H)):
            return StepReport(False, f"t = {t_c:.6g} s: communication step must be positive and finite, got {H!r}",
                              status="error")
        if abs(t_c - system.t) > tol:
            if self.discarded:  # a master that ignored the discard: stop it instead of freezing silently
                why = f"the step from t = {system.t:.9g} s was discarded ({self.discarded}) and the FMU stayed there"
            else:
                why = f"the FMU is at t = {system.t:.9g} s"
            return StepReport(
                False,
                f"t = {t_c:.6g} s: {why}; doStep must start where the last successful step ended (retry from "
                f"t = {system.t:.9g} s, or restore a saved FMU state first)",
                status="error",
            )
        point, msg = self._point_values(t_c)
        if msg:
            return StepReport(False, msg, status="discard")
        saved = system.snapshot()  # the factorization shared, not copied
        # n equal internal steps of at most solver.step (up to round-off in H / h). Never a sliver: a
        # step of 1e-11 s makes the iteration matrix nearly the singular F_ydot of the DAE and leaves
        # a lasting high-frequency error in the reactions.
        ratio = H / h
        n = max(1, round(ratio)) if abs(ratio - round(ratio)) < 1e-6 * max(1.0, ratio) else math.ceil(ratio)
        hh = H / n
        try:
            with self.one_blas_thread():
                worst = system.run_extrapolated(hh, n, t_c, point, self._row)  # one call of the C runtime on backend native
                system.t = t_end  # the master's clock, not the sum of n rounded steps
                dst, out = self._output_values(worst, self._row)
            self._check_finite(system, out)
        except IterationCapReached as e:  # a real-time bound broken: not a step a smaller H should retry
            system.restore(saved)
            return StepReport(False, f"t = {e.time:.6g} s: {e.cause}", status="error")
        except StepFailure as e:
            system.restore(saved)
            return StepReport(False, f"t = {e.time:.6g} s: {e.cause}", status="discard")
        except Exception as e:  # noqa: BLE001 - a programming error, not a numerical failure: fmi2Error
            system.restore(saved)
            return StepReport(False, f"t = {t_c:.6g} s: {type(e).__name__}: {e}", traceback.format_exc(),
                              status="error")
        self.last_step = LastStep(t_c, H, n, saved, self.values.copy())
        self.values[dst] = out
        return StepReport(True, iterations=worst)

    # ------------------------------------------------------------------ directional derivatives
    def directional_derivative(self, knowns, seeds, unknowns, step: bool = True) -> tuple[np.ndarray | None, str]:
        """step True: derivative of the outputs `unknowns` at the end of the last doStep with respect to the
        inputs `knowns` along `seeds`; False: FMI's partial derivatives at the communication point (zero)
        (fmu/derivatives.py): (values, '') or (None, why not)."""
        return directional_derivative(self, knowns, seeds, unknowns, step)

    @staticmethod
    def _check_finite(system: BodySystem, outputs: np.ndarray) -> None:
        """The step's outputs (port motions and forces, energies: they read every configuration
        field and the velocities) and all rates yd are finite. Not the Newton iteration matrix of
        get_state: checking that copy cost 60 us a step (B1), half the FMU's own overhead. A NaN or
        inf makes a sum non-finite, so two finite sums clear both arrays at one reduction each (~3 us
        less); a sum that overflowed on finite entries falls through to the element test."""
        if math.isfinite(outputs.sum()) and math.isfinite(system.yd.sum()):
            return
        if not (np.isfinite(outputs).all() and np.isfinite(system.yd).all()):
            raise StepFailure(system.t, "the state is not finite (NaN or overflow)")

    def _output_values(self, iterations: int, row: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(value references, values) of every output at the current state, not yet written; row: the
        body's output_row at this state if already computed (BodySystem.run_extrapolated fills one), else computed.

        Port fields come from the row's port_array part (one row per port, columns OUTPUT_FIELDS, 3 or
        9 each, R row-major as the variables), then the energies, the iterations, the probes and the
        modal coordinates with their rates: one gather with a map built on first use."""
        if self._output_map is None:
            self._output_map = self._build_output_map()
        dst, src, seen, frame, dX = self._output_map
        row = self.system.output_row() if row is None else row
        row[-1] = iterations  # the most of the communication step's internal steps, not the last one's
        extra = []
        if seen.size:  # probes, eq. (92): d = R_f^T (r_s - r_f) - (X_s - X_f), one per probe
            pr = row[: BodySystem.OUTPUT_WIDTH * len(self.data.ports)].reshape(len(self.data.ports), -1)
            R, r = FIELD_COLUMNS["R"], FIELD_COLUMNS["r"]
            extra.append(tip_from_hub(pr[frame, R].reshape(-1, 3, 3), pr[frame, r], pr[seen, r], dX).ravel())
        if ("modal", "eta") in self.index:  # the modal coordinates and their rates (the eta slots of the rates)
            nm = self.system.layout.nm
            extra += [self.system.eta.ravel(), self.system.yd[self.system.layout.cfg_map[:, 6 : 6 + nm].ravel()]]
        if extra:
            row = np.concatenate([row, *extra])
        return dst, row[src]

    def _build_output_map(self) -> tuple:
        """(value references, positions in [output_row, probes, eta, eta rates] (variables.output_sources), then
        per probe the rows of its seen and frame ports and X_s - X_f) of `_output_values`."""
        probes = list(self.config["parameters"].get("probes", ()))
        dst, src = output_sources(self.variables, self.data.ports, probes)
        row_of = {p.name: j for j, p in enumerate(self.data.ports)}
        X, seen, frame, dX = self.data.node_positions, [], [], []
        for name in probes:
            s, _, f = name.partition("_from_")
            seen.append(row_of[s])
            frame.append(row_of[f])
            dX.append(X[self.data.port(s).node] - X[self.data.port(f).node])
        return (np.array(dst, dtype=int), np.array(src, dtype=int), np.array(seen, dtype=int),
                np.array(frame, dtype=int), np.array(dX, dtype=float).reshape(-1, 3))

    def _write_outputs(self, iterations: int) -> None:
        dst, out = self._output_values(iterations)
        self.values[dst] = out

    # ------------------------------------------------------------------ FMU state
    def get_state(self) -> dict:
        """A complete snapshot (arrays are copies): values, mode, time, body integrator state
        (which includes the body's Newton iteration matrix: a restored run takes bit-identical
        steps)."""
        sys_state = None if self.system is None else self.system.get_state()
        return {
            "version": STATE_VERSION,
            "values": self.values.copy(),
            "mode": self.mode,
            "start_time": self.start_time,
            "failure": self.failure,
            "system": None if sys_state is None else sys_state.copy(),
            "initialized_with": None if self._initialized_with is None else self._initialized_with.copy(),
        }

    def set_state(self, state: dict) -> None:
        if state.get("version") != STATE_VERSION:
            raise ValueError(f"FMU state version {state.get('version')!r} is not {STATE_VERSION}")
        values = np.asarray(state["values"], dtype=float)
        if values.shape != self.values.shape:
            raise ValueError(f"FMU state has {values.size} values, this FMU has {self.values.size}")
        self.values = values.copy()
        self.mode = str(state["mode"])
        self.start_time = float(state["start_time"])
        self.failure = str(state["failure"])
        self.discarded = ""  # a restored state is a fresh start from its time
        self.last_step = None  # derivatives need a doStep from it
        iw = state.get("initialized_with")
        self._initialized_with = None if iw is None else np.asarray(iw, dtype=float).copy()
        if state["system"] is None:
            self.system = None
            self._system_params = None
        else:
            self._make_system().set_state(np.asarray(state["system"], dtype=float))


    @staticmethod
    def state_to_bytes(state: dict) -> bytes:
        buf = io.BytesIO()
        arrays = {
            "values": state["values"],
            "meta": np.array(json.dumps({k: state[k] for k in ("version", "mode", "start_time", "failure")})),
        }
        if state["system"] is not None:
            arrays["system"] = state["system"]
        if state["initialized_with"] is not None:
            arrays["initialized_with"] = state["initialized_with"]
        np.savez(buf, **arrays)
        return buf.getvalue()

    @staticmethod
    def state_from_bytes(blob: bytes) -> dict:
        with np.load(io.BytesIO(bytes(blob)), allow_pickle=False) as z:
            state = json.loads(str(z["meta"]))
            state["values"] = z["values"].copy()
            state["system"] = z["system"].copy() if "system" in z.files else None
            state["initialized_with"] = z["initialized_with"].copy() if "initialized_with" in z.files else None
        return state
