"""The FE model a solid's SolidSpec names (a generated or read mesh assembled with scikit-fem, or a
partner's export) and its size: what model.py needs while it reads a model file, below the reduction
(reduction.reduce_solid_body) so that reading a model never imports it."""
from __future__ import annotations

import functools

import numpy as np

from . import SolidFE


def _generated_mesh(spec):
    from .mesh import box_points, cylinder_points

    kind, params = spec.generated
    p = dict(params)
    if kind == "box":
        return box_points(p["size"], p["divisions"], p["origin"])
    return cylinder_points(p["radius"], p["length"], p["radial"], p["axial"], p["origin"])


def _shell_fe(spec, files, material) -> SolidFE:
    """A shell mesh (a generated plate, or the quads of a mesh file) assembled with MITC4 (shell.py) as a
    6-dof SolidFE (shell_body.py)."""
    from .shell import ShellFE, assemble_shells, plate_mesh
    from .shell_batch import assemble_mitc4
    from .shell_body import shell_body

    thickness = spec.thickness
    if "mesh" in files:
        from .mesh import read_mesh

        mesh, sets = read_mesh(files["mesh"])
        blocks = [k for k, c in enumerate(mesh.cells) if c.type == "quad"]
        blocks3 = [k for k, c in enumerate(mesh.cells) if c.type == "triangle"]
        other = sorted({c.type for c in mesh.cells} - {"quad", "triangle", "line", "vertex"})
        if other or not (blocks or blocks3):
            raise ValueError(f"{files['mesh']}: element {spec.element} needs quad or triangle cells, the mesh has "
                             f"{other or 'neither'}")
        nodes, source = np.asarray(mesh.points, dtype=float), files["mesh"]
        cells = lambda ks, k: np.concatenate([mesh.cells[j].data for j in ks]) if ks else np.zeros((0, k), int)  # noqa: E731
        quads, trias = cells(blocks, 4), cells(blocks3, 3)
        if isinstance(thickness, str):
            if thickness not in mesh.cell_data:
                raise ValueError(f"{source}: no cell data {thickness!r} for the thickness (cell data: "
                                 f"{sorted(mesh.cell_data) or 'none'})")
            thickness = np.concatenate([np.asarray(mesh.cell_data[thickness][k], dtype=float).ravel()
                                        for k in blocks + blocks3])  # quads, then triangles (ShellFE's order)
            bad = np.flatnonzero(~(np.isfinite(thickness) & (thickness > 0)))
            if bad.size:
                kind, i = ("quad", bad[0]) if bad[0] < len(quads) else ("triangle", bad[0] - len(quads))
                raise ValueError(f"{source}: cell data {spec.thickness!r}: {kind} {int(i)} has thickness "
                                 f"{thickness[bad[0]]:g} (expected > 0 [m])")
        if nodes.shape[1] == 2:
            nodes = np.column_stack([nodes, np.zeros(len(nodes))])
    else:
        p = dict(spec.generated[1])
        nodes, quads = plate_mesh(*p["size"], *p["divisions"])
        nodes = nodes + np.asarray(p["origin"], dtype=float)
        sets, source, trias = {}, "generated plate", np.zeros((0, 3), dtype=int)
    shell = assemble_mitc4(nodes, quads, np.broadcast_to(thickness, (len(quads) + len(trias),))[: len(quads)], material)
    if len(trias):  # DKT triangles (shell_tri.py), element by element, added to the quads' blocks
        tt = np.broadcast_to(thickness, (len(quads) + len(trias),))[len(quads):]
        tri = assemble_shells(nodes, np.zeros((0, 4), dtype=int), tt, material, trias=trias)
        shell = ShellFE(shell.coords, shell.quads, np.concatenate([shell.thickness, tri.thickness]), material,
                        shell.K + tri.K, shell.M + tri.M, trias=tri.trias)
    t = np.asarray(thickness, dtype=float)
    what = f"t = {float(t):g} m" if t.ndim == 0 else f"t = {t.min():g} .. {t.max():g} m from {spec.thickness!r}"
    return shell_body(shell, sets, f"{source} ({spec.element}, {what})")


@functools.lru_cache(maxsize=8)
def solid_fe(spec) -> SolidFE:
    """The FE model of a SolidSpec (cached: info, advise and the reduction ask for it several times)."""
    files = dict(spec.files)
    if spec.source == "nastran":
        from .nastran_body import nastran_body

        return nastran_body(files["deck"])
    if spec.source == "calculix":
        from .calculix_engine import run_ccx

        return run_ccx(files["inp"])
    if spec.source == "abaqus":
        from .exports import read_abaqus

        return read_abaqus(files["inp"], files["stiffness"], files["mass"])
    if spec.source == "ansys":
        from .exports import read_ansys

        return read_ansys(files["stiffness"], files["mass"], files["mapping"], files["nodes"], files.get("elements"))
    from .mesh import Material, assemble, read_mesh

    if spec.thickness is not None:
        return _shell_fe(spec, files, Material(*spec.material))
    if "mesh" in files:
        mesh, sets = read_mesh(files["mesh"])
        source = files["mesh"]
    else:
        mesh, sets, source = _generated_mesh(spec), {}, f"generated {spec.generated[0]}"
    return assemble(mesh, Material(*spec.material), spec.element, sets, f"{source} ({spec.element})")


def solid_size(spec) -> float:
    """The diagonal of the bounding box of the solid's nodes [m] (the body's length scale)."""
    if spec.generated:
        p = dict(spec.generated[1])
        if spec.generated[0] in ("box", "plate"):
            return float(np.linalg.norm(p["size"]))
        return float(np.hypot(2 * p["radius"], p["length"]))
    X = solid_fe(spec).coords
    return float(np.linalg.norm(X.max(0) - X.min(0)))
