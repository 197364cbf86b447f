"""[body] kind = "solid": a mesh and material or a partner's export, and ports as frames on node sets
(model.SolidSpec, docs/model-format.md, solids)."""
from __future__ import annotations

from pathlib import Path

from ..checked_toml import Reader, join, positive
from .body import _parse_damping, _port_coupling
from .keys import BODY_KEYS, PORT_KEYS, _NAME
from .schema import Body, PART_CAUSALITIES, Port, SolidFrame, SolidSpec


SOLID_KEYS = {
    "kind": BODY_KEYS["kind"],
    "name": BODY_KEYS["name"],
    "superelements": "1: a solid is one superelement",
    "modes": "an integer >= 0: the free-free modes kept (or cutoff_hz)",
    "cutoff_hz": "a positive frequency [Hz]: keep every free-free mode up to it (or modes)",
    "mesh": "a table [body.mesh] {file | box | cylinder | plate, element, thickness (shells)}",
    "material": "a table [body.material] {E, nu, rho}",
    "export": "a table [body.export] {format, files..., units}",
    "ports": "a table of ports [body.ports.NAME] {select, link, point, translation, rotation, coupling}",
    "damping": BODY_KEYS["damping"],
}
MESH_KEYS = {
    "file": "a mesh file read with meshio (Gmsh .msh, Abaqus .inp, VTK, ...), relative to the model file",
    "box": "a table {size = [lx, ly, lz] m, divisions = [nx, ny, nz], origin = [x, y, z] m}",
    "cylinder": "a table {radius m, length m, radial = cells across a radius, axial = cells along, origin} (along +Z)",
    "plate": "a table {size = [lx, ly] m, divisions = [nx, ny], origin = [x, y, z] m} (shells in the XY plane)",
    "element": "one of hex8, hex20, hex27, tet4, tet10 (hex8 and tet4 lock in bending: docs/solids.md) or the "
               "shell mitc4 (docs/shells.md)",
    "thickness": "a positive shell thickness [m], or {cell_data = NAME}: the mesh file's cell data field of the "
                 "thickness of each quad [m] (shell elements only)",
}
SOLID_ELEMENTS = ("hex8", "hex20", "hex27", "tet4", "tet10")
SHELL_ELEMENTS = ("mitc4",)
MATERIAL_KEYS = {"E": "a positive Young's modulus [Pa]", "nu": "a Poisson's ratio in [0, 0.5)",
                 "rho": "a positive density [kg/m^3]"}
EXPORT_KEYS = {
    "format": "'abaqus' (*MATRIX OUTPUT .mtx + .inp), 'ansys' (Matrix Market + dof mapping + node table) or "
              "'calculix' (a CalculiX/Abaqus deck assembled by ccx: solid/calculix_engine.py) or 'nastran' (a "
              "Nastran bulk data deck read with pyNastran: solid/nastran_body.py)",
    "deck": "the Nastran bulk data deck (.bdf, .dat; its INCLUDEs beside it)",
    "inp": "the Abaqus or CalculiX input deck (.inp): nodes and node sets",
    "stiffness": "the exported stiffness matrix file",
    "mass": "the exported mass matrix file",
    "mapping": "the Ansys dof mapping vector file (Matrix Market)",
    "nodes": "the Ansys node table (number, X, Y, Z)",
    "elements": "the Ansys element table (optional: cells for VTK output)",
    "units": "a text stating the units assumed (the files do not say)",
}
EXPORT_FILES = {"abaqus": ("inp", "stiffness", "mass"), "ansys": ("stiffness", "mass", "mapping", "nodes"),
                "calculix": ("inp",), "nastran": ("deck",)}
SOLID_PORT_KEYS = {
    "select": "a node selection table: {set = NAME} | {plane = {point, normal, tol}} | {cylinder = {point, axis, "
              "radius, tol}} | {box = {min, max}} | {near = {point | set, radius}}",
    "link": "'rigid' (RBE2: the set moves rigidly with the frame) or 'averaging' (RBE3: the frame follows the set's "
            "mean motion) (default 'rigid')",
    "point": "3 numbers [m]: the frame origin (default: the centroid of the selected nodes)",
    "translation": PORT_KEYS["translation"],
    "rotation": PORT_KEYS["rotation"],
    "coupling": PORT_KEYS["coupling"],
}



def _frozen(v):
    """TOML values as hashable tuples (tables as sorted pairs)."""
    if isinstance(v, dict):
        return tuple(sorted((k, _frozen(x)) for k, x in v.items()))
    if isinstance(v, list):
        return tuple(_frozen(x) for x in v)
    return v


def _parse_solid(r: Reader, t: dict, default_name: str, file: str) -> Body:
    """[body] kind = "solid": a mesh + material or an export, ports as frames on node sets (SolidSpec)."""
    import json

    b = "body"
    r.table(t, b, SOLID_KEYS, required=("ports",))
    name = r.string(t, b, "name", SOLID_KEYS["name"], default_name)
    if not _NAME.match(name):
        r.expected(join(b, "name"), SOLID_KEYS["name"], name)
    n_se = r.integer(t, b, "superelements", SOLID_KEYS["superelements"], 1, low=1)
    if n_se != 1:
        r.fail(join(b, "superelements"), f"a solid is one superelement (its frames are its boundary), got {n_se}; "
               "split a solid into parts as separate bodies")
    modes = r.integer(t, b, "modes", SOLID_KEYS["modes"], 0, low=0)
    cutoff = r.real(t, b, "cutoff_hz", SOLID_KEYS["cutoff_hz"], None, ok=positive) if "cutoff_hz" in t else None
    if ("modes" in t) == (cutoff is not None):
        r.fail(b, "expected one of modes = N or cutoff_hz = F (which free-free modes to keep)")
    base = Path(file).parent
    if ("mesh" in t) == ("export" in t):
        r.fail(b, "expected exactly one of [body.mesh] (with [body.material]) or [body.export]")
    files, generated, element, material, units, thickness = [], (), "", None, "", None
    if "mesh" in t:
        mp = join(b, "mesh")
        mt = r.table(t["mesh"], mp, MESH_KEYS, required=("element",))
        element = r.string(mt, mp, "element", MESH_KEYS["element"], choices=SOLID_ELEMENTS + SHELL_ELEMENTS)
        shell = element in SHELL_ELEMENTS
        given = [k for k in ("file", "box", "cylinder", "plate") if k in mt]
        if len(given) != 1:
            r.fail(mp, f"expected exactly one of file, box, cylinder, plate, got {given or 'none'}")
        if shell != ("thickness" in mt):
            r.fail(mp, f"a shell mesh (element {SHELL_ELEMENTS}) needs thickness = T [m], a solid one has none"
                   + (f" (element {element!r})" if not shell else ""))
        if shell and given[0] in ("box", "cylinder"):
            r.fail(join(mp, given[0]), f"element {element!r} is a shell: generate a plate, or give a file of quads")
        if not shell and given[0] == "plate":
            r.fail(join(mp, "plate"), f"a plate is meshed with shells (element one of {SHELL_ELEMENTS}), not {element!r}")
        thickness = None
        if shell and isinstance(mt["thickness"], dict):
            tt = r.table(mt["thickness"], join(mp, "thickness"), {"cell_data": "the name of a cell data field"},
                         required=("cell_data",))
            if "file" not in mt:
                r.fail(join(mp, "thickness"), "a thickness from cell data needs a mesh file")
            thickness = r.string(tt, join(mp, "thickness"), "cell_data", "the name of a cell data field")
        elif shell:
            thickness = r.real(mt, mp, "thickness", MESH_KEYS["thickness"], ok=positive)
        if "file" in mt:
            f = base / r.string(mt, mp, "file", MESH_KEYS["file"])
            if not f.is_file():
                r.fail(join(mp, "file"), f"no such file: {f}")
            files.append(("mesh", str(f)))
        else:
            kind = given[0]
            gp = join(mp, kind)
            if kind == "box":
                gt = r.table(mt[kind], gp, {"size": "3 positive lengths [m]", "divisions": "3 integers >= 1",
                                             "origin": "3 numbers [m] (default [0, 0, 0])"}, required=("size", "divisions"))
                size = r.vec3(gt, gp, "size", "3 positive lengths [m]")
                div = gt["divisions"]
                if min(size) <= 0:
                    r.expected(join(gp, "size"), "3 positive lengths [m]", list(size))
                if not (isinstance(div, list) and len(div) == 3 and all(isinstance(x, int) and x >= 1 for x in div)):
                    r.expected(join(gp, "divisions"), "3 integers >= 1", div)
                params = {"size": size, "divisions": tuple(div), "origin": r.vec3(gt, gp, "origin", "3 numbers [m]",
                                                                                  (0.0, 0.0, 0.0))}
            elif kind == "plate":
                gt = r.table(mt[kind], gp, {"size": "2 positive lengths [m]", "divisions": "2 integers >= 1",
                                             "origin": "3 numbers [m] (default [0, 0, 0])"}, required=("size", "divisions"))
                size, div = gt["size"], gt["divisions"]
                if not (isinstance(size, list) and len(size) == 2 and all(isinstance(x, (int, float))
                                                                          and not isinstance(x, bool) and x > 0 for x in size)):
                    r.expected(join(gp, "size"), "2 positive lengths [m]", size)
                if not (isinstance(div, list) and len(div) == 2 and all(isinstance(x, int) and x >= 1 for x in div)):
                    r.expected(join(gp, "divisions"), "2 integers >= 1", div)
                params = {"size": tuple(float(x) for x in size), "divisions": tuple(div),
                          "origin": r.vec3(gt, gp, "origin", "3 numbers [m]", (0.0, 0.0, 0.0))}
            else:
                gt = r.table(mt[kind], gp, {"radius": "a positive radius [m]", "length": "a positive length [m]",
                                             "radial": "an integer >= 1", "axial": "an integer >= 1",
                                             "origin": "3 numbers [m] (default [0, 0, 0])"},
                             required=("radius", "length", "radial", "axial"))
                params = {"radius": r.real(gt, gp, "radius", "a positive radius [m]", ok=positive),
                          "length": r.real(gt, gp, "length", "a positive length [m]", ok=positive),
                          "radial": r.integer(gt, gp, "radial", "an integer >= 1", low=1),
                          "axial": r.integer(gt, gp, "axial", "an integer >= 1", low=1),
                          "origin": r.vec3(gt, gp, "origin", "3 numbers [m]", (0.0, 0.0, 0.0))}
            generated = (kind, _frozen(params))
        if "material" not in t:
            r.fail(b, "a mesh needs a table [body.material] {E, nu, rho}")
        mp = join(b, "material")
        mat = r.table(t["material"], mp, MATERIAL_KEYS, required=("E", "nu", "rho"))
        material = (r.real(mat, mp, "E", MATERIAL_KEYS["E"], ok=positive),
                    r.real(mat, mp, "nu", MATERIAL_KEYS["nu"], ok=lambda x: 0.0 <= x < 0.5),
                    r.real(mat, mp, "rho", MATERIAL_KEYS["rho"], ok=positive))
        source = "mesh"
    else:
        ep = join(b, "export")
        et = r.table(t["export"], ep, EXPORT_KEYS, required=("format", "units"))
        source = r.string(et, ep, "format", EXPORT_KEYS["format"], choices=tuple(EXPORT_FILES))
        units = r.string(et, ep, "units", EXPORT_KEYS["units"])
        for role in EXPORT_FILES[source] + (("elements",) if source == "ansys" and "elements" in et else ()):
            if role not in et:
                r.fail(ep, f"expected {role} = FILE ({EXPORT_KEYS[role]}) for format {source!r}")
            f = base / r.string(et, ep, role, EXPORT_KEYS[role])
            if not f.is_file():
                r.fail(join(ep, role), f"no such file: {f}")
            files.append((role, str(f)))
        extra = sorted(set(et) - set(EXPORT_FILES[source]) - {"format", "units", "elements"})
        if extra:
            r.fail(join(ep, extra[0]), f"not a file of format {source!r} (expects {', '.join(EXPORT_FILES[source])})")
    ports, frames = [], []
    pt = r.table(t["ports"], "body.ports", None)
    for i, (pname, p) in enumerate(pt.items()):
        pp = join("body.ports", pname)
        if not _NAME.match(pname):
            r.fail(pp, "expected a port name of letters, digits and _ (it prefixes FMU variable names)")
        r.table(p, pp, SOLID_PORT_KEYS, required=("select",))
        sel = r.table(p["select"], join(pp, "select"), {k: SOLID_PORT_KEYS["select"] for k in
                                                        ("set", "plane", "cylinder", "box", "near")})
        if len(sel) != 1:
            r.fail(join(pp, "select"), f"expected exactly one selection kind, got {sorted(sel) or 'none'}")
        link = r.string(p, pp, "link", SOLID_PORT_KEYS["link"], "rigid", ("rigid", "averaging"))
        point = r.vec3(p, pp, "point", SOLID_PORT_KEYS["point"], None) if "point" in p else None
        tr = r.string(p, pp, "translation", PORT_KEYS["translation"], "force", PART_CAUSALITIES)
        rot = r.string(p, pp, "rotation", PORT_KEYS["rotation"], "force", PART_CAUSALITIES)
        ports.append(Port(pname, i, tr, rot, _port_coupling(r, p, pp, tr, rot)))
        frames.append(SolidFrame(pname, json.dumps(sel, sort_keys=True), link, point))
    if len(ports) < 2:
        r.fail("body.ports", f"a solid needs at least 2 ports (interface frames), got {len(ports)}")
    spec = SolidSpec(source, tuple(files), generated, element, material, cutoff, tuple(frames), units, thickness)
    from ..solid.source import solid_size  # the body's size: messages and scales of the tools that need one

    try:
        length = solid_size(spec)
    except (OSError, ValueError) as e:
        r.fail(b, f"cannot read the solid's nodes: {e}")
    return Body(name=name, length=length, origin=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), section=None,
                superelements=1, elements_per_superelement=0, modes=modes, ports=tuple(ports), source=file,
                solid=spec, damping=_parse_damping(r, t))
