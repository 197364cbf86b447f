"""The reference's statics: `relaxed_shape` (the static equilibrium of an initially deformed body with
prescribed port displacements) and `static_reference` (equilibrium under the scene's loads), by Newton on
the banded tangent in load steps."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..model import Body
from ..runtime.rotation import skew
from .assembly import _Banded, _internal
from .beam import newton
from .mesh import Mesh


class StaticResult(NamedTuple):
    r: np.ndarray  # (n_nodes, 3) node positions
    R: np.ndarray  # (n_nodes, 3, 3) node rotations relative to the reference (R = I unloaded)



def relaxed_shape(mesh: Mesh, body: Body, displacements: dict, *, load_steps: int = 5, tol: float = 1e-10,
                  max_iterations: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """The initially deformed body (scene.initial.port_displacements {port: u}), as the runtime makes it
    (BodySystem._relax): static equilibrium without loads or inertia with every undisplaced port's
    translation and rotation fixed, each displaced port fixed only along its u (at u.(x - X) = |u|, free
    across u: a force along u moved it there) and its rotation free unless motion-driven: for a free beam
    with its far end displaced, the cantilever shape. The constraints enter as Lagrange multipliers: two
    banded solves per constraint and iteration (bordered system). Nodal (x, R) with R including the section
    frame Lam0; the reference configuration when nothing is displaced."""
    nn = mesh.nn
    x = mesh.X.copy()
    R = np.repeat(mesh.Lam0[None], nn, axis=0)
    if not displacements:
        return x, R
    unknown = set(displacements) - {p.name for p in body.ports}
    if unknown:
        raise ValueError(f"reference: initial displacements of unknown ports {sorted(unknown)}")
    presc = np.zeros((nn, 6), bool)
    displaced = []  # (node, unit direction, |u|) of the displaced ports
    for p in body.ports:
        k = mesh.port_node[p.name]
        u = np.asarray(displacements.get(p.name, np.zeros(3)), float)
        if np.linalg.norm(u) == 0.0:
            presc[k, :3] = True
        else:
            displaced.append((k, u / np.linalg.norm(u), float(np.linalg.norm(u))))
        if p.name not in displacements or p.rotation == "motion":
            presc[k, 3:] = True
    band = _Banded(mesh, (~presc).ravel(), with_mass=False)
    C = np.zeros((len(displaced), nn, 6))
    for j, (k, e, _) in enumerate(displaced):
        C[j, k, :3] = e
    C = C.reshape(len(displaced), -1)
    for step in range(1, load_steps + 1):
        def correction(x, R, step=step):
            fint, st = _internal(mesh, x, R)
            try:
                fac = band.factor(mesh.elements.tangent_from(st), None)
            except np.linalg.LinAlgError:  # the fixed parts leave the body a mechanism: no unique shape
                return None
            y1 = band.solve(fac, -fint.ravel())
            Y2 = np.column_stack([band.solve(fac, c) for c in C] or [np.zeros(len(y1))])[:, : len(C)]
            gap = np.array([step / load_steps * size - e @ (x[k] - mesh.X[k]) for k, e, size in displaced])
            lam = np.linalg.solve(C @ Y2, gap - C @ y1)
            return (y1 + Y2 @ lam).reshape(nn, 6)

        x, R, converged = newton(x, R, correction, mesh.length, tol, max_iterations)
        if not converged:
            raise RuntimeError(f"reference: initial port displacements {sorted(displacements)}: no static equilibrium "
                               f"of the deformed body ({max_iterations} Newton iterations); smaller displacements, or "
                               "ports whose displacements the body can hold")
    return x, R


def static_reference(
    body: Body,
    loads: dict,
    fixed=None,
    n_elements: int | None = None,
    *,
    gravity=(0.0, 0.0, 0.0),
    load_steps: int = 10,
    tol: float = 1e-10,
    max_iterations: int = 30,
) -> StaticResult:
    """Static equilibrium under dead port loads {port: (force(3), moment(3))} in world axes
    (and gravity acting on the consistent mass, scaled with the loads).

    fixed: port names clamped at the reference (position and rotation); None -> every port part
    whose causality is "motion" in the body is fixed at the reference. Newton with `load_steps`
    equal load increments.
    """
    mesh = Mesh(body, n_elements)
    nn = mesh.nn
    presc = np.zeros((nn, 6), bool)
    for p in body.ports:
        k = mesh.port_node[p.name]
        if fixed is None:
            presc[k, :3] |= p.translation == "motion"
            presc[k, 3:] |= p.rotation == "motion"
        elif p.name in set(fixed):
            presc[k] = True
    if fixed is not None:
        unknown = set(fixed) - {p.name for p in body.ports}
        if unknown:
            raise ValueError(f"reference: unknown fixed ports {sorted(unknown)}")
    free = ~presc
    band = _Banded(mesh, free.ravel(), with_mass=False)
    Ftot = np.zeros((nn, 3))
    Ttot = np.zeros((nn, 3))
    for name, (f, m) in loads.items():
        k = mesh.port_node[body.port(name).name]
        Ftot[k] += np.asarray(f, float)
        Ttot[k] += np.asarray(m, float)
    g = np.asarray(gravity, dtype=float)
    Ftot += (mesh.md + np.concatenate([mesh.mo, [0.0]]) + np.concatenate([[0.0], mesh.mo]))[:, None] * g
    x = mesh.X.copy()
    R = np.repeat(mesh.Lam0[None], nn, axis=0)
    for step in range(1, load_steps + 1):
        lam = step / load_steps

        def correction(x, R, lam=lam):
            fint, st = _internal(mesh, x, R)
            Tmat = np.einsum("nji,nj->ni", R, lam * Ttot)
            r = fint.copy()
            r[:, :3] -= lam * Ftot
            r[:, 3:] -= Tmat
            return band.solve(band.factor(mesh.elements.tangent_from(st), -skew(Tmat)), -r.ravel()).reshape(nn, 6)

        x, R, converged = newton(x, R, correction, mesh.length, tol, max_iterations)
        if not converged:
            raise RuntimeError(f"reference: static Newton did not converge at load factor {lam:.3g}")
    return StaticResult(r=x, R=R @ mesh.Lam0.T)
