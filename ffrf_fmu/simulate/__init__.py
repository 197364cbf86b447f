"""Standalone runs: a scene's drives and loads as port inputs (inputs), the body stepped to the end
(loop), time series under the FMU's variable names and the files written from them (results), the
benchmark metrics computed from a result (quantities), its figure (plots), and the full-order
reference run as a result of the same shape (reference_run).

The names below are the package's public interface: `from ffrf_fmu import simulate as sim;
sim.run_scene(...)`."""
from .inputs import rule_error, scene_inputs, scene_schedule
from .loop import (InitializationFailure, Progress, build_system, free_body_state, record, run, run_input_rule,
                   run_scene, whole_steps)
from .plots import plot
from .quantities import (dominant_frequency, elastic_tip, end_ports, energy_balance, metrics, tip_from_cm,
                         tip_trajectory)
from .reference_run import run_reference
from .results import (ENERGIES, FREE_BODY_FIELDS, SimulationResult, column_names, free_body_columns,
                      free_body_keys, free_body_series, variable_names)

__all__ = [
    "ENERGIES", "FREE_BODY_FIELDS", "InitializationFailure", "Progress", "SimulationResult", "build_system",
    "column_names", "dominant_frequency", "elastic_tip", "end_ports", "energy_balance", "free_body_columns",
    "free_body_keys", "free_body_series", "free_body_state", "metrics", "plot", "record", "rule_error", "run",
    "run_input_rule", "run_reference", "run_scene", "scene_inputs", "scene_schedule", "tip_from_cm", "tip_trajectory", "variable_names",
    "whole_steps",
]
