"""The pythonfmu slave that the example partner FMUs share (crank_pin_slave.py, piston_slave.py,
hub_drive_slave.py, road_profile_slave.py, spin_drive_slave.py): its parameters, the registration of
outputs and inputs, the time the experiment starts at, and the FMU state; and the Wu-Haug spin-up law
the drives follow (`haug_spinup`).

A partner names its parameters in PARAMETERS {name: (default, unit, description)}: fixed FMU
parameters, held in self.p. Its FMU state is the JSON copy of the attributes STATE names (self.p and
self.t always), so getting, setting and serializing the state are one rule for every partner.

Only the standard library and pythonfmu are imported: examples.build_script_fmu ships this file in
the FMU beside the partner's script, renamed with a digest of both (pythonfmu FMUs whose scripts share
a name collide in one process, docs/fmu.md).
"""
import json
import math

from pythonfmu import Fmi2Slave, Real
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability


def haug_spinup(t, omega, T):
    """(psi, psi', psi'') of the Wu-Haug spin-up to omega over T (docs/background.md B1; the model format's
    `kind = "haug_spinup"`, runtime/drives.py, repeated here for the FMUs' standard-library-only scripts:
    tests/test_rotor_system.py checks the two agree), at rest before t = 0:
        psi = omega T (tau^2/2 + (cos 2 pi tau - 1)/(2 pi)^2),  tau = t/T < 1;  omega T (t/T - 1/2) after."""
    t = max(t, 0.0)
    if t < T:
        tau, two_pi = t / T, 2.0 * math.pi
        return (omega * T * (tau**2 / 2.0 + (math.cos(two_pi * tau) - 1.0) / two_pi**2),
                omega * (tau - math.sin(two_pi * tau) / two_pi), (omega / T) * (1.0 - math.cos(two_pi * tau)))
    return omega * T * (t / T - 0.5), omega, 0.0


class PartnerSlave(Fmi2Slave):
    """A partner FMU: subclasses set DESCRIPTION, PARAMETERS, EXPERIMENT (start, stop, step) and STATE."""

    author = "ffrf-fmu"
    DESCRIPTION = ""
    PARAMETERS: dict = {}
    EXPERIMENT = (0.0, 1.0, 1e-3)
    STATE = ("p", "t")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = self.DESCRIPTION
        start, stop, step = self.EXPERIMENT
        self.default_experiment = DefaultExperiment(start_time=start, stop_time=stop, step_size=step)
        self.p = {k: v[0] for k, v in self.PARAMETERS.items()}
        self.t = 0.0
        for name, (default, unit, desc) in self.PARAMETERS.items():
            self.register_variable(
                Real(name, start=default, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                     initial=Fmi2Initial.exact, description=f"{desc} [{unit}]",
                     getter=lambda n=name: self.p[n], setter=lambda v, n=name: self.p.__setitem__(n, float(v))),
                nested=False)

    def output(self, name, description, getter, start=None):
        """A continuous output, exact at its start value (getter() at registration when start is None)."""
        self.register_variable(
            Real(name, causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                 initial=Fmi2Initial.exact, start=getter() if start is None else start, description=description,
                 getter=getter), nested=False)

    def input(self, name, description, values, index, start=0.0):
        """A continuous input: component `index` of the list `values` (an attribute of the slave)."""
        self.register_variable(
            Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous, start=start,
                 description=description, getter=lambda: getattr(self, values)[index],
                 setter=lambda v: getattr(self, values).__setitem__(index, float(v))), nested=False)

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self.t = float(start_time)

    def _get_fmu_state(self):
        return json.loads(json.dumps({k: getattr(self, k) for k in self.STATE}))

    def _set_fmu_state(self, state):
        for k, v in json.loads(json.dumps(state)).items():
            setattr(self, k, v)

    @staticmethod
    def _fmu_state_to_bytes(state):
        return json.dumps(state).encode("utf-8")

    @staticmethod
    def _fmu_state_from_bytes(state):
        return json.loads(state.decode("utf-8"))
