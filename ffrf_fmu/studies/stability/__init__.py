"""Stability and accuracy maps: where the models, the integrator and the co-simulation fail.

    ffrf-fmu stability MODEL --scene NAME --map spin|integrator|cosim [-o DIR] [--scheduler ...]

writes DIR/map.csv (one row per run), DIR/series.npz (the runs' tip deflection histories) and
DIR/map.png; the runs go through the sweep layer (common.py) and are kept in DIR's result store,
so a rerun repeats no finished run. docs/stability.md shows the maps that ship with the project
and explains every boundary.

- spin.py: final spin rate against (superelements, term set), and the steady-spin check;
- integrator.py: step size against rho_inf;
- cosim.py: communication step against coupling scheme, over the coupled systems of case.py
  (split.py cuts the beam in two, compliant_b5.py puts the B5 shaft into the beam FMU; tasks.py
  is what a worker runs of it);
- plots.py: the figures from the tables;
- benchmarks.py: the bundled benchmarks' scenes, ports and sweeps the maps use by default.

Definitions used by every map
-----------------------------
unstable  the run did not reach its end time in a meaningful state: the body integrator raised
          StepFailure (Newton did not converge, a non-finite value), or, for the beam maps, the
          transverse elastic tip deflection (eq. 92) exceeded the beam length L (a body that
          bends by more than its own length has left every model's range: it is diverging), or,
          for the integrator map, the integrator created energy (integrator.ENERGY_GROWTH).
error     the relative error of the quantity of interest against the reference of the map
          (nonlinear full-order beam, converged small-step run, monolithic run); defined per map.
"""
from ..sweep import SweepOptions
from .common import read_map
from .case import DRIVE, CosimCase, CosimRun, CosimSettings
from .cosim import cosim_map
from .benchmarks import B5, INTEGRATOR_DEFAULTS, SPIN_SCENE, CoupledBeam
from .integrator import IntegratorSettings, integrator_map, integrator_run
from .plots import PLOTS
from .spin import SpinSettings, reference_step, spin_map, spin_overrides, spin_scene, steady_spin
from .split import split_models

__all__ = ["B5", "SPIN_SCENE", "CoupledBeam", "SweepOptions", "read_map", "DRIVE", "CosimCase", "CosimRun", "CosimSettings", "cosim_map",
           "INTEGRATOR_DEFAULTS", "IntegratorSettings", "integrator_map", "integrator_run", "PLOTS", "SpinSettings",
           "reference_step", "spin_map", "spin_overrides", "spin_scene", "steady_spin", "split_models"]
