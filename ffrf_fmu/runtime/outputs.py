"""What a body reports, named once: the fields of a port (shape, unit, meaning), the FMU's names of
their components, the output fields and energies of a time-series row, and eq. (92), the tip seen
from the hub. Below both the standalone run (ffrf_fmu/simulate) and the FMU (ffrf_fmu/fmu): each
reads its names and row layout from here.

Index conventions: `P.r[i]` i = 1..3, `P.R[i,j]` = component i (world axis) of nodal axis j, both
1-based; R row-major in a row. Runtime module: no import from the rest of ffrf_fmu (it ships inside
FMUs).
"""
from __future__ import annotations

import numpy as np

# (shape, unit, meaning) of the eight fields of a port
FIELDS = {
    "r": ((3,), "m", "position of the nodal frame origin, world axes"),
    "R": ((3, 3), None, "rotation matrix of the nodal frame: R[i,j] = world component i of nodal axis j"),
    "v": ((3,), "m/s", "velocity of the node, world axes"),
    "w": ((3,), "rad/s", "angular velocity of the nodal frame, world axes"),
    "f": ((3,), "N", "force the environment applies ON the body at the node, world axes"),
    "t": ((3,), "N.m", "moment the environment applies ON the body at the node, world axes"),
    "a": ((3,), "m/s2", "acceleration of the node, world axes"),
    "dw": ((3,), "rad/s2", "angular acceleration of the nodal frame, world axes"),
}

# The fields of every port, in this order: a time-series row's columns, 3 or 9 each (R row-major:
# BodySystem.port_array's columns, advance.c ffrf_record's (FFRF_OUTPUT_WIDTH), the FMUs' output maps) and
# the FMUs' value references (fmu/variables.py). a, dw: the true accelerations of the port's node at the
# end of the step (runtime/accelerations.py)
OUTPUT_FIELDS = tuple(FIELDS)
OUTPUT_WIDTH = sum(int(np.prod(FIELDS[f][0])) for f in OUTPUT_FIELDS)  # 30 columns per port


def _field_columns() -> dict[str, slice]:
    cols, start = {}, 0
    for f in OUTPUT_FIELDS:
        width = int(np.prod(FIELDS[f][0]))
        cols[f] = slice(start, start + width)
        start += width
    return cols


FIELD_COLUMNS = _field_columns()  # field -> its columns in a port's OUTPUT_WIDTH part of a row

ENERGIES = {
    "kinetic_rigid": "kinetic energy of the rigid (CM frame) motion of all superelements",
    "kinetic_elastic": "kinetic energy of the elastic velocity field, 1/2 r^T M r",
    "strain": "strain energy of the elastic deformation, 1/2 q^T K q",
    "work_external": "work done on the body by the port loads and gravity since initialization",
}
ENERGY_FIELDS = tuple(ENERGIES)  # a row's energies, in this order (BodySystem.energies' keys)
# an FMU's modal outputs (fmu/variables.py MODAL): every superelement's eta, then their rates, after the probes
MODAL_FIELDS = ("eta", "eta_rate")


def component_name(base: str, index: tuple[int, ...]) -> str:
    """The name of one component: ("tip.R", (0, 1)) -> "tip.R[1,2]" (0-based index, 1-based name)."""
    return f"{base}[{','.join(str(i + 1) for i in index)}]"


def _indices(shape: tuple[int, ...]) -> list[tuple[int, ...]]:
    """Component indices of a (3,) vector or a (3, 3) matrix, row-major."""
    return [(i,) for i in range(3)] if shape == (3,) else [(i, j) for i in range(3) for j in range(3)]


def field_shape(field: str) -> tuple[int, ...]:
    """(3,) or (3, 3) of a port field, also of the node frame fields "node.r", "node.R" of a compliant part."""
    return FIELDS[field.rpartition(".")[2]][0]


def port_variable(port: str, field: str, index: tuple[int, ...]) -> str:
    """FMU variable name of one component of a port field: ("hub", "R", (0, 1)) -> "hub.R[1,2]"."""
    return component_name(f"{port}.{field}", index)


def port_variables(port: str, field: str) -> list[str]:
    """Every component name of a port field in value-reference order (R row-major: R[1,1], R[1,2], ...).
    `port` may carry an instance prefix ("A.hub"): the master's connections name variables so."""
    return [component_name(f"{port}.{field}", idx) for idx in _indices(field_shape(field))]


def parse_port_variable(name: str) -> tuple[str, str, tuple[int, ...]]:
    """Inverse of `port_variable`: "tip.R[1,2]" -> ("tip", "R", (0, 1)), "hub.node.w[3]" ->
    ("hub", "node.w", (2,)). ValueError for a name that is not a port field component."""
    port, dot, rest = name.partition(".")
    base, bracket, idx = rest.partition("[")
    try:
        index = tuple(int(i) - 1 for i in idx[:-1].split(","))
        ok = dot and bracket and idx.endswith("]") and index and len(index) == len(field_shape(base))
    except (KeyError, ValueError):
        ok = False
    if not ok or not all(0 <= i < 3 for i in index):
        raise ValueError(f"{name!r} is not a port variable name (PORT.FIELD[i] or PORT.R[i,j], 1-based)")
    return port, base, index


def row_columns(ports) -> list[str]:
    """The names of a time-series row's columns (BodySystem.output_row): every port's OUTPUT_FIELDS
    components in ports order, the energies in ENERGY_FIELDS order, the Newton iterations of the step.
    `ports`: port names in the body's order."""
    names = [n for p in ports for fld in OUTPUT_FIELDS for n in port_variables(p, fld)]
    return names + [f"energy.{k}" for k in ENERGY_FIELDS] + ["solver.newton_iterations"]


def output_sources(variables, ports, probes) -> tuple[list[int], list[int]]:
    """(value references, positions) of every output: where each output's value is in [the body's output row
    (runtime/outputs.py: every port's OUTPUT_FIELDS, the energies, the iterations last), the probes (3 each, in
    `probes` order), the modal coordinates eta, their rates (superelement by superelement)]. The one map of both
    FMUs: fmu/native/resource.py writes it into body.bin for model.c, the pythonfmu slave (fmu/signals.py) gathers by it.
    variables: fmu/variables.py Variable rows (name, causality, kind, port, field); ports: with .name."""
    index: dict[tuple[str, str], list[int]] = {}
    for i, v in enumerate(variables):
        index.setdefault((v.port, v.field) if v.port else (v.kind, v.field), []).append(i)
    dst: list[int] = []
    src: list[int] = []
    for j, p in enumerate(ports):
        for field, columns in FIELD_COLUMNS.items():
            ix = index[(p.name, field)]
            cols = list(range(j * OUTPUT_WIDTH + columns.start, j * OUTPUT_WIDTH + columns.stop))
            if variables[ix[0]].causality == "output":
                dst += ix
                src += cols
            node = index.get((p.name, "node." + field))  # the body's own node frame at a compliant part
            if node is not None:
                dst += node
                src += cols
    size = OUTPUT_WIDTH * len(ports) + len(ENERGY_FIELDS) + 1  # the row's length, iterations last
    for i, k in enumerate(ENERGY_FIELDS):
        if ("energy", k) in index:
            dst += index[("energy", k)]
            src.append(OUTPUT_WIDTH * len(ports) + i)
    dst += index[("solver", "newton_iterations")]
    src.append(size - 1)
    for i, name in enumerate(probes):
        dst += index[("probe", name)]
        src += [size + 3 * i + k for k in range(3)]
    base = size + 3 * len(probes)
    for k, field in enumerate(MODAL_FIELDS):
        ix = index.get(("modal", field), [])
        dst += ix
        src += [base + k * len(ix) + i for i in range(len(ix))]
    return dst, src


def tip_from_hub(R_hub: np.ndarray, x_hub: np.ndarray, x_tip: np.ndarray, X_tip: np.ndarray) -> np.ndarray:
    """Eq. (92): the elastic displacement of the tip seen from the hub, d = R_hub^T (x_tip - x_hub) - X_tip,
    X_tip the tip seen from the hub at rest. One instant ((3, 3), (3,) ...) or a series ((nt, 3, 3),
    (nt, 3) ...)."""
    R_hub = np.asarray(R_hub, dtype=float)
    gap = np.asarray(x_tip, dtype=float) - np.asarray(x_hub, dtype=float)
    return np.einsum("...ji,...j->...i", R_hub, gap) - np.asarray(X_tip, dtype=float)
