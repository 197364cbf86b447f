"""pythonfmu script of the hub drive FMU (B5 partner of the beam FMU): a rigid hub inertia on a
fixed bearing, driven by a motor under a PI speed controller that tracks the Wu-Haug spin-up
speed profile, and joined to the beam root by a torsional shaft (stiffness k, damping c).

Built by `ffrf_fmu.examples.build_hub_drive`, which renames the module and the class with a digest
of this file (pythonfmu FMUs whose scripts share a name collide in one process, docs/fmu.md). Only
the standard library and pythonfmu are imported (with partner_slave.py, the slave the partners share,
shipped beside this script): the FMU runs wherever pythonfmu runs.

Port `hub` follows docs/fmu.md, seen from the drive:
- translation force-driven: outputs hub.r = 0, hub.v = 0 (the bearing holds the hub axis at the
  origin), input hub.f (force of the beam on the hub: taken by the bearing, unused);
- rotation motion-driven: inputs hub.R, hub.w = the beam root frame and angular velocity (world
  axes); output hub.t = the moment the beam applies ON the drive = -(shaft torque on the beam).
Joined with master.CoSimulation.connect_ports to the beam FMU's hub port (rotation
force-driven, translation motion-driven), the beam receives -hub.t = the shaft torque.

Equations (about the world Z axis, which is the drive axis):
    theta_b  = beam root angle from hub.R (unwrapped next to the hub angle), omega_b = hub.w[3]
    tau_s    = k (theta - theta_b) + c (omega - omega_b)            shaft torque on the beam
    tau_m    = Kp (omega_ref(t) - omega) + Ki z                      PI motor torque
    J dtheta/dt = J omega,  J domega/dt = tau_m - tau_s,  dz/dt = omega_ref(t) - omega
omega_ref is the Wu-Haug spin-up rate (docs/background.md B1): omega_f (tau - sin(2 pi tau)/(2 pi)),
tau = t/T, then omega_f. Inputs between communication points (same rule as the body FMUs,
docs/fmu.md): the values set before doStep(t_c, H) are the values at t_c; the beam angle is
extrapolated with its rate, theta_b(t) = theta_b(t_c) + omega_b(t_c) (t - t_c), omega_b held.
Integration: classical Runge-Kutta with n = ceil(H / solver.substep) equal substeps.

For compliant coupling (docs/cosim.md) the shaft lives in the beam FMU instead (its hub rotation
`compliant`, rotational stiffness = the shaft's) and the drive's own shaft is off (drive.k = 0):
the drive then gives its hub frame `hub_frame.R`, `hub_frame.w`, `hub_frame.dw` (world axes; the
beam's motion inputs, dw for their second-order extrapolation) and takes the moment of the shaft
on the hub `hub_frame.t` (world axes, held over the step; only the Z component acts):
    J domega/dt = tau_m - tau_s + hub_frame.t[3].
Outputs are the values at the end of the step (no direct feedthrough).
"""
import math

from pythonfmu.enums import Fmi2Status

from ffrf_fmu.examples.partner_slave import PartnerSlave, haug_spinup

PARAMETERS = {
    # name: (default, unit, description)
    "drive.J": (5.0, "kg.m2", "hub inertia about the drive axis"),
    "drive.k": (300.0, "N.m/rad", "torsional stiffness of the shaft between hub and beam root"),
    "drive.c": (0.0, "N.m.s/rad", "torsional damping of the shaft"),
    "drive.Kp": (100.0, "N.m.s/rad", "PI speed controller: proportional gain"),
    "drive.Ki": (200.0, "N.m/rad", "PI speed controller: integral gain"),
    "profile.omega": (4.0, "rad/s", "final spin rate of the Wu-Haug speed reference"),
    "profile.T": (15.0, "s", "spin-up time of the Wu-Haug speed reference"),
    "solver.substep": (5.0e-4, "s", "largest Runge-Kutta substep"),
}
OUTPUTS = {
    "drive.angle": ("rad", "hub angle"),
    "drive.speed": ("rad/s", "hub speed"),
    "drive.speed_reference": ("rad/s", "speed reference of the PI controller"),
    "drive.motor_torque": ("N.m", "motor torque on the hub"),
    "drive.shaft_torque": ("N.m", "shaft torque on the beam root (about Z)"),
    "drive.integral": ("rad", "integral of the speed error"),
}


def speed_reference(t, omega, T):
    """Wu-Haug spin-up rate (partner_slave.haug_spinup; docs/background.md B1)."""
    return haug_spinup(t, omega, T)[1]


class HubDrive(PartnerSlave):

    DESCRIPTION = ("Hub inertia + motor + PI speed controller (Wu-Haug speed profile) + torsional shaft to "
                   "the beam root. Port hub (docs/fmu.md): rotation motion-driven (inputs R, w of the beam root; "
                   "output t = moment of the beam on the hub), translation force-driven (r = v = 0 outputs, "
                   "f input unused). Inputs are values at t_c; the beam angle is extrapolated with its rate "
                   "over the step. RK4 substeps. Outputs at the step end, no direct feedthrough.")
    PARAMETERS = PARAMETERS
    EXPERIMENT = (0.0, 20.0, 2e-3)
    STATE = ("p", "R", "w", "f", "x", "t", "out", "torque_on_drive", "t_ext", "dw")  # complete

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.R = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]  # row-major, R[i,j] = R[3(i-1) + j-1]
        self.w = [0.0, 0.0, 0.0]
        self.f = [0.0, 0.0, 0.0]
        self.x = [0.0, 0.0, 0.0]  # theta, omega, z
        self.out = {k: 0.0 for k in OUTPUTS}
        self.torque_on_drive = [0.0, 0.0, 0.0]
        self.t_ext = [0.0, 0.0, 0.0]  # hub_frame.t: external moment on the hub (compliant coupling)
        self.dw = 0.0  # hub angular acceleration at the step end
        out, inp = self.output, self.input
        for i in range(3):
            out(f"hub.r[{i + 1}]", "hub position (fixed bearing) [m]", lambda: 0.0, 0.0)
        for i in range(3):
            for j in range(3):
                inp(f"hub.R[{i + 1},{j + 1}]", "beam root frame: world component i of nodal axis j", "R", 3 * i + j,
                    1.0 if i == j else 0.0)
        for i in range(3):
            out(f"hub.v[{i + 1}]", "hub velocity (fixed bearing) [m/s]", lambda: 0.0, 0.0)
        for i in range(3):
            inp(f"hub.w[{i + 1}]", "beam root angular velocity, world axes [rad/s]", "w", i)
        for i in range(3):
            inp(f"hub.f[{i + 1}]", "force of the beam on the hub (taken by the bearing, unused) [N]", "f", i)
        for i in range(3):
            out(f"hub.t[{i + 1}]", "moment of the beam ON the hub = -(shaft torque on the beam), world axes [N.m]",
                lambda k=i: self.torque_on_drive[k], 0.0)
        for i in range(3):
            for j in range(3):
                out(f"hub_frame.R[{i + 1},{j + 1}]",
                    "hub frame (rotation about Z by the hub angle): world component i of axis j",
                    lambda a=i, b=j: self._hub_R()[3 * a + b], 1.0 if i == j else 0.0)
        for i in range(3):
            out(f"hub_frame.w[{i + 1}]", "hub angular velocity, world axes [rad/s]",
                lambda k=i: self.x[1] if k == 2 else 0.0, 0.0)
        for i in range(3):
            out(f"hub_frame.dw[{i + 1}]", "hub angular acceleration, world axes [rad/s2]",
                lambda k=i: self.dw if k == 2 else 0.0, 0.0)
        for i in range(3):
            inp(f"hub_frame.t[{i + 1}]", "external moment on the hub, world axes (compliant coupling: minus the "
                "beam's hub.t; only Z acts) [N.m]", "t_ext", i)
        for name, (unit, desc) in OUTPUTS.items():
            out(name, f"{desc} [{unit}]", lambda n=name: self.out[n], 0.0)

    # ------------------------------------------------------------------ dynamics
    def _hub_R(self):
        c, s = math.cos(self.x[0]), math.sin(self.x[0])
        return [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0]

    def _beam_angle(self, theta_hub):
        raw = math.atan2(self.R[3], self.R[0])  # R[2,1], R[1,1]
        return theta_hub + math.remainder(raw - theta_hub, 2.0 * math.pi)

    def _rhs(self, t, x, theta_b, omega_b):
        p = self.p
        theta, omega, z = x
        ref = speed_reference(t, p["profile.omega"], p["profile.T"])
        tau_s = p["drive.k"] * (theta - theta_b) + p["drive.c"] * (omega - omega_b)
        tau_m = p["drive.Kp"] * (ref - omega) + p["drive.Ki"] * z
        return [omega, (tau_m - tau_s + self.t_ext[2]) / p["drive.J"], ref - omega]

    def _update_outputs(self, t, theta_b, omega_b):
        p = self.p
        theta, omega, z = self.x
        ref = speed_reference(t, p["profile.omega"], p["profile.T"])
        tau_s = p["drive.k"] * (theta - theta_b) + p["drive.c"] * (omega - omega_b)
        self.out.update({"drive.angle": theta, "drive.speed": omega, "drive.speed_reference": ref,
                         "drive.motor_torque": p["drive.Kp"] * (ref - omega) + p["drive.Ki"] * z,
                         "drive.shaft_torque": tau_s, "drive.integral": z})
        self.torque_on_drive = [0.0, 0.0, -tau_s]
        self.dw = self._rhs(t, self.x, theta_b, omega_b)[1]

    def exit_initialization_mode(self):
        self._update_outputs(self.t, self._beam_angle(self.x[0]), self.w[2])

    def do_step(self, current_time, step_size):
        values = self.R + self.w + self.t_ext + [step_size]
        if not all(math.isfinite(v) for v in values) or step_size <= 0.0:
            self.log(f"t = {current_time:g} s: non-finite input or bad step {step_size!r}", Fmi2Status.discard)
            return False
        theta_b0, omega_b = self._beam_angle(self.x[0]), self.w[2]
        n = max(1, math.ceil(step_size / self.p["solver.substep"] - 1e-9))
        h = step_size / n
        x, t = list(self.x), current_time
        tb = lambda s: theta_b0 + omega_b * (s - current_time)  # noqa: E731
        for _ in range(n):
            k1 = self._rhs(t, x, tb(t), omega_b)
            x2 = [a + 0.5 * h * b for a, b in zip(x, k1)]
            k2 = self._rhs(t + 0.5 * h, x2, tb(t + 0.5 * h), omega_b)
            x3 = [a + 0.5 * h * b for a, b in zip(x, k2)]
            k3 = self._rhs(t + 0.5 * h, x3, tb(t + 0.5 * h), omega_b)
            x4 = [a + h * b for a, b in zip(x, k3)]
            k4 = self._rhs(t + h, x4, tb(t + h), omega_b)
            x = [a + h / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]
            t += h
        if not all(math.isfinite(v) for v in x):
            self.log(f"t = {current_time:g} s: hub state not finite", Fmi2Status.discard)
            return False
        self.x, self.t = x, current_time + step_size
        self._update_outputs(self.t, tb(self.t), omega_b)
        return True
