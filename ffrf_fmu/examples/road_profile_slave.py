"""pythonfmu script of the road profile FMU: the road heights under the four wheels of a vehicle body
(models/car_body.toml's mounts), the partner of the car body FMU whose mounts are `compliant`.

The body FMU carries the mounts' spring-dampers (its compliant ports, docs/cosim.md: the physical
compliance in the body, so plain Jacobi is stable at any step). This FMU is the far end of each
spring: a prescribed motion, the road under the wheel. Per wheel W in front_left, front_right,
rear_left, rear_right it outputs the vertical component of the mount's motion inputs, `W.r[3]`,
`W.v[3]`, `W.a[3]` (the acceleration for the body's second-order extrapolation, docs/fmu.md); the
horizontal components stay at the body's start values (the mount points).

Road: flat but for one bump of height `road.bump.value` and length `road.bump.duration` (in time)
from `road.bump.t_start` under wheel `road.bump.wheel` (1 front_left, 2 front_right, 3 rear_left,
4 rear_right): z = value sin^4(pi tau), tau = (t - t_start) / duration in [0, 1), the model format's
`kind = "bump"` time function (runtime/drives.py, repeated here so that this FMU needs only the
standard library and pythonfmu; tests/test_car_body_system.py checks the two agree). A vehicle that
drives over the bump hits it with the rear wheel of the same side `road.wheelbase_time` seconds later
(0: never, the car body model's scene `bump`).

Built by `ffrf_fmu.examples.build_road_profile`, which renames the module and the class with a
digest of this file and of partner_slave.py, shipped beside it (pythonfmu FMUs whose scripts share a
name collide in one process, docs/fmu.md). Outputs are the values at the end of the step (no inputs:
an exact signal).
"""
import math

from pythonfmu import Real
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability

from ffrf_fmu.examples.partner_slave import PartnerSlave

WHEELS = ("front_left", "front_right", "rear_left", "rear_right")
REAR_OF = {1: 3, 2: 4}  # the rear wheel on the side of a front one
PARAMETERS = {
    # name: (default, unit, description)
    "road.bump.value": (0.02, "m", "bump height"),
    "road.bump.t_start": (0.1, "s", "time the bumped wheel reaches the bump"),
    "road.bump.duration": (0.2, "s", "time the wheel takes to cross the bump"),
    "road.wheelbase_time": (0.0, "s", "delay of the rear wheel on the bump's side (0: no rear hit)"),
}


def bump(t, value, t_start, duration):
    """(z, dz/dt, d2z/dt2) of value sin^4(pi tau), tau = (t - t_start) / duration in [0, 1), else 0."""
    tau = (t - t_start) / duration
    if not 0.0 <= tau < 1.0:
        return 0.0, 0.0, 0.0
    sn, cs, k = math.sin(math.pi * tau), math.cos(math.pi * tau), math.pi / duration
    return value * sn**4, 4.0 * value * k * sn**3 * cs, 4.0 * value * k * k * (3.0 * sn * sn * cs * cs - sn**4)


class RoadProfile(PartnerSlave):

    DESCRIPTION = ("Road heights under four wheels (front_left, front_right, rear_left, rear_right): W.r[3], W.v[3], "
                   "W.a[3], flat but for a sin^4 bump under road.bump.wheel (1..4) from road.bump.t_start for "
                   "road.bump.duration s, the rear wheel of that side road.wheelbase_time s later (0: never). "
                   "Outputs at the step end; no inputs.")
    PARAMETERS = PARAMETERS
    EXPERIMENT = (0.0, 2.0, 1e-3)
    STATE = ("p", "wheel", "t", "z")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.wheel = 1
        self.z = [[0.0, 0.0, 0.0] for _ in WHEELS]
        self.register_variable(
            Real("road.bump.wheel", start=1.0, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                 initial=Fmi2Initial.exact, description="the bumped wheel: 1 front_left, 2 front_right, 3 rear_left, "
                 "4 rear_right (a Real: SSP parameter sets carry reals)", getter=lambda: float(self.wheel),
                 setter=lambda v: setattr(self, "wheel", int(round(float(v))))),
            nested=False)
        for w, wheel in enumerate(WHEELS):
            for k, (fld, unit) in enumerate((("r", "m"), ("v", "m/s"), ("a", "m/s2"))):
                self.output(f"{wheel}.{fld}[3]", f"road under {wheel}: vertical {('height', 'rate', 'acceleration')[k]} "
                            f"[{unit}]", lambda w=w, k=k: self.z[w][k], 0.0)

    def _update(self, t):
        p = self.p
        law = (p["road.bump.value"], p["road.bump.t_start"], p["road.bump.duration"])
        self.z = [[0.0, 0.0, 0.0] for _ in WHEELS]
        self.z[self.wheel - 1] = list(bump(t, *law))
        rear = REAR_OF.get(self.wheel)
        if rear and p["road.wheelbase_time"] > 0.0:
            self.z[rear - 1] = list(bump(t - p["road.wheelbase_time"], *law))

    def exit_initialization_mode(self):
        if not 1 <= self.wheel <= 4 or self.p["road.bump.duration"] <= 0.0:
            self.log(f"road.bump.wheel = {self.wheel} (expected 1..4) or road.bump.duration = "
                     f"{self.p['road.bump.duration']} (expected > 0)")
            return False
        self._update(self.t)

    def do_step(self, current_time, step_size):
        self.t = current_time + step_size
        self._update(self.t)
        return True
