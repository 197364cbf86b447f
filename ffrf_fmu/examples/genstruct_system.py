"""GenStruct1 or GenStruct2 spun up as a system of two FMUs (docs/inertia-terms.md, "GenStruct1 and GenStruct2
in a system"): the body FMU (models/genstruct{1,2}.toml, scene spin: the hub frame motion-driven) and the spin
drive FMU (spin_drive_slave.py: the prescribed Wu-Haug spin-up, its unbalance set to zero and not connected).

The drive turns about world X; the frames spin about Z. A rotation about X conjugated by the cyclic permutation
of the axes P (x -> z, y -> x, z -> y) is the same rotation about Z: R_z(psi) = P R_x(psi) P^T, componentwise
R_z[i, j] = R_x[s(i), s(j)] with s = (y, z, x) for i = (x, y, z). So the package wires drive.R[s(i), s(j)] to
hub.R[i, j] and drive.w[s(i)], drive.dw[s(i)] to hub.w[i], hub.dw[i]: no other partner is needed. The hub's
translation stays at its inputs' start values (the origin, at rest).

Monolithic reference: the model's scene spin at the FMU's internal step (the same body, the same drive law
evaluated at every step's end; the slave's law is tested equal to runtime/drives.py's). What differs is the
FMU's input rule (docs/fmu.md): the hub frame extrapolated over a communication step from its value, rate and
acceleration at the step's start, so its angular acceleration is held: off by psi''' H at the step's end, at
most (omega / T) (2 pi / T) H = 15.7 rad/s^2 at H = 0.5 ms against the 2000 rad/s^2 peak of the spin-up
(7.9e-3), and exact at speed (psi''' = 0 after T). The frame's lag behind the hub is proportional to the angular
acceleration, so the corner's displacement differs by at most that share of the lag during the spin-up; at speed
only the centrifugal widening is left, which the extrapolation does not touch but through the ringing the
spin-up left (docs/inertia-terms.md).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import system_scene

MODELS = Path(__file__).resolve().parents[2] / "models"
AXES = (1, 2, 0)  # s(i): the drive's axis whose component lands on the hub's axis i (module doc; X -> Z)


def model_path(n: int) -> Path:
    if n not in (1, 2):
        raise ValueError(f"GenStruct{n}: there are GenStruct1 and GenStruct2")
    return MODELS / f"genstruct{n}.toml"


@dataclass(frozen=True)
class GenStructFmus:
    body: Path
    drive: Path
    step: float
    n: int


def build(fmu_dir, n: int, step: float = 5e-4) -> GenStructFmus:
    from . import build_spin_drive

    body, drive = system_scene.build_pair(fmu_dir, model_path(n), f"genstruct{n}.fmu", "spin", [f"step={step!r}"],
                                          build_spin_drive, "spin_drive.fmu")
    return GenStructFmus(body, drive, step, n)


def connections() -> list[tuple[str, str, float]]:
    """The drive's frame, rate and acceleration to the hub's, the axes permuted (module doc)."""
    c = [(f"drive.drive.R[{AXES[i] + 1},{AXES[j] + 1}]", f"body.hub.R[{i + 1},{j + 1}]", 1.0)
         for i in range(3) for j in range(3)]
    return c + [(f"drive.drive.{f}[{AXES[i] + 1}]", f"body.hub.{f}[{i + 1}]", 1.0) for f in ("w", "dw") for i in range(3)]


def drive_parameters(n: int) -> dict[str, float]:
    """The spin drive FMU's parameters from the scene's one haug_spinup drive about Z; no unbalance."""
    from ..model import load_model

    (drive,) = load_model(model_path(n)).scene("spin").drives
    fn = drive.rotation.angle
    if fn.kind != "haug_spinup" or tuple(drive.rotation.axis) != (0.0, 0.0, 1.0) or drive.port != "hub":
        raise ValueError(f"{model_path(n)}: scene spin: the system wires a haug_spinup of the hub about Z")
    return system_scene.spin_drive_parameters(fn, 0.0)


def system(fmus: GenStructFmus, H: float, duration: float):
    return system_scene.system(f"genstruct{fmus.n}_spin", {"body": fmus.body, "drive": fmus.drive}, connections(),
                               {**drive_parameters(fmus.n), "body.solver.step": fmus.step}, H, duration)


# the hub frame from the drive's outputs at the step's end (the body's hub.R are inputs, which the engines record
# before or after the step's transfer alike: a step's lag of the frame, 0.1 rad at speed), its origin at rest
RECORD = ([f"drive.drive.R[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
          + [f"body.corner.r[{k}]" for k in (1, 2, 3)] + ["drive.drive.speed"])


@dataclass
class SpinRun(system_scene.Run):
    """t, the corner's displacement seen from the hub frame (eq. 92, (nt, 3) [m]), the spin rate [rad/s]."""

    u: np.ndarray
    speed: np.ndarray

    @property
    def magnitude(self) -> np.ndarray:
        return np.linalg.norm(self.u, axis=1)

    def mean_at_speed(self, T: float) -> float:
        """The metric of docs/inertia-terms.md: mean |u| over the time at speed (t > T)."""
        return float(self.magnitude[self.t > T + 1e-12].mean())


def _corner_from_hub(R: np.ndarray, r_hub: np.ndarray, r_corner: np.ndarray) -> np.ndarray:
    from ..runtime.outputs import tip_from_hub

    return tip_from_hub(R, r_hub, r_corner, r_corner[0] - r_hub[0])


def run_engine(package, engine: str) -> SpinRun:
    from ..master.ssp import run_ssp

    r = run_ssp(package, engine, RECORD)
    c = r.columns
    R = np.stack([c[f"drive.drive.R[{AXES[i] + 1},{AXES[j] + 1}]"] for i in range(3) for j in range(3)],
                 axis=-1).reshape(-1, 3, 3)
    corner = np.stack([c[f"body.corner.r[{k}]"] for k in (1, 2, 3)], axis=-1)
    return SpinRun(np.asarray(r.t), _corner_from_hub(R, np.zeros_like(corner), corner),
                   np.asarray(c["drive.drive.speed"]), wall=r.wall, stopped=r.stopped)


def run_monolithic(n: int, step: float) -> SpinRun:
    from ..model import load_model
    from ..simulate import run_scene

    t0 = time.perf_counter()
    m = load_model(model_path(n), [f"step={step!r}"])
    res = run_scene(m, "spin")
    speed = system_scene.drive_speed(m.scene("spin").drives[0].rotation.angle, res.t)
    u = _corner_from_hub(res.port("hub", "R"), res.port("hub", "r"), res.port("corner", "r"))
    return SpinRun(np.asarray(res.t), u, speed, wall=time.perf_counter() - t0, stopped=system_scene.stopped(res))


def error(run: SpinRun, ref: SpinRun) -> float:
    """max over the run of |u - u_ref| / max |u_ref|, the reference at the run's times."""
    b = np.stack([np.interp(run.t, ref.t, ref.u[:, k]) for k in range(3)], axis=1)
    return float(np.linalg.norm(run.u - b, axis=1).max() / ref.magnitude.max())
