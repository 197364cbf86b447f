"""The full-order beam at a steady spin: the relative equilibrium a scene with [scenes.NAME.initial]
state = "steady_spin" starts from (the twin of ffrf_fmu/initial_state.py for the reduced body).

The body spins rigidly at w (world, about an axis through the origin, the rotation drive's rate at t0):
every node moves with x_dot = w x x, its material angular velocity is W = R^T w (constant: W_dot =
-W x W = 0), its acceleration the centripetal w x (w x x). The equilibrium of `solver`'s equations
under that motion is

    r(x, R) = M_t (w x (w x x)) + f_x(x, R) - f_g - F = 0,   W x J W + f_theta(x, R) - R^T T = 0,

(the consistent translational mass M_t integrates the centripetal load exactly). Newton with the tangent
K_t (elements) + M_t [w]^2 (the centripetal load's dependence on the positions: the centrifugal
softening) + ([W] J - [J W]) [W] (the gyroscopic moment's dependence on the node rotation, W = R^T w),
the spin ramped in `load_steps` steps of w^2 (the centripetal load linear in the step). The motion-driven
ports are held where the drives put them at t0: Newton starts from the reference configuration turned
rigidly by the drive's angle at t0 about the spin axis.
"""
from __future__ import annotations

import math

import numpy as np

from ..runtime.drives import evaluate
from ..runtime.rotation import cross, expm, skew
from .beam import newton


def spin_of(scene, t0: float = 0.0) -> tuple[np.ndarray, float, np.ndarray]:
    """(w (world spin vector), the drive's angle at t0, unit axis) of the scene's rotation drive, which
    must spin steadily at t0 (initial_state._spin, the same checks and messages)."""
    from ..initial_state import _spin

    w = _spin(scene, t0)
    d = next(d for d in scene.drives if d.rotation is not None)
    phi = evaluate(d.rotation.angle.kind, dict(d.rotation.angle.params), t0)[0]
    return w, float(phi), w / np.linalg.norm(w)


def steady_spin_state(mesh, sc, w, phi: float, F: np.ndarray, T: np.ndarray, *, banded, internal, load_steps: int = 4,
                      tol: float = 1e-10, max_iterations: int = 40):
    """(x, R, v, vd) of the relative equilibrium at the spin w (module doc) on `mesh` with the scene's
    causality, gravity and drives `sc` (assembly._Scene), port loads F, T (nn, 3) world; R are the nodal
    section frames, v (nn, 6) the velocities (world translational, material angular), vd the accelerations.
    The drives' axis must pass through the origin (initial_state: the same relative equilibrium).
    banded, internal: solver's band matrix and internal forces (passed in: solver imports this module)."""
    w = np.asarray(w, dtype=float)
    a = w / np.linalg.norm(w)
    for k, X, *_ in sc.trans:
        if np.linalg.norm(np.cross(a, X)) > 1e-9 * mesh.length:
            raise ValueError("reference: initial state 'steady_spin' needs the spin axis through the motion-driven "
                             f"ports (node {k} at {X.tolist()} is off the axis through the origin)")
    nn, ne, J = mesh.nn, mesh.ne, mesh.J
    band = banded(mesh, sc.free, with_mass=False)
    free = sc.free.reshape(nn, 6)
    # the element share of the translational mass: each element's ends take md / (number of elements at
    # the node), its off-diagonal the consistent mo; their sum over the elements is M_t
    share = np.full(nn, 0.5)
    share[0] = share[-1] = 1.0
    diag = mesh.md * share
    Q = expm(phi * a)  # the drive's angle at t0: the body turned rigidly with the hub, the hub where it is driven
    x = mesh.X @ Q.T
    R = np.repeat((Q @ mesh.Lam0)[None], nn, axis=0)
    f_ext = sc.f_gravity + F
    for step in range(1, load_steps + 1):
        ws = w * math.sqrt(step / load_steps)
        W2 = skew(ws) @ skew(ws)
        Kc = np.zeros((ne, 12, 12))
        Kc[:, 0:3, 0:3] = diag[:-1, None, None] * W2
        Kc[:, 6:9, 6:9] = diag[1:, None, None] * W2
        Kc[:, 0:3, 6:9] = Kc[:, 6:9, 0:3] = mesh.mo[:, None, None] * W2
        def correction(x, R, ws=ws, Kc=Kc):
            fint, st = internal(mesh, x, R)
            acc = np.zeros((nn, 6))
            acc[:, :3] = cross(ws, cross(ws, x))
            W = np.einsum("nji,j->ni", R, ws)
            JW = J * W
            r = mesh.mass_times(acc) + fint
            r[:, :3] -= f_ext
            r[:, 3:] += cross(W, JW) - np.einsum("nji,nj->ni", R, T)
            Kr = (skew(W) * J[:, None, :] - skew(JW)) @ skew(W) - skew(np.einsum("nji,nj->ni", R, T))
            return band.solve(band.factor(mesh.elements.tangent_from(st) + Kc, Kr), -(r * free).ravel()).reshape(nn, 6)

        x, R, converged = newton(x, R, correction, mesh.length, tol, max_iterations)
        if not converged:
            raise RuntimeError(f"reference: initial state 'steady_spin': Newton did not converge at {math.sqrt(step / load_steps):.3g} "
                               f"x the spin ({max_iterations} iterations): the spin is beyond what the body holds")
    v = np.zeros((nn, 6))
    v[:, :3] = cross(w, x)
    v[:, 3:] = np.einsum("nji,j->ni", R, w)
    vd = np.zeros((nn, 6))
    vd[:, :3] = cross(w, cross(w, x))
    return x, R, v, vd
