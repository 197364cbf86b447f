"""The full-order model's mesh and body data: nodes along the beam, section frames, the element forces'
tables (beam.BeamElements), the consistent translational and lumped rotary mass, and the mass properties
(CM, inertia, momenta) of a configuration. Used by the dynamics (solver.py) and the statics (statics.py)."""
from __future__ import annotations

import numpy as np

from ..model import Body
from ..runtime.rotation import cross
from .beam import BeamElements

_GA_PENALTY = 1.0e2  # shear-rigid sections: GA = 100 * 12 EI_max / L_e^2 (see Mesh)


# ============================================================================ mesh and body data
def section_frame(direction) -> np.ndarray:
    """Lambda0 = [e1 e2 e3]: e1 = beam direction, e2 = normalize(e_z x e1), e3 = e1 x e2.

    For a beam along +-Z (e_z x e1 = 0) e2 = e_y is used (stated convention of this module).
    """
    e1 = np.asarray(direction, dtype=float)
    e1 = e1 / np.linalg.norm(e1)
    e2 = cross(np.array([0.0, 0.0, 1.0]), e1)
    if np.linalg.norm(e2) < 1e-9:
        e2 = np.array([0.0, 1.0, 0.0])
    e2 = e2 / np.linalg.norm(e2)
    e3 = cross(e1, e2)
    return np.column_stack([e1, e2, e3])


class Mesh:
    """Uniform mesh of the body's beam: nodes, elements, mass, port nodes.

    Section stiffness: C_N = diag(EA, GA2, GA3), C_M = diag(GJ, EI2, EI3) in section axes.
    GA2/GA3 None (Euler-Bernoulli section) is modelled as shear-rigid by a penalty
    GA = 100 * 12 EI_max / L_e^2: the shear flexibility of an element is 1 % of its bending
    flexibility, so the shear adds 1/(400 n^2) relative to a cantilever's tip deflection (1e-5 at
    16 elements, 100 times below the element's own 1/(4 n^2) discretization error), while the
    conditioning and the stiffness of the shear modes stay moderate (a larger penalty made the
    Newton iteration struggle on B2's suddenly applied root torque); with one-point integration
    the penalty causes no locking.
    """

    def __init__(self, body: Body, n_elements: int | None = None):
        nse = int(body.superelements)
        if n_elements is None:
            n_elements = max(16, 4 * nse)
        n_elements = int(n_elements)
        if n_elements < 1 or n_elements % nse:
            raise ValueError(
                f"reference: n_elements={n_elements} must be a positive multiple of body.superelements={nse} "
                "so that every port lands on a finite-element node"
            )
        sec = body.section
        self.body = body
        self.ne = n_elements
        self.nn = n_elements + 1
        self.length = float(body.length)
        self.Le = self.length / n_elements
        self.Lam0 = section_frame(body.direction)
        self.origin = np.asarray(body.origin, dtype=float)
        s = np.linspace(0.0, self.length, self.nn)
        self.s = s
        self.X = self.origin + s[:, None] * self.Lam0[:, 0]
        ei_max = max(sec.EI2, sec.EI3)
        ga_pen = _GA_PENALTY * 12.0 * ei_max / self.Le**2
        self.shear_rigid = (sec.GA2 is None, sec.GA3 is None)
        GA2 = ga_pen if sec.GA2 is None else float(sec.GA2)
        GA3 = ga_pen if sec.GA3 is None else float(sec.GA3)
        self.elements = BeamElements(self.Le, [sec.EA, GA2, GA3], [sec.GJ, sec.EI2, sec.EI3])
        m = float(sec.m)
        m11 = sec.m22 + sec.m33 if sec.m11 is None else sec.m11
        w = np.full(self.nn, self.Le)
        w[0] = w[-1] = 0.5 * self.Le
        self.md = m * self.Le / 3.0 * np.where((np.arange(self.nn) == 0) | (np.arange(self.nn) == self.nn - 1), 1, 2)
        self.mo = np.full(self.ne, m * self.Le / 6.0)
        self.J = w[:, None] * np.array([m11, sec.m22, sec.m33], dtype=float)[None, :]
        self.mass = m * self.length
        for pm in body.masses:  # rigid bodies lumped at nodes: mass on the node, inertia in section axes
            k = int(round(pm.at / self.Le))
            if abs(pm.at - k * self.Le) > 1e-9 * self.length:
                raise ValueError(f"reference: point mass at {pm.at:g} m is not on a node of the {n_elements}-element mesh "
                                 f"(element length {self.Le:g} m): choose n_elements so that it is")
            self.md[k] += pm.mass
            self.J[k] += np.asarray(pm.inertia, dtype=float)
            self.mass += pm.mass
        self.M_dense = None
        if self.nn <= 80:  # one dense mat-vec beats five sliced updates at these sizes
            self.M_dense = self._mass_columns()
        per = n_elements // nse
        self.port_node = {p.name: (p.node % (nse + 1)) * per for p in body.ports}

    def mass_times(self, vd: np.ndarray) -> np.ndarray:
        """M @ vd for (..., nn, 6) generalized accelerations (translational consistent, rotary lumped)."""
        if vd.ndim == 2 and self.M_dense is not None:
            return (self.M_dense @ vd.ravel()).reshape(vd.shape)
        out = np.empty_like(vd)
        out[..., :3] = self.md[:, None] * vd[..., :3]
        out[..., :-1, :3] += self.mo[:, None] * vd[..., 1:, :3]
        out[..., 1:, :3] += self.mo[:, None] * vd[..., :-1, :3]
        out[..., 3:] = self.J * vd[..., 3:]
        return out

    def _mass_columns(self) -> np.ndarray:
        """Dense M (6 nn x 6 nn), built column by column from the sliced product."""
        eye = np.eye(6 * self.nn).reshape(6 * self.nn, self.nn, 6)
        saved, self.M_dense = self.M_dense, None
        cols = self.mass_times(eye).reshape(6 * self.nn, 6 * self.nn)
        self.M_dense = saved
        return np.ascontiguousarray(cols.T)

    def kinetic_energy(self, v: np.ndarray) -> np.ndarray:
        """0.5 v^T M v for (..., nn, 6) velocities."""
        return 0.5 * np.sum(v * self.mass_times(v), axis=(-2, -1))


def mass_properties(mesh: Mesh, x: np.ndarray, R: np.ndarray, v: np.ndarray):
    """(CM (3,), inertia tensor about the CM (3, 3), linear momentum (3,), angular momentum about the CM
    (3,)) of the beam at nodal positions x (nn, 3), rotations R (nn, 3, 3) (section frames) and velocities
    v (nn, 6) (world translational, section-axes angular), world axes: the consistent translational mass
    (exact for the linear interpolation of positions and velocities along each element), the rotary
    inertia lumped at the nodes in section axes (R J R^T), point masses on their nodes."""
    md, mo, vt = mesh.md, mesh.mo, v[:, :3]
    c = (md @ x + mo @ (x[:-1] + x[1:])) / mesh.mass
    y = x - c
    p = md @ vt + mo @ (vt[:-1] + vt[1:])
    h = md @ cross(y, vt) + mo @ (cross(y[:-1], vt[1:]) + cross(y[1:], vt[:-1]))
    h = h + np.einsum("nij,nj->i", R, mesh.J * v[:, 3:])
    S = np.einsum("n,ni,nj->ij", md, y, y) + np.einsum("n,ni,nj->ij", mo, y[:-1], y[1:])
    S = S + S.T - np.einsum("n,ni,nj->ij", md, y, y)  # md y y^T once, the mo pairs both ways
    J_cm = np.trace(S) * np.eye(3) - S + np.einsum("nik,nk,njk->ij", R, mesh.J, R)
    return c, J_cm, p, h
