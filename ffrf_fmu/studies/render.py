"""A recovered solid's deformed shape as a picture (PNG): the surface of its mesh drawn with
matplotlib's 3D polygon collection, the elastic deformation scaled and the scale stated.

What is drawn: the body in its floating (CM) frame, model axes, at one recorded state of
`simulate.recovery.run_recorded`: node X + s u, u = Y q_bar the elastic displacement (eq. 76), s the
scale factor (default: the largest |u| drawn as 5 % of the body's largest extent); the faces coloured
by |u| (unscaled, mm). The rigid motion is left out, so the picture shows the deformation only.

Surface: shell quads and triangles are drawn as they are; of volume cells (tetrahedra, hexahedra,
wedges; linear or quadratic, by their corner nodes) the faces that belong to one cell only.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

# corner faces of the volume cells (meshio's node order), outward or not: drawn, not integrated
VOLUME_FACES = {
    "tetra": ((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)),
    "hexahedron": ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)),
    "wedge": ((0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)),
}
SURFACE_CORNERS = {"triangle": 3, "triangle6": 3, "quad": 4, "quad8": 4, "quad9": 4}
SHARE_OF_EXTENT = 0.05


def _base(cell_type: str) -> str:
    for b in ("tetra", "hexahedron", "wedge"):
        if cell_type.startswith(b):
            return b
    return cell_type


def surface_faces(cells) -> list[np.ndarray]:
    """Faces (node index arrays) of the mesh's surface: shell cells, and the volume cells' faces that
    no other cell shares. Raises ValueError naming an unknown cell type."""
    faces: list[np.ndarray] = []
    seen: dict[tuple, np.ndarray] = {}
    count: dict[tuple, int] = {}
    for ct, conn in cells:
        conn = np.asarray(conn, int)
        if ct in SURFACE_CORNERS:
            faces.extend(conn[:, :SURFACE_CORNERS[ct]])
            continue
        base = _base(ct)
        if base not in VOLUME_FACES:
            raise ValueError(f"render: cell type {ct!r} has no known faces (known: "
                             f"{sorted(SURFACE_CORNERS) + sorted(VOLUME_FACES)} and their quadratic kinds)")
        for f in VOLUME_FACES[base]:
            for row in conn[:, list(f)]:
                key = tuple(sorted(row))
                count[key] = count.get(key, 0) + 1
                seen[key] = row
    faces.extend(seen[k] for k, n in count.items() if n == 1)
    return faces


@dataclass(frozen=True)
class Picture:
    """What a render drew: the file, the time of the state, the scale s and the largest |u| [m]."""

    path: Path
    t: float
    scale: float
    u_max: float


def elastic_displacements(red, q) -> np.ndarray:
    """u = Y q_bar at the FE nodes (n, 3), the body's CM frame (eq. 76)."""
    return red.fe.translations(red.Y @ np.asarray(q)[:, None])[:, :, 0]


def render_state(red, q, path, t: float = 0.0, scale: float | None = None, title: str = "",
                 view: tuple[float, float] = (25.0, -60.0)) -> Picture:
    """Draw the surface at elastic coordinates q (module doc) into the PNG `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if not red.fe.cells:
        raise ValueError(f"{red.fe.source}: no cells to draw (the mesh's elements are needed)")
    X = red.fe.coords
    u = elastic_displacements(red, q)
    mag = np.linalg.norm(u, axis=1)
    u_max = float(mag.max())
    extent = float(np.max(X.max(0) - X.min(0)))
    s = float(scale) if scale is not None else (SHARE_OF_EXTENT * extent / u_max if u_max > 0 else 1.0)
    x = X + s * u
    faces = surface_faces(red.fe.cells)
    polys = [x[f] for f in faces]
    colour = np.array([mag[f].mean() for f in faces]) * 1e3
    fig = plt.figure(figsize=(8, 6))
    ax = fig.add_subplot(projection="3d")
    pc = Poly3DCollection(polys, cmap="viridis", edgecolor=(0, 0, 0, 0.15), linewidth=0.2)
    pc.set_array(colour)
    ax.add_collection3d(pc)
    lo, hi = x.min(0), x.max(0)
    ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * extent))
    ax.view_init(*view)
    from matplotlib.ticker import MaxNLocator

    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(3))
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x [m]"), ax.set_ylabel("y [m]"), ax.set_zlabel("z [m]")
    fig.colorbar(pc, ax=ax, shrink=0.6, label="|u| [mm] (unscaled)")
    ax.set_title((title + "\n" if title else "") + f"t = {t:.4g} s, deformation x {s:.4g} (max |u| = {u_max * 1e3:.3g} mm), "
                 "floating frame", fontsize=9)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return Picture(path, float(t), s, u_max)


def pick_state(rec, red, at: float | None) -> int:
    """Index of the recorded state nearest to time `at`, or (None) of the largest elastic |u|."""
    if at is not None:
        return int(np.argmin(np.abs(np.asarray(rec.t) - at)))
    return int(np.argmax([np.abs(elastic_displacements(red, q)).max() for q in rec.q]))
