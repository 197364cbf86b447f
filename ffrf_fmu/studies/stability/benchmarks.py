"""The benchmarks the stability maps run by default, in one table with their provenance: the
scenes and ports of the bundled models the maps rely on and the maps' default sweeps. The map
code takes these as parameters (settings); only the defaults come from here.

Benchmarks: docs/background.md (B1 Wu-Haug spin-up, B2 spherical beam, B3 the spin-up
beyond the first bending frequency, B5 beam + hub drive); the maps and why these values:
docs/stability.md.
"""
from __future__ import annotations

from dataclasses import dataclass

#: B3: the spin map's default scene (models/haug_beam.toml: the Wu-Haug spin-up whose final rate
#: the map sweeps, drive port "hub", rotation.angle parameters omega and T)
SPIN_SCENE = "spinup_fast"

#: the integrator map's sweep per (body, scene), integrator.IntegratorSettings keywords: B1 spin-up
#: halved like the spin map (T = 7.5 s, 10 s), B2 cut after 20 s (torque 0-10 s, tip load 15-15.2 s,
#: 4.8 s of the 1.74 Hz vibration after it); converged steps 0.5 ms and 1 ms (docs/stability.md, section 2)
INTEGRATOR_DEFAULTS = {
    ("haug_beam", "spinup"): dict(steps=(1e-3, 2e-3, 5e-3, 0.01, 0.02, 0.05, 0.1, 0.2), converged_step=5e-4,
                                  duration=10.0, overrides=("scenes.spinup.drives.hub.rotation.angle.T=7.5",)),
    ("spherical_beam", "torque_then_tip"): dict(steps=(5e-3, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5), converged_step=1e-3,
                                                duration=20.0),
}


@dataclass(frozen=True)
class CoupledBeam:
    """What the co-simulation map takes from the beam's model file: the scene whose hub drive is
    the speed profile (a haug_spinup rotation of the hub port: omega, T), the scene with the hub
    rotation force-driven (the beam FMU of the motor case), and the end port names."""

    driven_scene: str
    free_scene: str
    hub: str
    tip: str


#: B5 and the split B1 (models/haug_beam.toml: scenes spinup and hub_free, ports hub and tip)
B5 = CoupledBeam("spinup", "hub_free", "hub", "tip")
