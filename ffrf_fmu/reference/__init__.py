"""Full-order geometrically exact beam: the independent reference for the superelement path.

Shares no dynamics code with the superelement path: it imports only the model dataclasses
(`ffrf_fmu.model`), the drive time functions (`ffrf_fmu.runtime.drives`) and the package's one
SO(3) toolkit (`ffrf_fmu.runtime.rotation`, checked against exact arithmetic on its own in
tests/test_rotation.py); element, mass, integrator and Newton solver are its own (`beam`, `solver`).

Formulation choice: Simo-Reissner (geometrically exact) rather than co-rotational.
- It is exact for arbitrarily large displacements, rotations and (within the linear section law)
  strains; the only error is the spatial discretization, which converges as 1/n^2 (checked: static
  cantilever, elastica, B1). A co-rotational element is exact only in the limit of small rotations
  relative to each element's co-rotated frame, i.e. it contains a floating-frame approximation of
  its own, and the reference must not share the kind of approximation it is meant to check.
- Two-node elements with the strain-objective, path-independent rotation interpolation of
  Crisfield & Jelenic (1999), R(s) = R1 exp(s/L log(R1^T R2)): curvature exactly constant per
  element, shear/axial strain at the midpoint only (one-point reduced integration: no shear
  locking). The discrete energy is the exact element energy under this interpolation with the
  force strains sampled at the midpoint; forces are its exact gradient and the tangent is the
  exact (analytic) derivative, checked against finite differences in tests/test_reference.py.
- Shear: section GA2/GA3 used as given; None (Euler-Bernoulli section) is a shear-rigid limit
  realized by a penalty GA = 100 * 12 EI_max / L_e^2 (shear flexibility 1 % of an element's
  bending flexibility: 1/(400 n^2) relative on a cantilever tip deflection; locking-free thanks
  to the reduced integration).
- Inertia: consistent translational mass (exact for the linear velocity field, so centrifugal
  loads are integrated exactly), rotary inertia diag(m11, m22, m33) (m11 None -> m22 + m33) lumped
  at the nodes in section axes.
- Time integration: Lie-group generalized-alpha for second-order systems (Bruls, Cardona & Arnold
  2012) on (R^3 x SO(3))^N, rho_inf from the scene, Newton with the consistent iteration matrix,
  LAPACK band factorization reused across steps in a co-rotated way (see `solver`).

Conventions (same scene semantics as the superelement path):
- Section axes: axis 1 = beam direction, axis 2 = normalize(e_z x axis 1) (e_y for a beam along
  Z), axis 3 = axis 1 x axis 2; EI2 bends about axis 2.
- Ports sit at boundary nodes of the superelement chain (s = node * L / superelements); the mesh
  has n_elements (default max(16, 4 * superelements)), a multiple of body.superelements.
- Port outputs: r, v (world), R = nodal rotation relative to the world-aligned reference nodal
  frame (R = I at rest; for a beam along +X this is also the section frame), w = world angular
  velocity, f/t = force/moment applied ON the body by the environment at the node (the reaction
  for motion-driven parts, the scene's load for force-driven parts). RotationDrive: R(t) =
  exp(phi(t) axis) about the world axis through the port's reference position; TranslationDrive:
  r = r_ref + u(t) direction (axes and directions are normalized); a motion part without drive is
  fixed at the reference. Loads are dead (world-fixed) forces and moments, active on
  [t_start, t_end). Gravity acts on the (consistent) mass.
- Energies: "kinetic" (translational + rotary), "strain", "work_external" (trapezoidal integral
  of the power of loads, gravity and reactions); kinetic + strain - work_external minus its
  initial value is the integrator's energy error (O(h^2) plus the numerical dissipation set by
  rho_inf).

Step size: B1 (4 rad/s) is within 0.11 % of the converged maximum deflection at h = 20 ms; on
B3's profile the error at h = 20 ms is +0.29 % at 8 rad/s, and at 12 rad/s h = 20 ms goes
unstable with rho_inf 0.8 (generalized-alpha has no nonlinear stability guarantee; stable with
rho_inf 0.5) while h = 10 ms is within 0.12 %. Keep the rotation per step (spin rate * h) below
~0.12 rad; `info["energy_error"]` (that energy error / energy level, ~0.2 % for B1 at
20 ms, O(h^2)) is reported and a RuntimeWarning is issued above 2 %.

Initially deformed body (Initial.port_displacements): `relaxed_shape`, the static equilibrium the runtime
relaxes to (undisplaced ports held, translation and rotation; a displaced port held along its u only, at
u.(x - X) = |u|: pulled by u, free across it), then released with the rigid velocity field on that shape
(predictor "velocity" by default then: the release rings the mesh's top mode, `simulate_reference`).

Free bodies: `mass_properties` (CM, inertia about it, linear and angular momentum) is recorded at every
step (ReferenceResult.mass); the free-body metrics (ffrf_fmu.simulate, kind "momentum") read it.

Limits: relative rotation across one element below pi (always true on sane meshes).

Entry points: `simulate_reference`, `static_reference`, `tip_from_hub`; convergence study on B1:
`ffrf-fmu convergence`.
"""
from .mesh import Mesh
from .solver import ReferenceResult, simulate_reference, tip_from_hub
from .statics import StaticResult, static_reference

__all__ = ["ReferenceResult", "StaticResult", "Mesh", "simulate_reference", "static_reference", "tip_from_hub"]
