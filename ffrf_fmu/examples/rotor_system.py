"""The Jeffcott rotor run up through its first critical speed as a system of two FMUs (docs/cosim.md,
"The Jeffcott rotor run-up"): the rotor FMU (models/jeffcott_runup.toml, scene runup: bearings and the
torsional drive spring `compliant` ports inside it) and the spin drive FMU (spin_drive_slave.py: the
prescribed Wu-Haug spin-up of the drive spring's far end and the rotating unbalance force on the disc).

Why the bearings inside and the drive outside: the bearings are stiff springs (1e7 N/m, 100 x the
shaft) on the shaft ends, whose interface inertia is a few grams of shaft; as a partner FMU their force
would reach that inertia one step late, which docs/cosim.md's table shows unstable under Jacobi (the
spring left in the partner: B5 fails from 5 ms; here omega H at 1e7 N/m on ~0.1 kg is ~5 at 0.5 ms).
Inside the body they are integrated implicitly (runtime/coupling.py) and the partner is a prescribed
motion and a load, which any engine couples stably. The co-simulation error is then the input rule
(docs/fmu.md): the drive frame extrapolated to second order with its dw (exact for a fixed axis up to
the change of psi'' over a step), and the unbalance force held over the step, i.e. applied one
communication step late: a phase lag psi' H of the whirl, first order in H; the whirl amplitude
hypot(y, z) is blind to the phase in steady state and sees the lag only through the slowly changing
speed (the peak's speed moves by alpha H).

Monolithic reference: the model's scene runup at the FMU's internal step: the same body, bearings and
drive spring (the same code and coefficients), the drive angle and the unbalance force from the same
laws (runtime/drives.py "haug_spinup", simulate/inputs.unbalance_force; repeated in the drive FMU and
tested equal), evaluated at every step's end.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import system_scene

MODEL = Path(__file__).resolve().parents[2] / "models" / "jeffcott_runup.toml"


@dataclass(frozen=True)
class RotorFmus:
    body: Path
    drive: Path
    step: float


def model_overrides(step: float, duration: float, T: float | None = None) -> list[str]:
    o = [f"step={step!r}", f"duration={duration!r}"]
    return o + ([f"scenes.runup.drives.bearing_a.rotation.angle.T={T!r}"] if T is not None else [])


def build(fmu_dir, step: float = 5e-4, duration: float = 10.0) -> RotorFmus:
    from . import build_spin_drive

    body, drive = system_scene.build_pair(fmu_dir, MODEL, "jeffcott_rotor.fmu", "runup",
                                          model_overrides(step, duration), build_spin_drive, "spin_drive.fmu")
    return RotorFmus(body, drive, step)


def connections() -> list[tuple[str, str, float]]:
    """The drive frame, rate and acceleration to bearing_a's compliant rotation, the unbalance force to the disc."""
    from ..fmu.variables import port_variables

    c = [(f"drive.{a}", f"body.{b}", 1.0) for fld in ("R", "w", "dw")
         for a, b in zip(port_variables("drive", fld), port_variables("bearing_a", fld))]
    return c + [(f"drive.unbalance.f[{i}]", f"body.disc.f[{i}]", 1.0) for i in (1, 2, 3)]


def drive_parameters(T: float | None = None) -> dict[str, float]:
    """The spin drive FMU's parameters from the scene (its haug_spinup drive, its one unbalance)."""
    from ..model import load_model

    sc = load_model(MODEL, [] if T is None else model_overrides(5e-4, 1.0, T)[2:]).scene("runup")
    (drive,), (ub,) = sc.drives, sc.unbalances
    fn = drive.rotation.angle
    if (fn.kind != "haug_spinup" or tuple(drive.rotation.axis) != (1.0, 0.0, 0.0) or tuple(ub.reference) != (0.0, 1.0, 0.0)
            or ub.phase != 0.0):
        raise ValueError(f"{MODEL}: scene runup: the spin drive FMU turns about X with the unbalance at +Y")
    return system_scene.spin_drive_parameters(fn, ub.mass_eccentricity)


def system(fmus: RotorFmus, H: float, duration: float, T: float | None = None):
    return system_scene.system("jeffcott_runup", {"body": fmus.body, "drive": fmus.drive}, connections(),
                               {**drive_parameters(T), "body.solver.step": fmus.step}, H, duration)


RECORD = ["body.disc.r[2]", "body.disc.r[3]", "drive.drive.speed"]


@dataclass
class RotorRun(system_scene.Run):
    """t, the disc's whirl amplitude hypot(y, z) [m], the drive speed [rad/s]."""

    whirl: np.ndarray
    speed: np.ndarray

    @property
    def peak(self) -> tuple[float, float]:
        """(peak whirl amplitude [m], the drive speed there [rad/s])."""
        i = int(np.argmax(self.whirl))
        return float(self.whirl[i]), float(self.speed[i])


def run_engine(package, engine: str) -> RotorRun:
    from ..master.ssp import run_ssp

    r = run_ssp(package, engine, RECORD)
    c = r.columns
    return RotorRun(np.asarray(r.t), np.hypot(c["body.disc.r[2]"], c["body.disc.r[3]"]),
                    np.asarray(c["drive.drive.speed"]), wall=r.wall, stopped=r.stopped)


def run_monolithic(step: float, duration: float, T: float | None = None) -> RotorRun:
    import time

    from ..model import load_model
    from ..simulate import run_scene

    t0 = time.perf_counter()
    m = load_model(MODEL, model_overrides(step, duration, T))
    res = run_scene(m, "runup")
    speed = system_scene.drive_speed(m.scene("runup").drives[0].rotation.angle, res.t)
    return RotorRun(np.asarray(res.t), np.hypot(res.columns["disc.r[2]"], res.columns["disc.r[3]"]), speed,
                    wall=time.perf_counter() - t0, stopped=system_scene.stopped(res))


def error(run: RotorRun, ref: RotorRun) -> float:
    """max over the run of |whirl - whirl_ref| / max whirl_ref, the reference at the run's times."""
    b = np.interp(run.t, ref.t, ref.whirl)
    return float(np.max(np.abs(run.whirl - b)) / np.max(ref.whirl))
