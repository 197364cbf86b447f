"""The body FMU's signals: its inputs checked into the point values of a communication step, its outputs
gathered from the body's output row.

`Signals` is the input and output half of `core.BodyCoSim` (a mixin: it reads the instance's `values`,
`variables`, `input_ix`, `_point_map`, `data`, `config` and `system`). The maps are built once: the
point-value map in BodyCoSim.__init__, the output map on first use (runtime/outputs.py `output_sources`,
the one map of both FMUs).
"""
from __future__ import annotations

import math

import numpy as np

from ..runtime.body import BodySystem
from ..runtime.outputs import FIELD_COLUMNS, output_sources, tip_from_hub
from ..runtime.ports import StepFailure
from ..runtime.rotation import ROTATION_TOL, rotation_defect

ROTATION_EXACT = 1e-12  # re-orthonormalize R (polar factor) when max |R^T R - I| exceeds this


class Signals:
    """The FMU's inputs and outputs (see the module docstring)."""

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


    # ------------------------------------------------------------------ outputs
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
