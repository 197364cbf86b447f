"""What the systems of a body FMU and one partner FMU share (car_body_system.py, rotor_system.py,
genstruct_system.py): building the pair, the SSP system of the two, the spin drive's parameters of a
scene's haug_spinup drive, a run's record (its times, wall time and stop reason) and the drive speed of
the monolithic reference run."""
from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from pathlib import Path

import numpy as np


def build_pair(fmu_dir, model: Path, body_fmu: str, scene: str, overrides: list[str], build_partner,
               partner_fmu: str) -> tuple[Path, Path]:
    """(body FMU, partner FMU) built into `fmu_dir`: the body of `model`'s `scene` under `overrides` as
    `body_fmu`, the partner by `build_partner` (an examples.build_* function) as `partner_fmu`."""
    from ..fmu.builder import build_fmu

    d = Path(fmu_dir)
    d.mkdir(parents=True, exist_ok=True)
    body = build_fmu(model, d / body_fmu, scene=scene, overrides=overrides)
    return Path(body), build_partner(d / partner_fmu)


def system(name: str, fmus: dict[str, Path], connections, params: dict[str, float], H: float, duration: float):
    """The SSP system (master/ssp.py) `name` of the FMUs {instance name: path}, the (source, sink, gain)
    connections and the parameters, run from 0 to `duration` at communication step H."""
    from ..master.ssp import Connection, System

    return System(name, {k: str(v) for k, v in fmus.items()}, tuple(Connection(*c) for c in connections),
                  params, H, 0.0, duration)


def spin_drive_parameters(angle, mass_eccentricity: float) -> dict[str, float]:
    """The spin drive FMU's parameters (spin_drive_slave.py) of a haug_spinup angle function (omega, T)
    and the unbalance m e [kg m] (0: none)."""
    p = dict(angle.params)
    return {"drive.profile.omega": p["omega"], "drive.profile.T": p["T"], "drive.unbalance.me": mass_eccentricity}


def drive_speed(angle, t) -> np.ndarray:
    """The rate [rad/s] of a drive's angle function at the times t (runtime/drives.py)."""
    from ..runtime import drives

    return np.array([drives.evaluate(angle.kind, dict(angle.params), ti)[1] for ti in t])


@dataclass
class Run:
    """The times [s] of a system's or its reference's run, its wall time [s] and why it stopped early ("" if
    it completed); a system's run adds its histories at those times."""

    t: np.ndarray
    _: KW_ONLY
    wall: float = 0.0
    stopped: str = ""


def stopped(result) -> str:
    """Why a monolithic run (simulate.run_scene) stopped early, "" if it completed."""
    return "" if result.summary["completed"] else str(result.summary["failure"])
