"""The co-simulation map's runs as tasks (task.py runner "cosim"): the run settings as the task's
option, the scheme labels, and the function a worker calls. Apart from cosim.py (the map), which
builds the tasks through the sweep layer: a worker imports this module and what it needs only."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import tempfile
from pathlib import Path
from typing import Sequence

from . import compliant_b5, monolithic
from .benchmarks import CoupledBeam
from .case import COSIM_SCHEMES, RUN_SETTINGS, CosimCase, CosimRun, CosimSettings

IMPLICIT = ("gauss-seidel implicit", "gauss-seidel", False, "fwd")
#: motor case with the shaft in the beam's compliant hub (compliant_b5.py, docs/cosim.md)
COMPLIANT = ("compliant jacobi", "jacobi", False, "fwd")
#: linearly implicit coupling (master.CoSimulation(interface_jacobian=True), docs/cosim.md)
INTERFACE_JACOBIAN = ("interface-jacobian", "gauss-seidel", False, "fwd")
REFERENCE = "monolithic reference"
SCHEMES = {s[0]: s for s in (*COSIM_SCHEMES, IMPLICIT, COMPLIANT, INTERFACE_JACOBIAN)}


def run_settings(settings: CosimSettings) -> str:
    """The settings that define a run, as the task option `settings` (JSON text)."""
    return json.dumps({k: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v
                       for k, v in ((k, getattr(settings, k)) for k in RUN_SETTINGS)}, sort_keys=True)


_CASES: dict[str, tuple[CosimCase, dict]] = {}  # per worker process: a case's FMUs are built once (`_case`)


def _case(kind: str, model_path, settings: CosimSettings) -> tuple[CosimCase, dict]:
    """The case with its FMUs, built once per process into a temporary directory (and the compliant
    B5's, on its first run): they are a function of the key (model bytes, overrides, run settings),
    and building takes longer than many runs."""
    key = hashlib.sha256(Path(model_path).read_bytes() + json.dumps(
        [kind, list(settings.overrides), run_settings(settings)]).encode()).hexdigest()
    if key not in _CASES:
        fmu_dir = Path(tempfile.mkdtemp(prefix=f"ffrf_cosim_{kind}_"))
        _CASES[key] = (CosimCase(kind, model_path, fmu_dir, settings), {"fmu_dir": fmu_dir})
    return _CASES[key]


def perturbed_run(model_path, settings: CosimSettings, kind: str, H: float, label: str,
                  perturbation: float) -> CosimRun:
    """A map run (not the reference) again in this process with the spin-up time of the hub's Wu-Haug
    profile scaled by 1 + perturbation (motor: the drive's speed reference, `drive.profile.T`; split: the
    hub motion of A), the margin check's re-run (margin.py). The coupled systems start at rest, where a
    relative perturbation of the state is zero: the profile carries it into the state from the first
    step on. The case's FMUs are the unperturbed run's (`_case`): the profile is a start value, or
    (split) computed by the master."""
    case, extra = _case(kind, model_path, settings)
    f = 1.0 + perturbation
    if label == COMPLIANT[0]:
        if "compliant" not in extra:
            extra["compliant"] = compliant_b5.build(model_path, extra["fmu_dir"], settings)
        return compliant_b5.run_master(extra["compliant"], dataclasses.replace(settings, T=settings.T * f), H,
                                       case.duration)
    _, scheme, extrap, order = SCHEMES[label]
    saved = dict(case.start_values), dict(getattr(case, "profile", {}))
    try:
        if kind == "motor":
            case.start_values["drive.profile.T"] = case.start_values["drive.profile.T"] * f
        else:
            case.profile["T"] = case.profile["T"] * f
        return case.run(H, scheme, extrap, order, iterations=settings.implicit_iterations if label == IMPLICIT[0] else 1,
                        interface_jacobian=label == INTERFACE_JACOBIAN[0])
    finally:
        case.start_values = saved[0]
        if kind != "motor":
            case.profile = saved[1]


def run_task(model_path: str, overrides: Sequence[str], opts: dict) -> dict:
    """One run of the map (task runner "cosim"): options case, H, scheme (a SCHEMES label or
    REFERENCE) and settings (run_settings)."""
    raw = json.loads(opts["settings"])
    raw["implicit_tolerance"] = tuple(raw["implicit_tolerance"])
    raw["beam"] = CoupledBeam(**raw["beam"])
    settings = CosimSettings(**raw, overrides=tuple(overrides))
    kind, H, label = opts["case"], float(opts["H"]), opts["scheme"]
    case, extra = _case(kind, model_path, settings)
    if label == REFERENCE:  # one standalone run of the whole system (monolithic.py)
        run = (monolithic.b5_monolithic(model_path, settings, H) if kind == "motor"
               else monolithic.split_monolithic(model_path, settings, H))
    elif label == COMPLIANT[0]:  # the shaft moves into the beam FMU (docs/cosim.md)
        if "compliant" not in extra:
            extra["compliant"] = compliant_b5.build(model_path, extra["fmu_dir"], settings)
        run = compliant_b5.run_master(extra["compliant"], settings, H, case.duration)
    else:
        _, scheme, extrap, order = SCHEMES[label]
        run = case.run(H, scheme, extrap, order, iterations=settings.implicit_iterations if label == IMPLICIT[0] else 1,
                       interface_jacobian=label == INTERFACE_JACOBIAN[0])
    return {**run.as_result(), "length": case.length}
