"""A rigid partner's one degree of freedom stepped together with a body (the monolithic references:
examples/crank_monolithic.py's piston, studies/stability/monolithic.py's hub).

The partner's state y = (x, v) is integrated by the body's first-order generalized-alpha
(runtime/integrator.py: the same am, af, gamma, equations at t_{n+1}). With A0 = c1 y' + c2 a,
c1 = (1 - af)/am, c2 = -(1 - am)/am, and D0 = h ((1 - gamma) a + gamma A0), its one unknown per step,
the acceleration s = v'_{n+1}, fixes
    v_{n+1} = v_n + D0[1] + beta s,   x_{n+1} = x_n + D0[0] + beta v_{n+1},   beta = h gamma af / am,
and after the step a = (af/am) (v_{n+1}, s) + A0. The partner's equation r(s) = 0, whose residual
steps the body from its saved state, is solved by secant steps (`solve`).
"""
from __future__ import annotations

import numpy as np

from ..runtime.integrator import alpha_coefficients
from ..runtime.ports import StepFailure


class PartnerDof:
    """The partner's (x, v), its rates and generalized-alpha's a, all 0 at rest; h the step."""

    def __init__(self, rho_inf: float, h: float):
        self.am, self.af, self.gamma = alpha_coefficients(rho_inf)
        self.h = h
        self.beta = h * self.gamma * self.af / self.am
        self.c1, self.c2 = (1.0 - self.af) / self.am, -(1.0 - self.am) / self.am
        self.y, self.yd, self.a = np.zeros(2), np.zeros(2), np.zeros(2)
        self.s = 0.0  # the last step's acceleration: the next step's first guess

    def begin(self) -> None:
        """A0 and D0 of the step from t_n (module doc)."""
        self.A0 = self.c1 * self.yd + self.c2 * self.a
        self.D0 = self.h * ((1.0 - self.gamma) * self.a + self.gamma * self.A0)

    def state(self, s: float) -> tuple[float, float]:
        """(x_{n+1}, v_{n+1}) for the acceleration s."""
        v1 = self.y[1] + self.D0[1] + self.beta * s
        return self.y[0] + self.D0[0] + self.beta * v1, v1

    def solve(self, residual, slope: float, tolerance: float, iterations: int, t: float, what: str) -> float:
        """s with |r(s)| <= tolerance * scale, residual(s) -> (r, scale): secant steps from the last
        step's s, the first with the partner's own slope (its mass or inertia). Raises StepFailure at t
        after `iterations` residuals (or a flat secant), naming `what` and the residual [its unit]."""
        s0 = self.s
        r_a, _ = residual(s0)
        s1 = s0 - r_a / slope
        r_b, scale = residual(s1)
        it = 2
        while abs(r_b) > tolerance * scale:
            if it >= iterations or r_b == r_a:
                raise StepFailure(t, what.format(it=it, residual=r_b))
            s0, s1, r_a = s1, s1 - r_b * (s1 - s0) / (r_b - r_a), r_b
            r_b, scale = residual(s1)
            it += 1
        return s1

    def accept(self, s: float) -> tuple[float, float]:
        """End the step at the acceleration s; (x_{n+1}, v_{n+1})."""
        x1, v1 = self.state(s)
        yd_new = np.array([v1, s])
        self.a = (self.af / self.am) * yd_new + self.A0
        self.y, self.yd, self.s = np.array([x1, v1]), yd_new, s
        return x1, v1
