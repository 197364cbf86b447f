"""What a body FMU does, without pythonfmu: values, initialization, communication steps, state.

The pythonfmu slave (slave_template.py) is a thin shell around `BodyCoSim`; keeping the logic
here makes it testable in-process and the same code runs inside every FMU (the builder copies
this module and its halves next to a copy of ffrf_fmu/runtime). Imports: numpy, the standard library and the
runtime package (relative), nothing else.

Inputs between communication points and internal steps: variables.INPUTS_BETWEEN_COMMUNICATION_POINTS
and variables.INTERNAL_STEPS (the one source of the modelDescription text and docs/fmu.md). As
H -> 0 the extrapolated inputs tend to the exact signals, so the FMU run tends to the standalone
run (which evaluates the exact signals at every internal step).

`BodyCoSim` is the FMU's state machine (values, initialization, communication steps) over its halves:
the parameters and the body they make (fmu/parameters.py), the inputs and outputs (fmu/signals.py), the
FMU state (fmu/state.py); the directional derivatives of the last step (re-runs of it) are in
fmu/derivatives.py.
"""
from __future__ import annotations

import contextlib
import json
import math
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..runtime import input_rule
from ..runtime.data import BodyData
from ..runtime.ports import IterationCapReached, StepFailure
from ..runtime.steps import whole_steps
from ..runtime.terms import TERM_SETS
from ..runtime.body import BodySystem
from .derivatives import LastStep, directional_derivative
from .parameters import Parameters
from .signals import Signals
from .state import FmuState
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


class BodyCoSim(Parameters, Signals, FmuState):
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
        n, hh = whole_steps(H, h)  # n equal internal steps of at most solver.step, never a sliver
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
