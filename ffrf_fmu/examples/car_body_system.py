"""The car body on its four mounts driven by a road bump, as a system of two FMUs (docs/cosim.md,
"The car body on its mounts"): the car body FMU (models/car_body.toml; its four mounts `compliant`
translations, i.e. the mount spring-dampers inside the body, runtime/coupling.py) and the road
profile FMU (road_profile_slave.py), the far ends of the four springs.

Why the springs sit in the body: docs/cosim.md's table, "a physical spring/shaft/bushing to a
partner": the stiff side of the coupling, the spring on the body's small interface inertia, is
integrated implicitly with the body, and the partner here is a prescribed motion (the road), so
plain Jacobi is the exact map of the standalone scene up to the input rule: each mount's far end
r, v, a at t_c, extrapolated to second order over the step (docs/fmu.md). That is the whole
co-simulation error: O(H^2) in the rates, O(H^3) in the positions of the springs' far ends.

Monolithic reference: the model's own scene `bump` at the FMU's internal step. It is the same system
in one process: the same body, the same spring-damper law f = K (r_in - x_N) + C (v_in - xdot_N)
(the same code, runtime/coupling.py, with the same coefficients from the model file), and the road
as the same function (runtime/drives.py "bump", repeated in the road FMU and tested equal), which the
standalone run evaluates exactly at every step's end.

Outputs: the body's twist, two ways. `probe.rear_right_from_front_left[3]` (the FMU's eq. 92
output, the scene's `outputs`): the rear right mount's vertical elastic displacement seen from the
front left mount's frame; and the twist angle of the floor from the four mount nodes,
    theta = ((z_FL - z_FR) - (z_RL - z_RR)) / track,   track = 1.5 m,
the difference of the front and rear roll angles (a rigid heave, pitch or roll leaves it at zero to
first order in the angles).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import system_scene

MODEL = Path(__file__).resolve().parents[2] / "models" / "car_body.toml"
WHEELS = ("front_left", "front_right", "rear_left", "rear_right")
TRACK = 1.5  # m, the mounts' y distance (models/car_body.toml)
PROBE = "probe.rear_right_from_front_left[3]"


@dataclass(frozen=True)
class CarBodyFmus:
    """The two FMUs of the system and the body's internal step they were built for."""

    body: Path
    road: Path
    step: float


def model_overrides(step: float, duration: float) -> list[str]:
    return [f"step={step!r}", f"duration={duration!r}"]


def build(fmu_dir, step: float = 1e-3, duration: float = 2.0) -> CarBodyFmus:
    """The car body FMU (internal step `step`) and the road profile FMU in `fmu_dir`."""
    from . import build_road_profile

    body, road = system_scene.build_pair(fmu_dir, MODEL, "car_body.fmu", "bump", model_overrides(step, duration),
                                         build_road_profile, "road_profile.fmu")
    return CarBodyFmus(body, road, step)


def connections() -> list[tuple[str, str, float]]:
    """(source, sink, gain): each wheel's road height, rate and acceleration to the mount's far end."""
    return [(f"road.{w}.{f}[3]", f"body.{w}.{f}[3]", 1.0) for w in WHEELS for f in ("r", "v", "a")]


def road_parameters(model=None) -> dict[str, float]:
    """The road FMU's parameters of the scene's bump drive (models/car_body.toml, scene bump)."""
    from ..model import load_model

    m = model or load_model(MODEL)
    (drive,) = [d for d in m.scene("bump").drives if d.translation is not None]
    fn = drive.translation.displacement
    if fn.kind != "bump" or drive.port not in WHEELS:
        raise ValueError(f"{MODEL}: scene bump: expected one bump drive on a mount, got {fn.kind!r} on {drive.port!r}")
    p = dict(fn.params)
    return {"road.road.bump.value": p["value"], "road.road.bump.t_start": p["t_start"],
            "road.road.bump.duration": p["duration"], "road.road.bump.wheel": float(WHEELS.index(drive.port) + 1)}


def system(fmus: CarBodyFmus, H: float, duration: float):
    """The SSP system (master/ssp.py): body and road, the connections, the road's bump and the body's
    internal step as parameters."""
    return system_scene.system("car_body_bump", {"body": fmus.body, "road": fmus.road}, connections(),
                               {**road_parameters(), "body.solver.step": fmus.step}, H, duration)


RECORD = [f"body.{w}.node.r[3]" for w in WHEELS] + [f"body.{PROBE}", "body.front_left.f[3]"]


@dataclass
class CarBodyRun(system_scene.Run):
    """Histories of one run: t, the twist angle theta [rad], the probe [m], the bumped mount's force [N]."""

    twist: np.ndarray
    probe: np.ndarray
    force: np.ndarray


def twist_angle(z: dict) -> np.ndarray:
    """theta = ((z_FL - z_FR) - (z_RL - z_RR)) / track (module doc)."""
    return ((z["front_left"] - z["front_right"]) - (z["rear_left"] - z["rear_right"])) / TRACK


def run_engine(package, engine: str) -> CarBodyRun:
    """Run the package under `engine` (master, libcosim, ecos; master/ssp.run_ssp)."""
    from ..master.ssp import run_ssp

    r = run_ssp(package, engine, RECORD)
    c = r.columns
    z = {w: np.asarray(c[f"body.{w}.node.r[3]"]) for w in WHEELS}
    return CarBodyRun(np.asarray(r.t), twist_angle(z), np.asarray(c[f"body.{PROBE}"]),
                      np.asarray(c["body.front_left.f[3]"]), wall=r.wall, stopped=r.stopped)


def run_monolithic(step: float, duration: float) -> CarBodyRun:
    """The scene bump in one process at the FMU's internal step (module doc: the same system)."""
    import time

    from ..model import load_model
    from ..simulate import run_scene

    t0 = time.perf_counter()
    res = run_scene(load_model(MODEL, model_overrides(step, duration)), "bump")
    c = res.columns
    z = {w: np.asarray(c[f"{w}.r[3]"]) for w in WHEELS}  # a compliant part's r: the body's node
    probe = probe_history(res)
    return CarBodyRun(np.asarray(res.t), twist_angle(z), probe[:, 2], np.asarray(c["front_left.f[3]"]),
                      wall=time.perf_counter() - t0, stopped=system_scene.stopped(res))


def probe_history(result) -> np.ndarray:
    """eq. (92) of the standalone run, what the FMU outputs as probe.rear_right_from_front_left: the rear
    right mount seen from the front left one, X_A - X_B their distance at rest (the run's first row)."""
    from ..runtime.outputs import tip_from_hub

    rB, rA = result.port("front_left", "r"), result.port("rear_right", "r")
    return tip_from_hub(result.port("front_left", "R"), rB, rA, rA[0] - rB[0])


def error(run: CarBodyRun, ref: CarBodyRun, field: str) -> float:
    """max over the run of |run - ref| / max |ref|, the reference sampled at the run's times."""
    a, b = getattr(run, field), np.interp(run.t, ref.t, getattr(ref, field))
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))
