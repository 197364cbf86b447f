"""pythonfmu script of the spin drive FMU: a prescribed spin-up about a fixed axis with a rotating
unbalance, the partner of a rotor FMU whose drive port and bearings are `compliant`
(models/jeffcott_runup.toml: the torsional drive spring and the bearings inside the rotor FMU).

The drive angle follows the Wu-Haug spin-up to `profile.omega` over `profile.T` (the model format's
`kind = "haug_spinup"`, runtime/drives.py; partner_slave.haug_spinup, so that the FMU needs only the
standard library and pythonfmu: tests/test_rotor_system.py checks the two agree) about the world X axis:
    psi(t),  R = rotation about X by psi,  w = (psi', 0, 0),  dw = (psi'', 0, 0),
the motion inputs `drive.R`, `drive.w`, `drive.dw` of the rotor's driven port (dw for its
second-order extrapolation, docs/fmu.md). The unbalance m e on the disc, at angle 0 along +Y
(`[[scenes.NAME.unbalances]]`, docs/model-format.md), loads it with the inertia force
    f = m e (psi'^2 rho - psi'' tau),  rho = (0, cos psi, sin psi),  tau = (0, -sin psi, cos psi),
output `unbalance.f[i]` (world axes) for the disc's force input. The rotor holds force inputs over a
step (docs/fmu.md), so the co-simulated unbalance lags the standalone one by one communication step:
a phase lag psi' H that moves the whirl's phase, not its amplitude envelope.

Built by `ffrf_fmu.examples.build_spin_drive` (module and class renamed with a digest of this file;
partner_slave.py, the slave the partners share, shipped beside it). Outputs are
the values at the end of the step; no inputs.
"""
import math

from ffrf_fmu.examples.partner_slave import PartnerSlave, haug_spinup

PARAMETERS = {
    # name: (default, unit, description)
    "profile.omega": (340.0, "rad/s", "final spin rate of the Wu-Haug spin-up"),
    "profile.T": (10.0, "s", "spin-up time of the Wu-Haug spin-up"),
    "unbalance.me": (5.5504e-4, "kg.m", "unbalance mass times its eccentricity"),
}


class SpinDrive(PartnerSlave):

    DESCRIPTION = ("Prescribed Wu-Haug spin-up about world X (drive.R, drive.w, drive.dw) and the inertia force of a "
                   "rotating unbalance m e at angle 0 along +Y (unbalance.f, world axes). Outputs at the step end; "
                   "no inputs.")
    PARAMETERS = PARAMETERS
    EXPERIMENT = (0.0, 10.0, 5e-4)
    STATE = ("p", "t", "psi")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.psi = (0.0, 0.0, 0.0)
        out = self.output
        for i in range(3):
            for j in range(3):
                out(f"drive.R[{i + 1},{j + 1}]", "drive frame: world component i of axis j",
                    lambda a=i, b=j: self._R()[3 * a + b], 1.0 if i == j else 0.0)
        for i in range(3):
            out(f"drive.w[{i + 1}]", "drive angular velocity, world axes [rad/s]", lambda k=i: self.psi[1] if k == 0 else 0.0,
                0.0)
        for i in range(3):
            out(f"drive.dw[{i + 1}]", "drive angular acceleration, world axes [rad/s2]",
                lambda k=i: self.psi[2] if k == 0 else 0.0, 0.0)
        for i in range(3):
            out(f"unbalance.f[{i + 1}]", "inertia force of the unbalance on the disc, world axes [N]",
                lambda k=i: self._force()[k], 0.0)
        out("drive.angle", "drive angle [rad]", lambda: self.psi[0], 0.0)
        out("drive.speed", "drive speed [rad/s]", lambda: self.psi[1], 0.0)

    def _R(self):
        c, s = math.cos(self.psi[0]), math.sin(self.psi[0])
        return [1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c]

    def _force(self):
        psi, d, dd = self.psi
        me, c, s = self.p["unbalance.me"], math.cos(psi), math.sin(psi)
        return [0.0, me * (d * d * c + dd * s), me * (d * d * s - dd * c)]

    def exit_initialization_mode(self):
        self.psi = haug_spinup(self.t, self.p["profile.omega"], self.p["profile.T"])

    def do_step(self, current_time, step_size):
        self.t = current_time + step_size
        self.psi = haug_spinup(self.t, self.p["profile.omega"], self.p["profile.T"])
        return True
