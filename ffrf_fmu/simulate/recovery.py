"""Result recovery of a solid (docs/solids.md, "Result recovery"): the modal coordinates of a run and
its deformed mesh for ParaView.

A standalone run of the scene, stepped here one step at a time, records every `every` steps the CM
frame (x0, R0) of the superelement and its elastic coordinates q_bar = [q_B; eta] (eq. 89, from the
port frames: BodySystem.elastic_coordinates). The FE displacement field in the CM frame is u = Y q_bar
(eq. 76, SolidReduction.Y), so a node at X (reference, model axes) is at
    x = x0 + R0 (X - x_cm + u).
Written: modal.csv (t, q_B of every frame, eta) and, with the mesh's cells, one VTK file (.vtu,
meshio) per recorded step with point data `displacement` (x - X, world axes) and a ParaView collection
(.pvd) that orders them in time.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True, eq=False)
class Recovery:
    """Recorded states of one run: times (k,), CM frames x0 (k, 3), R0 (k, 3, 3), q_bar (k, n), and the
    port frames xN (k, n_f, 3), RN (k, n_f, 3, 3) of the run (what the ports output)."""

    t: np.ndarray
    x0: np.ndarray
    R0: np.ndarray
    q: np.ndarray
    xN: np.ndarray
    RN: np.ndarray


def run_recorded(model, scene_name=None, every: int = 10, backend: str = "numpy"):
    """(Recovery, SolidReduction, BodyData) of the scene's standalone run of a solid body, states every
    `every` steps (and the first)."""
    from ..reduction import reduce_scene_body
    from .loop import build_system, whole_steps

    scene = model.scene(scene_name)
    if model.body.solid is None:
        from ..checked_toml import ModelError

        raise ModelError(f"{model.path}: result recovery writes solid meshes; body {model.body.name!r} is a beam")
    reduced = reduce_scene_body(model.body, scene)
    data, (red,) = reduced.data, reduced.reductions
    n_steps, h = whole_steps(scene.duration, scene.step)
    system, inputs = build_system(data, scene, origin=model.body.origin, backend=backend)
    rows = []

    def keep():
        rows.append((system.t, system.x0[0].copy(), system.R0[0].copy(), system.elastic_coordinates()[0].copy(),
                     system.xN.copy(), system.RN.copy()))

    keep()
    for k in range(1, n_steps + 1):
        system.step(h, inputs)
        if k % every == 0 or k == n_steps:
            keep()
    return Recovery(*(np.array(c) for c in zip(*rows))), red, data


def deformed_positions(red, x0, R0, q) -> np.ndarray:
    """Node positions (n, 3), world axes, of the reduced solid at one state (module doc)."""
    u = red.fe.translations(red.Y @ q[:, None])[:, :, 0]
    return x0 + (red.fe.coords - red.data.x_cm + u) @ R0.T


def write_modal_csv(rec: Recovery, red, path) -> None:
    names = [f"{f.name}.q_B[{i + 1}]" for f in red.frames for i in range(6)]
    names += [f"eta[{j + 1}]" for j in range(rec.q.shape[1] - len(names))]
    np.savetxt(path, np.column_stack([rec.t, rec.q]), delimiter=",", header=",".join(["t"] + names), comments="")


def write_vtk(rec: Recovery, red, out_dir, name: str = "body") -> Path:
    """One .vtu per recorded state and a .pvd collection; returns the .pvd path. Needs the mesh's cells
    (a mesh file, a generated mesh, an Abaqus deck or the Ansys element table)."""
    import meshio

    if not red.fe.cells:
        raise ValueError(f"{red.fe.source}: no cells to write (give the Ansys element table: export.elements)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    X = red.fe.coords
    entries = []
    n_pts = max(int(c.max()) for _, c in red.fe.cells) + 1  # cells use the leading FE nodes (corners first)
    for i, (t, x0, R0, q) in enumerate(zip(rec.t, rec.x0, rec.R0, rec.q)):  # noqa: B007
        x = deformed_positions(red, x0, R0, q)
        f = out / f"{name}_{i:05d}.vtu"
        meshio.write(f, meshio.Mesh(x[:n_pts], [(ct, c) for ct, c in red.fe.cells],
                                    point_data={"displacement": (x - X)[:n_pts]}))
        entries.append(f'    <DataSet timestep="{t:.9g}" file="{f.name}"/>')
    pvd = out / f"{name}.pvd"
    pvd.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n'
                   + "\n".join(entries) + "\n  </Collection>\n</VTKFile>\n")
    return pvd
