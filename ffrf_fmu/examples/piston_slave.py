"""pythonfmu script of the piston FMU (crank-drive partner of the conrod FMU, models/conrod_crank.toml):
a piston of mass m sliding along the cylinder axis (world Y), loaded by the gas force and by the
gudgeon pin's spring, whose spring lives in the conrod FMU (its small eye `compliant`, docs/cosim.md).

Built by `ffrf_fmu.examples.crank_drive.build_piston` (module and class renamed with a digest of this
file, docs/fmu.md). Only the standard library and pythonfmu are imported, through the slave
the partners share (partner_slave.py, shipped beside this script).

Seen from the piston (port `pin`, docs/fmu.md's fields):
- outputs pin.r, pin.v, pin.a (world axes): the gudgeon pin's centre (0, y0 + x, 0), its velocity and
  acceleration: the far end of the conrod's small-eye spring (the cylinder guide holds X and Z at 0);
  pin.R = identity, pin.w = pin.dw = 0: the piston does not turn;
- input pin.f: the force of the spring ON THE CONROD (the conrod's small_eye.f); the piston feels -pin.f,
  of which the cylinder wall takes the X and Z parts (output piston.side_force = -pin.f[3]).
Equations (along Y, x the piston's displacement from its reference y0):
    m x'' = -pin.f[2] - F_gas(t)
    F_gas(t) = F_max sin^4(pi phi / width) for 0 <= phi < width, else 0, phi = theta(t) mod 2 pi,
    in every revolution that starts at or after the crank's run-up (theta(T) <= 2 pi k); theta(t) the
    crank's Wu-Haug run-up to omega in T (crank_pin_slave.py, the same law): the gas pushes the
    piston towards the crank (-Y) after top dead centre.
Inputs between communication points: pin.f held at its value at t_c (a Jacobi master's rule); the gas
force is evaluated at each substep. Integration: classical Runge-Kutta with n = ceil(H / solver.substep)
substeps. Outputs are the values at the end of the step (no direct feedthrough).
"""
import math

from pythonfmu.enums import Fmi2Status

from ffrf_fmu.examples.partner_slave import PartnerSlave, haug_spinup

PARAMETERS = {
    "piston.m": (0.2, "kg", "piston mass (with its gudgeon pin)"),
    "piston.y0": (0.155, "m", "reference position of the gudgeon pin on the cylinder axis (world Y)"),
    "crank.omega": (5000.0, "rad/s", "crank speed after the run-up"),
    "crank.T": (2.5e-3, "s", "run-up time of the crank (Wu-Haug law)"),
    "gas.F_max": (2.0e4, "N", "peak gas force on the piston"),
    "gas.width": (1.0471975511965976, "rad", "crank angle over which the gas force acts after top dead centre"),
    "solver.substep": (2.5e-6, "s", "largest Runge-Kutta substep"),
}


def crank_angle(t, omega, T):
    """Wu-Haug run-up angle (partner_slave.haug_spinup, runtime/drives.py `haug_spinup`)."""
    return haug_spinup(t, omega, T)[0]


def gas_force(t, omega, T, F_max, width):
    """The gas force's magnitude [N] at t (module doc)."""
    theta = crank_angle(t, omega, T)
    k = math.floor(theta / (2.0 * math.pi))
    phi = theta - 2.0 * math.pi * k
    if 2.0 * math.pi * k < crank_angle(T, omega, T) or phi >= width:
        return 0.0
    return F_max * math.sin(math.pi * phi / width) ** 4


class Piston(PartnerSlave):

    DESCRIPTION = ("Piston mass on the cylinder axis (world Y) with the gas force of a firing engine; port pin: "
                   "outputs the gudgeon pin's motion (r, v, a; R = I, w = dw = 0), input the pin spring's force "
                   "on the conrod (f). Inputs held over the step, RK4 substeps, outputs at the step end.")
    PARAMETERS = PARAMETERS
    EXPERIMENT = (0.0, 0.01, 1e-5)
    STATE = ("p", "f", "x", "t", "acc")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.f = [0.0, 0.0, 0.0]
        self.x = [0.0, 0.0]  # displacement, velocity
        self.acc = 0.0
        out = self.output
        for i in range(3):
            out(f"pin.r[{i + 1}]", "gudgeon pin centre, world axes [m]",
                lambda k=i: self.p["piston.y0"] + self.x[0] if k == 1 else 0.0)
        for i in range(3):
            out(f"pin.v[{i + 1}]", "gudgeon pin velocity, world axes [m/s]", lambda k=i: self.x[1] if k == 1 else 0.0)
        for i in range(3):
            out(f"pin.a[{i + 1}]", "gudgeon pin acceleration, world axes [m/s2]", lambda k=i: self.acc if k == 1 else 0.0)
        for i in range(3):
            for j in range(3):
                out(f"pin.R[{i + 1},{j + 1}]", "piston frame (fixed): world component i of axis j",
                    lambda v=1.0 if i == j else 0.0: v)
        for i in range(3):
            out(f"pin.w[{i + 1}]", "piston angular velocity (0) [rad/s]", lambda: 0.0)
        for i in range(3):
            out(f"pin.dw[{i + 1}]", "piston angular acceleration (0) [rad/s2]", lambda: 0.0)
        for i in range(3):
            self.input(f"pin.f[{i + 1}]", "force of the pin spring ON THE CONROD, world axes [N]", "f", i)
        out("piston.x", "piston displacement from y0 along Y [m]", lambda: self.x[0])
        out("piston.side_force", "force of the piston on the cylinder wall across the axis (Z) [N]", lambda: -self.f[2])
        out("gas.force", "gas force on the piston (towards the crank) [N]", lambda: self._gas(self.t))

    def _gas(self, t):
        p = self.p
        return gas_force(t, p["crank.omega"], p["crank.T"], p["gas.F_max"], p["gas.width"])

    def _rhs(self, t, x):
        return [x[1], (-self.f[1] - self._gas(t)) / self.p["piston.m"]]

    def exit_initialization_mode(self):
        self.acc = self._rhs(self.t, self.x)[1]

    def do_step(self, current_time, step_size):
        if not all(math.isfinite(v) for v in self.f + [step_size]) or step_size <= 0.0:
            self.log(f"t = {current_time:g} s: non-finite input or bad step {step_size!r}", Fmi2Status.discard)
            return False
        n = max(1, math.ceil(step_size / self.p["solver.substep"] - 1e-9))
        h = step_size / n
        x, t = list(self.x), current_time
        for _ in range(n):
            k1 = self._rhs(t, x)
            k2 = self._rhs(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(x, k1)])
            k3 = self._rhs(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(x, k2)])
            k4 = self._rhs(t + h, [a + h * b for a, b in zip(x, k3)])
            x = [a + h / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]
            t += h
        self.x, self.t = x, current_time + step_size
        self.acc = self._rhs(self.t, self.x)[1]
        return True
