"""The body FMU's parameters: read from the value array, checked before a run, and the body they make.

`Parameters` is the parameter half of `core.BodyCoSim` (a mixin: it reads the instance's `values`,
`index`, `data`, `config`, start and stop time, and keeps its `system`); the native FMU's twin of
the checks is fmu/native/model.c `check_parameters`.
"""
from __future__ import annotations

import math

import numpy as np

from ..runtime.body import BodySystem
from ..runtime.damping import Damping
from ..runtime.terms import TERM_SETS


class Parameters:
    """The FMU's parameters (see the module docstring)."""

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
        if not (0.0 <= cap <= 2**31 - 1 and cap == int(cap)):  # the runtime's cap is a C int
            return f"parameter solver.max_newton_iterations must be an integer in 0 .. 2^31 - 1 (0: no cap), got {cap!r}"
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
