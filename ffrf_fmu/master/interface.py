"""Linearly implicit coupling with interface Jacobians (`CoSimulation(interface_jacobian=True)`).

Kuebler and Schiehlen 2000; Sadjina et al. 2017: no iteration to convergence but one Newton step
on the interface equations of implicit coupling. At t_c the FMU states are saved; the sweep from
them is a map x -> G(x) of the iterated held inputs (the implicit scheme's unknowns); with its
coupling Jacobian J = dG/dx over the step (outputs at t_c + H w.r.t. inputs held over
[t_c, t_c + H], chained through the receivers in the sweep) one linear solve
(I - J) dx = G(x_0) - x_0 gives the interface inputs, and the real step is the sweep at x_0 + dx.
For linear subsystems this is the converged implicit step; the FMUs' nonlinearity over one step
leaves a residual that is not iterated away.

J comes from (`jacobian`):
- "fmu": the sweep at x_0, then per iterated input a tangent sweep: each FMU gets the direction
  of its inputs and returns the direction of its outputs at t_c + H, by the derivatives of its last
  step when it exports them (a body FMU's ffrf2GetStepDerivative, docs/fmu.md: not FMI's
  fmi2GetDirectionalDerivative, whose partial derivatives at the communication point are zero for
  outputs without direct feedthrough), else by a forward difference of its own step from its saved state. 2 sweeps a step, plus the
  derivative work inside the FMUs.
- "fd": forward differences of the whole sweep, one sweep per iterated input from the restored
  states: n + 2 sweeps for n iterated inputs.
- "auto" (default): "fmu" when at least one FMU exports the derivatives of its step.
"""
from __future__ import annotations

import numpy as np

from .instance import CoSimulationError
from .links import Signal, _split


class InterfaceJacobian:
    """The linearly implicit step of `schemes.CoSimulation` (a mixin: it works on the master's
    instances, links and sweep)."""

    def _coupling_jacobian(self, t, h, ext, prev, cur, need, iterated, x0, g0, restore) -> np.ndarray:
        """J = dG/dx of the sweep map at x0 (G(x0) = g0 given), by forward differences, one sweep
        from the saved states per iterated input (jacobian="fd")."""
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

    def _jacobian_source(self) -> str:
        """'fmu' or 'fd' for this run: the `jacobian` argument, 'auto' = 'fmu' when at least one FMU
        provides directional derivatives."""
        if self.jacobian == "auto":
            return "fmu" if any(inst.provides_step_derivatives for inst in self.instances.values()) else "fd"
        return self.jacobian

    def _fmu_coupling_jacobian(self, t, h, cur, fresh0, need, iterated, states) -> np.ndarray:
        """J = dG/dx of the sweep map at the sweep just done (x0, fresh0) from each FMU's derivatives
        (jacobian="fmu"): per iterated input, a tangent sweep: each FMU in the sweep's order gets the
        input direction (the iterated input's unit seed, and the derivative of every fresh link from
        the directions its source returned) and returns the direction of its linked outputs at
        t_c + H (`_step_derivative`)."""
        keys = [l.dst for l in iterated]
        J = np.empty((len(keys), len(keys)))
        for j in range(len(keys)):
            dfresh: dict[str, float] = {}
            done: set = set()
            for name in self.order:
                du: dict[str, float] = {}
                if self.scheme == "gauss-seidel":
                    for l in self._links_into(name):
                        if self._src_inst(l) in done:
                            du.update(self._fresh_tangent(l, h, cur, fresh0, dfresh))
                for i, k in enumerate(keys):  # the iterated inputs are the unknowns x: they override links
                    if _split(k)[0] == name:
                        du[k] = 1.0 if i == j else 0.0
                du = {k: v for k, v in du.items() if v != 0.0}
                outs = need[name]
                if du and outs:
                    d = self._step_derivative(name, t, h, outs, du, fresh0, states[name])
                    dfresh.update(zip((f"{name}.{o}" for o in outs), d))
                else:
                    dfresh.update({f"{name}.{o}": 0.0 for o in outs})
                done.add(name)
            J[:, j] = [l.gain * dfresh[l.src] for l in iterated]
        return J

    def _step_derivative(self, name, t, h, outs, du, fresh0, state) -> np.ndarray:
        """Derivative of FMU `name`'s outputs `outs` at t + h along the input direction du, at its
        step in the sweep just done: the derivatives of its last step when the FMU exports them (a body
        FMU's ffrf2GetStepDerivative, docs/fmu.md), else a forward difference of the FMU's
        own step from its saved state (relative step fd_step); the FMU is then left past a perturbed
        step, which the real sweep's restore undoes."""
        inst = self.instances[name]
        knowns = [_split(k)[1] for k in du]
        if inst.provides_step_derivatives:
            try:
                return inst.step_derivative(outs, knowns, list(du.values()))
            except Exception as e:  # noqa: BLE001 - fmpy raises FMICallException with the status
                raise CoSimulationError(f"{name}: directional derivative of the step from t = {t:.6g} s failed: "
                                        f"{inst.last_message()} ({e})") from None
        base = self._applied[name]
        d = np.array(list(du.values()))
        eps = self.fd_step * max(1.0, max(abs(base.get(k, 0.0)) for k in du)) / float(np.max(np.abs(d)))
        inst.fmu.setFMUstate(state)
        self._apply({**base, **{k: base[k] + eps * v for k, v in du.items()}})
        self._do_step(name, t, h)
        return (inst.get(outs) - np.array([fresh0[f"{name}.{o}"] for o in outs])) / eps

    def _fresh_tangent(self, link, H: float, cur: dict, fresh: dict, dfresh: dict) -> dict:
        """Directional derivative of `_fresh` (the values a fresh link gives) at `fresh` along
        `dfresh`: exact for Signal links and translations (linear), central differences of the closed
        form for a rotation's expm(-H w) R (relative step 1e-7: ~1e-9 relative error)."""
        src = (link.src,) if isinstance(link, Signal) else link.src
        d = np.array([dfresh.get(n, 0.0) for n in src])
        if not d.any():
            return {}
        if isinstance(link, Signal) or link.kind == "translation":
            tau = 1.0
        else:
            tau = 1e-7 * max(1.0, max(abs(fresh[n]) for n in src)) / float(np.max(np.abs(d)))
        up = dict(fresh, **{n: fresh[n] + tau * x for n, x in zip(src, d)})
        down = dict(fresh, **{n: fresh[n] - tau * x for n, x in zip(src, d)})
        a, b = self._fresh(link, H, cur, up), self._fresh(link, H, cur, down)
        return {k: (a[k] - b[k]) / (2.0 * tau) for k in a}

    def _linearly_implicit_step(self, t, h, ext, prev, cur, need, iterated, source) -> int:
        """One linearly implicit step (module docstring): predictor x0 = the stale inputs, G(x0)
        and J = dG/dx from the saved states (source "fd": finite differences, n sweeps; "fmu": the
        FMUs' directional derivatives at the sweep at x0), x = x0 + (I - J)^-1 (G(x0) - x0), the
        real sweep at x. Returns the sweeps done (n + 2 with "fd", 2 with "fmu")."""
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
            if source == "fmu":
                J = self._fmu_coupling_jacobian(t, h, cur, fresh, need, iterated, states)
            else:
                J = self._coupling_jacobian(t, h, ext, prev, cur, need, iterated, x0, g0, restore)
            A = np.eye(len(x0)) - J
            try:
                x = x0 + np.linalg.solve(A, g0 - x0)
            except np.linalg.LinAlgError:
                raise CoSimulationError(f"interface Jacobian at t = {t:.6g} s: I - dG/dx is singular") from None
            restore()
            self._sweep(t, h, ext, prev, cur, dict(zip(keys, x)), need)
            return 2 if source == "fmu" else len(x0) + 2
        finally:
            for name, inst in self.instances.items():
                inst.fmu.freeFMUstate(states[name])
