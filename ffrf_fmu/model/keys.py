"""The model file's schema: each table's keys and what each expects (the text is used verbatim in the
messages of checked_toml.Reader), the `--set` aliases and the retired short keys."""
from __future__ import annotations

import re

from ..runtime.terms import FULL_TERMS, TERM_SETS
from .schema import METRIC_KINDS


# ---------------------------------------------------------------------------------------------
# Parsing. Each schema maps a key to what it expects; the text is used verbatim in messages.

TOP_KEYS = {"body": "a table [body]", "scenes": "a table of scenes [scenes.NAME]"}
BODY_KEYS = {
    "kind": "'beam' (default) or 'solid' (docs/model-format.md, solids)",
    "name": "a name of letters, digits and _ (default: the file name)",
    "length": "a positive length [m]",
    "origin": "3 numbers [m] (default [0, 0, 0])",
    "direction": "3 numbers, not all zero (default [1, 0, 0])",
    "superelements": "an integer >= 1",
    "elements_per_superelement": "an integer >= 2 (F_BB must be invertible: a superelement needs interior nodes)",
    "modes": "an integer >= 0 free-free modes per superelement",
    "section": "a table [body.section]",
    "ports": "a table of ports [body.ports.NAME]",
    "masses": "an array of point masses [[body.masses]]",
    "damping": "a table [body.damping] {ratio} (modal) or {alpha, beta} (Rayleigh): structural damping",
}
DAMPING_KEYS = {
    "ratio": "a damping ratio >= 0 for every mode, or an array of ratios >= 0, one per mode of a superelement's "
             "reduced model (6 x its boundary frames + its modes, by rising frequency)",
    "alpha": "a Rayleigh coefficient >= 0 on the mass [1/s] (default 0)",
    "beta": "a Rayleigh coefficient >= 0 on the stiffness [s] (default 0)",
}
MASS_KEYS = {
    "at": "a distance from the origin along the beam in [0, length] [m], on a node of the FE mesh",
    "mass": "a positive mass [kg]",
    "inertia": "3 non-negative moments of inertia [kg m^2] about the node, section axes 1, 2, 3 (default [0, 0, 0])",
}
SECTION_KEYS = {
    "EA": "a positive axial stiffness [N]",
    "GA2": "a positive shear stiffness [N] (omit GA2 and GA3 together for Euler-Bernoulli)",
    "GA3": "a positive shear stiffness [N] (omit GA2 and GA3 together for Euler-Bernoulli)",
    "GJ": "a positive torsional stiffness [N m^2]",
    "EI2": "a positive bending stiffness [N m^2]",
    "EI3": "a positive bending stiffness [N m^2]",
    "m": "a positive mass per length [kg/m]",
    "m22": "a non-negative rotary inertia per length [kg m]",
    "m33": "a non-negative rotary inertia per length [kg m]",
    "m11": "a positive torsional inertia per length [kg m] (default m22 + m33)",
}
PORT_KEYS = {
    "node": "a boundary node index 0..superelements (negative counts from the end)",
    "translation": "'motion', 'force' or 'compliant' (default 'force')",
    "rotation": "'motion', 'force' or 'compliant' (default 'force')",
    "coupling": "a table {step, stiffness, damping, rotational_stiffness, rotational_damping} for compliant parts",
}
COUPLING_KEYS = {
    "step": "a positive communication step [s]: stiffness and damping by the rule of docs/cosim.md",
    "stiffness": "3 numbers >= 0 [N/m], world axes",
    "damping": "3 numbers >= 0 [N s/m], world axes",
    "rotational_stiffness": "3 numbers >= 0 [N m/rad], nodal axes",
    "rotational_damping": "3 numbers >= 0 [N m s/rad], nodal axes",
}
SCENE_KEYS = {
    "duration": "a positive time [s]",
    "step": "a positive time step [s], at most the duration",
    "rho_inf": "a spectral radius in [0, 1] (default 0.8)",
    "terms": f"one of {', '.join(TERM_SETS)} (default linear)",
    "max_newton_iterations": "an integer >= 0: at most this many Newton iterations in a step, a step that needs more "
                             "fails (a hard real-time bound, docs/fmu.md 'Real-time datasheet'; default 0: no cap)",
    "stiffening": "true or false: geometric stiffening inside each superelement (default false)",
    "full_terms": f"an array of Witteveen's terms for terms = 'full', from {', '.join(FULL_TERMS)} (default all)",
    "gravity": "3 numbers [m/s^2] (default [0, 0, 0])",
    "metrics": f"a table [scenes.NAME.metrics] {{kind, primary, band_hz, min_window_s, coast_end_s}} or a kind "
               f"({', '.join(METRIC_KINDS)}) (default: none)",
    "outputs": "an array of probe names '<port>_from_<port>' (eq. 92; FMU outputs probe.NAME[i]) (default [])",
    "drives": "a table of drives [scenes.NAME.drives.PORT]",
    "loads": "an array of tables [[scenes.NAME.loads]]",
    "unbalances": "an array of tables [[scenes.NAME.unbalances]] {port, mass_eccentricity, drive, reference, phase}",
    "initial": "a table [scenes.NAME.initial]",
    "causality": "a table of causality overrides [scenes.NAME.causality.PORT]",
    "reference": "a table [scenes.NAME.reference] {elements, step}: the full-order reference that resolves "
                 "the primary metric",
}
REFERENCE_KEYS = {
    "elements": "a positive integer: elements of the reference beam, a multiple of the superelements",
    "step": "a positive time step [s] of the reference",
}
DRIVE_KEYS = {"rotation": "a table {axis, angle}", "translation": "a table {direction, displacement}"}
ROTATION_DRIVE_KEYS = {"axis": "3 numbers, not all zero", "angle": "a time function [rad]"}
TRANSLATION_DRIVE_KEYS = {"direction": "3 numbers, not all zero", "displacement": "a time function [m]"}
LOAD_KEYS = {
    "port": "a port name",
    "force": "3 numbers [N], world axes (default [0, 0, 0])",
    "moment": "3 numbers [N m], world axes (default [0, 0, 0])",
    "t_start": "a time [s] (default 0)",
    "t_end": "a time [s] after t_start (default inf)",
}
UNBALANCE_KEYS = {
    "port": "a port name (a force-driven translation: the node the unbalance mass sits on)",
    "mass_eccentricity": "a positive number m e [kg m]: unbalance mass times its radius",
    "drive": "a port name whose rotation drive gives the spin angle and axis",
    "reference": "3 numbers, not along the spin axis: where the mass points at angle 0 (default [0, 1, 0])",
    "phase": "an angle [rad] added to the drive's angle (default 0)",
}
METRICS_KEYS = {
    "kind": f"one of {', '.join(METRIC_KINDS)}",
    "primary": "one of the kind's metrics: the one whose relative error charts report and advise budgets",
    "band_hz": "2 frequencies 0 < low < high [Hz]: the band searched for the dominant vibration frequency",
    "min_window_s": "a time >= 0 [s]: the vibration fit needs at least this much time after its start (default 0)",
    "coast_end_s": "a positive time [s] (hub_rates): Omega_z is averaged from the end of the hub torque to here",
}
INITIAL_KEYS = {
    "velocity": "3 numbers [m/s] (default [0, 0, 0])",
    "angular_velocity": "3 numbers [rad/s] (default [0, 0, 0])",
    "port_displacements": "a table PORT = [dx, dy, dz] [m]",
    "state": 'one of "rest" (default), "static", "steady_spin"',
}
CAUSALITY_KEYS = {"translation": PORT_KEYS["translation"], "rotation": PORT_KEYS["rotation"]}
# Optional time-function parameters; every other parameter in drives.KINDS is required.
TIME_FUNCTION_DEFAULTS = {"sine": {"phase": 0.0}, "ramp": {"t_start": 0.0}}
# Short `--set` keys -> dotted paths; "scenes.*" means every scene.
OVERRIDE_ALIASES = {
    "superelements": ("body.superelements",),
    "elements_per_superelement": ("body.elements_per_superelement",),
    "modes": ("body.modes",),
    "length": ("body.length",),
    "rotary_inertia": ("body.section.m22", "body.section.m33"),
    **{k: (f"body.section.{k}",) for k in SECTION_KEYS},
    **{k: (f"scenes.*.{k}",) for k in ("duration", "step", "rho_inf", "terms", "gravity", "metrics", "stiffening", "full_terms",
                                            "max_newton_iterations")},
}

# Short keys refused, with what to write instead: `elements` meant the elements of each superelement
# here, the reference beam's total in [scenes.NAME.reference] and in the peers' sweeps
RETIRED_ALIASES = {
    "elements": "the short key `elements` is ambiguous (per superelement here, the whole beam for the reference "
                "and the peers): write elements_per_superelement=N for each superelement's FE elements, or "
                "scenes.NAME.reference.elements=N for the full-order reference beam",
}

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
