"""One FMU instance under fmpy's FMU2Slave: name-based access, the messages it logged, its directional
derivatives (fmi2GetDirectionalDerivative, FMI's meaning) and a body FMU's derivatives of its last step
(ffrf2GetStepDerivative, the interface-Jacobian master's)."""
from __future__ import annotations

import shutil
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

import numpy as np


# the body FMUs' derivatives of their last communication step (fmu/native/fmi2Functions.c, fmu/native_loader.c):
# exported beside the fmi2 functions, with fmi2GetDirectionalDerivative's signature and a non-FMI meaning
STEP_DERIVATIVE = "ffrf2GetStepDerivative"


class CoSimulationError(RuntimeError):
    """An FMU refused a step (discard/error) or the setup is inconsistent."""


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

    @property
    def provides_derivatives(self) -> bool:
        return bool(self.md.coSimulation.providesDirectionalDerivative)

    def derivative(self, unknowns: list[str], knowns: list[str], seeds) -> np.ndarray:
        """fmi2GetDirectionalDerivative: d(unknowns) along `seeds` on the knowns (Real variables), FMI's
        meaning: the partial derivatives at the current communication point (zero for a body FMU, whose
        outputs have no direct feedthrough; docs/fmu.md)."""
        return np.array(self.fmu.getDirectionalDerivative(self._vrs(unknowns), self._vrs(knowns),
                                                          [float(x) for x in seeds]))

    @property
    def provides_step_derivatives(self) -> bool:
        """The FMU exports STEP_DERIVATIVE, the derivatives of its last communication step (a body FMU of
        this package: docs/fmu.md, "Directional derivatives"; not an FMI function)."""
        return hasattr(self.fmu.dll, STEP_DERIVATIVE)

    def step_derivative(self, unknowns: list[str], knowns: list[str], seeds) -> np.ndarray:
        """d(outputs at t_c + H) along `seeds` on the inputs held over the last doStep(t_c, H): the body FMU's
        STEP_DERIVATIVE, the same arguments and statuses as fmi2GetDirectionalDerivative."""
        f = getattr(self.fmu.dll, STEP_DERIVATIVE)
        f.argtypes = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_uint), c_size_t, POINTER(c_double),
                      POINTER(c_double)]
        f.restype = c_int
        u, k = self._vrs(unknowns), self._vrs(knowns)
        out = (c_double * len(u))()
        status = f(self.fmu.component, (c_uint * len(u))(*u), len(u), (c_uint * len(k))(*k), len(k),
                   (c_double * len(k))(*[float(x) for x in seeds]), out)
        if status != 0:
            raise CoSimulationError(f"{self.name}: {STEP_DERIVATIVE} returned status {status}: {self.last_message()}")
        return np.array(out[:])

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
