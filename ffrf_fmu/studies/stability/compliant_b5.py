"""B5 (beam + hub inertia + PI drive) with compliant coupling, run by our master, libcosim and ecos.

The torsional shaft (k = 300 N m/rad, c = 0) moves from the drive FMU into the beam FMU: the beam's
hub rotation is `compliant` (runtime/coupling.py) with rotational stiffness [0, 0, k] in nodal axes
(the shaft, about the spin axis; the other two axes free as in the force-driven B5), its
translation motion-driven (r = v = 0). The drive's own shaft is off (drive.k = 0): it gives its hub
frame and rates (hub_frame.R, w, dw) and takes the moment of the shaft on the hub
(hub_frame.t = -beam.hub.t). Every connection is a plain signal with a gain (no frame arithmetic),
so every engine runs the same discrete map: Jacobi with held inputs (values at t_c), the beam
extrapolating its motion inputs to second order with hub_frame.dw.

Same physical system as the map's B5 (shaft in the drive, docs/stability.md), so its implicit run
is the reference.
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from ...fmu.variables import port_variables
from .case import CosimRun, CosimSettings, _vec, tip_deflection

SHAFT_K = 300.0


def beam_overrides(settings: CosimSettings, k: float = SHAFT_K, c: float = 0.0) -> list[str]:
    sc, hub = settings.beam.free_scene, settings.beam.hub
    return [*settings.overrides, f"scenes.{sc}.causality.{hub}.rotation=\"compliant\"",
            f"body.ports.{hub}.coupling={{ rotational_stiffness = [0.0, 0.0, {k!r}], rotational_damping = [0.0, 0.0, {c!r}] }}",
            f"scenes.{sc}.duration={settings.duration!r}"]


@dataclasses.dataclass(frozen=True)
class CompliantB5:
    """The two FMUs {"beam", "drive"} and the beam's tip seen from its hub at rest (eq. 92's X_tip)."""

    fmus: dict
    X_tip: tuple[float, float, float]


def build(model_path, fmu_dir, settings: CosimSettings) -> CompliantB5:
    from ...examples import build_hub_drive
    from ...fmu.builder import build_fmu
    from ...model import load_model

    fmu_dir = Path(fmu_dir)
    fmu_dir.mkdir(parents=True, exist_ok=True)
    body = load_model(model_path, beam_overrides(settings)).body
    e = np.asarray(body.direction, float)
    return CompliantB5({"beam": build_fmu(model_path, fmu_dir / "beam_compliant.fmu", scene=settings.beam.free_scene,
                                                 overrides=beam_overrides(settings)),
                        "drive": build_hub_drive(fmu_dir / "hub_drive.fmu")},
                       tuple(float(x) for x in body.length * e / np.linalg.norm(e)))


def connections(acceleration: bool = True) -> list[tuple[str, str, float]]:
    """(source, sink, gain): the drive's hub frame to the beam's compliant hub inputs, minus the
    beam's spring moment to the drive hub, the bearing's (zero) position and velocity."""
    joined = lambda src, dst, fields: [(a, b, 1.0) for f in fields
                                       for a, b in zip(port_variables(src, f), port_variables(dst, f))]
    c = joined("drive.hub_frame", "beam.hub", ("R", "w", "dw") if acceleration else ("R", "w"))
    c += joined("drive.hub", "beam.hub", ("r", "v"))
    c += [("beam.hub.t[3]", "drive.hub_frame.t[3]", -1.0)]
    return c


def start_values(settings: CosimSettings, H: float, beam_step: float | None = None) -> dict:
    sv = {f"drive.{k}": v for k, v in settings.drive.items()}
    sv["drive.drive.k"] = 0.0  # the shaft is in the beam
    sv["drive.profile.T"] = settings.T
    sv["beam.solver.step"] = min(H, settings.beam_step) if beam_step is None else beam_step
    return sv


NODE_R = _vec("beam", "hub", "node.R")
RECORD = [*NODE_R, *_vec("beam", "tip", "r"), "beam.hub.node.w[3]", "beam.hub.t[3]"]


def _result(b5: CompliantB5, t, get, stopped, wall) -> CosimRun:
    """CosimRun from recorded columns: deflection against the beam root (the node frame), hub speed
    of the beam root, shaft torque on the beam."""
    R = np.stack([get(n) for n in NODE_R], -1).reshape(-1, 3, 3)
    r_tip = np.stack([get(n) for n in _vec("beam", "tip", "r")], -1)
    d = tip_deflection(R, np.zeros_like(r_tip), r_tip, np.array(b5.X_tip)) if len(t) else np.zeros(0)
    return CosimRun(np.asarray(t), d, get("beam.hub.node.w[3]"), get("beam.hub.t[3]"), stopped, wall)


def system(b5: CompliantB5, settings: CosimSettings, H: float, duration: float, acceleration: bool = True):
    """The compliant B5 as an SSP system (master/ssp.py): the two FMUs, the connections, the
    drive's parameters and the beam's internal step as parameters, the shaft stiffness inside the
    beam FMU (its `hub.coupling.k_rot[3]` parameter, set too so the package shows it)."""
    from ...master.ssp import Connection, System

    params = {**start_values(settings, H), "beam.hub.coupling.k_rot[3]": SHAFT_K}
    return System("b5_compliant", dict(b5.fmus), tuple(Connection(*c) for c in connections(acceleration)),
                  params, H, 0.0, duration)


def run_master(b5: CompliantB5, settings: CosimSettings, H: float, duration: float, scheme: str = "jacobi",
               acceleration: bool = True) -> CosimRun:
    from ...master import CoSimulation

    t0 = time.perf_counter()
    with CoSimulation(b5.fmus, step=H, scheme=scheme, order=["beam", "drive"],
                      start_values=start_values(settings, H)) as sim:
        for src, dst, g in connections(acceleration):
            sim.connect(src, dst, g)
        res = sim.run(duration, record=RECORD)
    return _result(b5, res.t, lambda n: res.columns[n], res.stopped_early, time.perf_counter() - t0)


def run_libcosim(b5: CompliantB5, settings: CosimSettings, H: float, duration: float, work_dir,
                 acceleration: bool = True, overrides: dict | None = None) -> CosimRun:
    """libcosim's fixed-step algorithm (Jacobi, held inputs) from a generated SSD (engines.libcosim_run)."""
    from ...engines import libcosim_run

    t, cols, stopped, wall = libcosim_run(b5.fmus, connections(acceleration), {**start_values(settings, H), **(overrides or {})},
                                          H, duration, RECORD, work_dir)
    return _result(b5, t, lambda n: cols[n], stopped, wall)


def run_ecos(b5: CompliantB5, settings: CosimSettings, H: float, duration: float, acceleration: bool = True,
             overrides: dict | None = None) -> CosimRun:
    """ecos (ecospy) with its fixed-step Jacobi algorithm, the FMUs loaded in this process."""
    from ...engines import import_ecospy

    ecospy = import_ecospy()
    EcosSimulation, EcosSimulationStructure = ecospy.EcosSimulation, ecospy.EcosSimulationStructure

    t0 = time.perf_counter()
    rows, times, stopped = [], [], ""
    with EcosSimulationStructure() as ss:
        for name, fmu in b5.fmus.items():
            ss.add_model(name, str(fmu))
        for src, dst, g in connections(acceleration):
            s, d = src.replace(".", "::", 1), dst.replace(".", "::", 1)
            if g == 1.0:
                ss.make_real_connection(s, d)
            else:
                ss.make_real_connection(s, d, modifier=lambda v, g=g: g * v)
        ss.add_parameter_set("start", {k.replace(".", "::", 1): float(v)
                                       for k, v in {**start_values(settings, H), **(overrides or {})}.items()})
        with EcosSimulation(structure=ss, step_size=H) as sim:
            sim.init(parameter_set="start")
            for k in range(int(round(duration / H))):
                try:
                    sim.step(1)
                except Exception as e:  # noqa: BLE001 - the engine's report, kept as the run's failure
                    stopped = f"ecos: step at t = {k * H:.6g} s failed: {e}"
                    break
                rows.append([sim.get_real(n.replace(".", "::", 1)) for n in RECORD])
                times.append((k + 1) * H)
            sim.terminate()
    cols = {full: np.array([r[i] for r in rows]) for i, full in enumerate(RECORD)}
    return _result(b5, times, lambda n: cols[n], stopped, time.perf_counter() - t0)
