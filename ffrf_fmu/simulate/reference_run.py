"""The scene on the full-order geometrically exact beam (ffrf_fmu/reference) as a SimulationResult,
with the same port columns and metrics as a standalone run."""
from __future__ import annotations

import numpy as np

from ..model import Model, Scene, scene_body
from ..runtime.outputs import OUTPUT_FIELDS, port_variables
from .quantities import energy_balance, metrics
from .results import FREE_BODY_FIELDS, SimulationResult, free_body_columns


def run_reference(model: Model, scene: Scene, n_elements: int | None = None, step: float | None = None) -> SimulationResult:
    """The scene on the full-order geometrically exact beam (ffrf_fmu/reference), as a SimulationResult
    with the same port columns and metrics. Default mesh: the FE mesh the superelements are reduced
    from (superelements x elements per superelement), unreduced."""
    from ..reference import simulate_reference
    from ..runtime.data import BodyData, PortData

    body = scene_body(model.body, scene)
    if body.solid is not None:
        from ..checked_toml import ModelError

        raise ModelError(f"{model.path}: the full-order reference is the geometrically exact beam; a solid has none "
                         "(docs/solids.md: its quality report compares the reduction with the full FE model)")
    if body.damping is not None and body.damping.kind != "none":
        from ..checked_toml import ModelError

        raise ModelError(f"{model.path}: body.damping: the full-order reference beam has no structural damping, so it "
                         "cannot be the reference of a damped body (compare the undamped body, without [body.damping])")
    n = n_elements or body.superelements * body.elements_per_superelement
    ref = simulate_reference(body, scene, n_elements=n, step=step)
    L, e = body.length, np.asarray(body.direction, float) / np.linalg.norm(body.direction)
    nodes = np.asarray(body.origin, float) + np.outer(np.arange(body.superelements + 1) * L / body.superelements, e)
    ports = tuple(PortData(p.name, p.node, p.translation, p.rotation) for p in body.ports)
    shell = BodyData(name=body.name, superelements=(), node_positions=nodes, ports=ports)
    columns = {}
    for p in ports:
        for fld in OUTPUT_FIELDS:
            arr = ref.ports[p.name][fld].reshape(len(ref.t), -1)
            columns.update(zip(port_variables(p.name, fld), arr.T))
    for k in ("kinetic", "strain", "work_external"):
        columns[f"energy.{k}"] = ref.energy[k]
    columns |= free_body_columns(*(ref.mass[k] for k in FREE_BODY_FIELDS))
    summary = {
        "body": body.name, "scene": scene.name, "solver": "reference", "elements": n,
        "step": (ref.info or {}).get("step", step or scene.step), "completed": bool(ref.t[-1] >= scene.duration - 1e-9),
        "failure": None, "t_end": float(ref.t[-1]), "wall_time_s": ref.wall_time_s, "steps": len(ref.t) - 1,
        "real_time_factor": float(ref.t[-1] / ref.wall_time_s) if ref.wall_time_s > 0 else None,
        "newton_iterations_mean": ref.newton_iterations_mean, "energy_balance_max_rel": energy_balance(columns),
        "energy_error": float((ref.info or {}).get("energy_error", np.nan)),
    }
    result = SimulationResult(ref.t, columns, summary, shell)
    summary["metrics"] = metrics(result, scene)
    return result
