"""pythonfmu script of the crank FMU (crank-drive partner of the conrod FMU, models/conrod_crank.toml): a
rigid crank of radius r about the world X axis through (0, -r, 0), turned by the Wu-Haug run-up to the
speed omega in T (docs/background.md B1's law) and at omega after it, so that its pin starts at top
dead centre at the origin (the conrod's big eye in its reference position).

Built by `ffrf_fmu.examples.crank_drive.build_crank` (module and class renamed with a digest of this
file, docs/fmu.md). Only the standard library and pythonfmu are imported, through the slave
the partners share (partner_slave.py, shipped beside this script).

A prescribed motion (the crank is rigid and its speed imposed: the conrod's loads do not change it), so
the FMU has no inputs; outputs, exact at every communication point (world axes):
    theta(t) = omega T (tau^2/2 + (cos 2 pi tau - 1)/(2 pi)^2), tau = t/T < 1;  omega (t - T/2) after
    pin.r = (0, -r + r cos theta, r sin theta)
    pin.v = r theta' (0, -sin theta, cos theta)
    pin.a = r theta'' (0, -sin theta, cos theta) - r theta'^2 (0, cos theta, sin theta)
and crank.angle, crank.speed. Joined to the conrod's big eye (translation motion-driven) as r, v, a:
the body extrapolates them to second order over the step (docs/cosim.md, acceleration inputs).
"""
import math

from ffrf_fmu.examples.partner_slave import PartnerSlave, haug_spinup

PARAMETERS = {
    "crank.r": (0.01, "m", "crank radius (half the stroke)"),
    "crank.omega": (5000.0, "rad/s", "crank speed after the run-up"),
    "crank.T": (2.5e-3, "s", "run-up time (Wu-Haug law)"),
}


def crank_motion(t, omega, T):
    """(theta, theta', theta'') of the Wu-Haug run-up (partner_slave.haug_spinup, runtime/drives.py `haug_spinup`)."""
    return haug_spinup(t, omega, T)


def pin_motion(t, r, omega, T):
    """Crank pin position, velocity, acceleration (3-lists, world axes) at t (module doc)."""
    th, dth, ddth = crank_motion(t, omega, T)
    c, s = math.cos(th), math.sin(th)
    return ([0.0, -r + r * c, r * s], [0.0, -r * dth * s, r * dth * c],
            [0.0, -r * ddth * s - r * dth * dth * c, r * ddth * c - r * dth * dth * s])


class CrankPin(PartnerSlave):

    DESCRIPTION = ("Rigid crank at an imposed speed (Wu-Haug run-up to crank.omega in crank.T): outputs the "
                   "crank pin's motion pin.r, pin.v, pin.a (world axes), exact at the communication points; no inputs.")
    PARAMETERS = PARAMETERS
    EXPERIMENT = (0.0, 0.01, 1e-5)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for k, (fld, desc) in enumerate((("r", "position [m]"), ("v", "velocity [m/s]"), ("a", "acceleration [m/s2]"))):
            for i in range(3):
                self.output(f"pin.{fld}[{i + 1}]", f"crank pin {desc}, world axes", lambda k=k, i=i: self._pin()[k][i])
        self.output("crank.angle", "crank angle from top dead centre [rad]", lambda: self._motion()[0])
        self.output("crank.speed", "crank speed [rad/s]", lambda: self._motion()[1])

    def _motion(self):
        return crank_motion(self.t, self.p["crank.omega"], self.p["crank.T"])

    def _pin(self):
        return pin_motion(self.t, self.p["crank.r"], self.p["crank.omega"], self.p["crank.T"])

    def do_step(self, current_time, step_size):
        self.t = current_time + step_size
        return True
