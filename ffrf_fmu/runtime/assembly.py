"""The numpy path's body equations: every superelement through the plain oracle (runtime/equations.py
`residual_and_jacobian`), one at a time, assembled into the body's rows. BodySystem on the numpy backend
(the reference run the C runtime is checked against, and where no C compiler is found) evaluates its
residual and Jacobian here; on the native backend the C runtime does (runtime/native, `ffrf_body_residual`).

The superelements as the body runs them, built once: the reduced matrices under the term set's switches
(the gyroscopic parts `parts`), the structural damping D of the body (runtime/damping.py, which an FMU's
parameters may set apart from the model file's) and the stiffening hooks on the body's W1, W2 (W2 less
its gyroscopic part when the Coriolis terms are on: BodySystem holds it so).
"""
from __future__ import annotations

import numpy as np

from . import equations, stiffening


class Assembly:
    """The oracle's superelements of one BodySystem and the map of their local rows into the body's."""

    def __init__(self, system):
        L = self.layout = system.layout
        D, W1, W2 = system.D, system.W1, system.W2
        self.superelements = [equations.Superelement(system.K[e], system.M[e], system.G[e], system.mass[e], system.J0[e],
                                                     system.X_B[e], None if D is None else D[e]) for e in range(L.n_se)]
        self.hooks = [{} for _ in range(L.n_se)]
        if W1 is not None:  # geometric stiffening, deformation-dependent inertia (runtime/stiffening.py)
            for e, hooks in enumerate(self.hooks):
                membrane = (system.vk_a[e], system.vk_B[e]) if system.stiffening else (None, None)
                g_term, row_term = stiffening.plain_hooks(W1[e], *membrane, None if W2 is None else W2[e])
                hooks.update(g_terms=(g_term,), row_terms=(row_term,))
        self.parts = tuple(p for p, on in (("inertia_coupling", system.inertia_coupling), ("coriolis", system.coriolis)) if on)
        self.nodes = system.se_nodes
        self.rows = np.concatenate([L.vel_map, L.cfg_map], axis=1)  # local row -> global row

    def evaluate(self, p, yd, R, gravity, jacobian: bool):
        """The assembled residual without loads F (ny,) at the stage p, yd (ny,) and the rotations R
        (N + E, 3, 3) (runtime/layout.py `stage`), and with jacobian the local blocks F_ydot, F_y
        (E, nv + nc, nc + nv); (F, None, None) without."""
        L, N = self.layout, self.layout.n_nodes
        xN = p[: 6 * N].reshape(N, 6)[:, 0:3]
        F = np.zeros(L.ny)
        Fz, Fy = [], []
        for e, se in enumerate(self.superelements):
            cfg, vel, nodes = L.cfg_map[e], L.vel_map[e], self.nodes[e]
            Fe, Fze, Fye = equations.residual_and_jacobian(
                se, "linear", gravity, p[cfg[0:3]], R[N + e], p[cfg[6 : 6 + L.nm]], xN[nodes], R[nodes], p[vel],
                yd[cfg], yd[vel], parts=self.parts, **self.hooks[e])
            F[self.rows[e]] += Fe  # (the rows of one superelement are distinct)
            Fz.append(Fze)
            Fy.append(Fye)
        if not jacobian:
            return F, None, None
        return F, np.stack(Fz), np.stack(Fy)
