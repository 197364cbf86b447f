"""A shell model (solid/shell.py) as the reduction's input: a SolidFE on 6 dofs per node whose mass is
split into the node-block mass of the mid-surface and the mass points of the fibres' rotary inertia
(solid/__init__.py; docs/equations.md, "Invariants of a body with rotational dofs").

A material point at height z on the fibre of a mid-surface point moves by u = u_0 + z theta x n
(n the element normal, theta the node rotations interpolated like u_0: the shell's kinematics). Its
tensor kernel over the element is
    T_ab = int rho t N^T N e_a e_b^T  +  int rho (t^3 / 12) (N (-n~))_a^T (N (-n~))_b
(the cross terms vanish: int z = 0 over the thickness), the first on the translations (M_s, node
block), the second on the rotations. The second is integrated by the element's mass quadrature
(shell.py: 2 x 2 Gauss, exact for N_i N_j on a parallelogram) and through the thickness by the
two Gauss points z = +-t / (2 sqrt 3), which carry equal and opposite fields; the kernels being
quadratic in the field, one point at z = t / sqrt(12) with both weights stands for them:
    w_p = rho t det J_g,   N_p = (t / sqrt 12) N(xi_g) (-n~)   on the element's node rotations.
Summed with M_s this is the shell's consistent mass (rho t^3/12 N^T N on the two fibre rotations, none
on the drilling rotation, as T^T diag(1, 1, 0) T = I - n n^T): six_dof_fe checks that it adds up.
"""
from __future__ import annotations

import numpy as np

from . import MassPoints, SolidFE, six_dof_fe
from .shell import ShellFE
from .shell_batch import fibre_mass


def shell_body(shell: ShellFE, node_sets=None, source: str = "") -> SolidFE:
    """The SolidFE (6 dofs per node, node-block mass and fibre mass points: module doc) of a shell model;
    the points are built for all elements at once (shell_batch.fibre_mass)."""
    if len(shell.quads9):
        raise ValueError(f"a shell body is of MITC4 quads and DKT triangles so far; this mesh has {len(shell.quads9)} "
                         "9-node quads (their fibre mass points are not built yet)")
    Ms, Np, w = fibre_mass(shell)
    cells = tuple((kind, np.asarray(c, dtype=int)) for kind, c in (("quad", shell.quads), ("triangle", shell.trias))
                  if len(c))
    return six_dof_fe(shell.coords, shell.K, shell.M, Ms, MassPoints(Np, w), node_sets,
                      source or f"{len(shell.quads)} MITC4 quads, {len(shell.trias)} DKT triangles", cells)
