"""Model files: a body (beam, superelements, ports) and named scenes, as frozen dataclasses.

The TOML format is documented in docs/model-format.md; `load_model` parses, applies
`--set key=value` overrides and validates, raising `ModelError` that names the file, the key
and what was expected (the checked reading itself is checked_toml.py). Over 400 lines: the
dataclasses, the key tables and the parser of one file format stay together, each key's
meaning next to the check that reads it.
"""
from __future__ import annotations

import dataclasses
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from .checked_toml import REQUIRED, ModelError, Reader, apply_overrides, join, nearest, nonnegative, positive, toml_text
from .runtime.damping import Damping, per_mode_ratios
from .section import Section  # noqa: F401  (model.Section: the body's section, as it always was)
from .runtime.drives import KINDS as TIME_FUNCTION_KINDS
from .runtime.terms import FULL_TERMS, TERM_SETS

PART_CAUSALITIES = ("motion", "force", "compliant")
# metric kind -> the summary metrics it computes (simulate.metrics); "{coast_end_s}" is filled in
METRIC_KINDS = {
    "tip_deflection": ("tip_deflection_max_m", "tip_axial_at_max_m", "t_at_max_s", "oscillation_frequency_hz",
                       "tip_in_plane_max_m", "tip_out_of_plane_max_m", "in_plane_frequency_hz", "out_of_plane_frequency_hz"),
    "hub_rates": ("omega_z_at_{coast_end_s}s", "omega_y_mean_after_load", "tip_frequency_hz", "hub_rotation_vector_end",
                  "t_end_s"),
    "momentum": ("linear_momentum_drift_rel", "angular_momentum_drift_rel", "total_energy_drift_rel", "tip_from_cm_max_m",
                 "tip_from_cm_rms_m", "tip_from_cm_frequency_hz"),
}
OLD_METRIC_NAMES = {"haug": "tip_deflection", "spherical": "hub_rates", "free": "momentum"}
PART_INDEX = {"translation": 0, "rotation": 1}  # position of a part in (translation, rotation) pairs


@dataclass(frozen=True)
class Port:
    """A named boundary node of the body and the causality of its two parts (docs/fmu.md)."""

    name: str
    node: int  # boundary node index 0..superelements (negative counts from the end), normalized >= 0
    translation: str  # "motion" | "force" | "compliant"
    rotation: str  # "motion" | "force" | "compliant"
    coupling: tuple = ()  # compliant parts: (key, value) pairs of the port's `coupling` table


@dataclass(frozen=True)
class PointMass:
    """A rigid body lumped at a node of the FE mesh (docs/model-format.md, [[body.masses]]): its mass
    at the node and its inertia about the node, diagonal in the section axes 1, 2, 3."""

    at: float  # distance from the body origin along the beam [m]; an FE node
    mass: float  # [kg]
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [kg m^2] about section axes 1, 2, 3


@dataclass(frozen=True)
class SolidFrame:
    """A solid's port frame (docs/model-format.md, solids): its node selection (solid/frames.py) as
    canonical JSON (hashable), the link of the set to the frame, and its origin (None: the set's centroid)."""

    port: str
    select: str  # JSON of the selection table, e.g. {"near": {"set": "BCleft", "radius": 0.08}}
    link: str  # "rigid" (RBE2) | "averaging" (RBE3)
    point: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class SolidSpec:
    """[body] kind = "solid" (docs/model-format.md): where K and M come from and how it is reduced.

    source "mesh": a mesh (a file read with meshio, or a generated box/cylinder) assembled with
    scikit-fem from the material; "abaqus"/"ansys": a partner's exported matrices, read as they are;
    "calculix": a deck whose matrices ccx assembles (solid/calculix_engine.py); "nastran": a bulk data deck
    assembled here (solid/nastran_body.py)."""

    source: str  # "mesh" | "abaqus" | "ansys" | "calculix" | "nastran"
    files: tuple[tuple[str, str], ...] = ()  # (role, absolute path): mesh | inp, stiffness, mass | mapping, nodes, elements
    generated: tuple[tuple[str, Any], ...] = ()  # ("box"|"cylinder", parameters as sorted pairs), when no mesh file
    element: str = ""  # hex8 | hex20 | hex27 | tet4 | tet10 | mitc4 (mesh only; mitc4: shells, SHELL_ELEMENTS)
    material: tuple[float, float, float] | None = None  # E [Pa], nu, rho [kg/m^3] (mesh only)
    cutoff_hz: float | None = None  # keep every free-free mode up to this frequency (besides or instead of modes)
    frames: tuple[SolidFrame, ...] = ()
    units: str = ""  # the units assumed for an export (stated in the model file)
    thickness: float | str | None = None  # shell thickness [m], or the mesh file's cell data field of it (shells only)


@dataclass(frozen=True)
class Body:
    name: str
    length: float
    origin: tuple[float, float, float]
    direction: tuple[float, float, float]  # unit vector of the beam axis (local axis 1)
    section: Section
    superelements: int
    elements_per_superelement: int
    modes: int  # free-free vibration modes kept per superelement
    ports: tuple[Port, ...]
    source: str = ""  # file the body came from (for messages)
    masses: tuple[PointMass, ...] = ()  # point masses at FE nodes
    solid: "SolidSpec | None" = None  # kind = "solid": its mesh or export and frames (section is then None)
    damping: Damping | None = None  # structural damping [body.damping] (runtime/damping.py), None: undamped

    def port(self, name: str) -> Port:
        for p in self.ports:
            if p.name == name:
                return p
        raise ModelError(f"{self.source}: no port named {name!r} (ports: {[p.name for p in self.ports]})")


@dataclass(frozen=True)
class TimeFunction:
    """A scalar time function s(t) with its first two derivatives (see drives.py for kinds).

    kind: "constant" (value), "haug_spinup" (omega, T: angle profile of Wu-Haug, docs/background.md B1),
    "ramp" (rate, t_start), "window" (value, t_start, t_end: value inside [t_start, t_end), else 0),
    "sine" (amplitude, frequency_hz, phase), "bump" (value, t_start, duration: value sin^4(pi tau),
    tau = (t - t_start) / duration in [0, 1), else 0: a road bump, smooth to the acceleration).
    """

    kind: str
    params: tuple[tuple[str, float], ...]  # sorted (name, value) pairs, hashable


@dataclass(frozen=True)
class RotationDrive:
    """Prescribed rotation of a motion-driven port about a fixed world axis: R = exp(phi(t) axis) R_ref."""

    axis: tuple[float, float, float]
    angle: TimeFunction


@dataclass(frozen=True)
class TranslationDrive:
    """Prescribed displacement of a motion-driven port from its reference position: r = r_ref + u(t) e."""

    direction: tuple[float, float, float]
    displacement: TimeFunction


@dataclass(frozen=True)
class Drive:
    port: str
    rotation: RotationDrive | None = None  # None: fixed at the reference orientation
    translation: TranslationDrive | None = None  # None: fixed at the reference position


@dataclass(frozen=True)
class Load:
    """A force and/or moment (world axes) on a force-driven port part, scaled by a time function."""

    port: str
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    moment: tuple[float, float, float] = (0.0, 0.0, 0.0)
    t_start: float = 0.0
    t_end: float = float("inf")


@dataclass(frozen=True)
class Unbalance:
    """A rotating unbalance on a force-driven port translation ([[scenes.NAME.unbalances]]): a point mass m at
    radius e from the spin axis, at the angle psi = phi(t) + phase of the rotation drive of port `drive`
    (angle phi, axis a). Its inertia force on the body, world axes, is
    f = m e (psi'^2 rho - psi'' tau) with rho = cos psi e1 + sin psi e2, tau = a x rho, where e1 is the
    unit part of `reference` normal to a and e2 = a x e1 (the mass's acceleration is -e psi'^2 rho +
    e psi'' tau). The mass itself is not added to the body (give it in [[body.masses]])."""

    port: str
    mass_eccentricity: float  # m e [kg m]
    drive: str  # the port whose rotation drive gives phi(t) and the axis a
    reference: tuple[float, float, float] = (0.0, 1.0, 0.0)  # direction of the mass at psi = 0 (world)
    phase: float = 0.0  # [rad]


@dataclass(frozen=True)
class Initial:
    """Initial state: rigid velocity field v + w x (X - origin) of the whole body; port offsets."""

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    port_displacements: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    state: str = "rest"  # INITIAL_STATES: where the body starts (initial_state.py)


INITIAL_STATES = ("rest", "static", "steady_spin")


@dataclass(frozen=True)
class Metrics:
    """The summary metrics of a scene ([scenes.NAME.metrics], docs/model-format.md): which kind
    (METRIC_KINDS), the primary one (whose relative error charts report and advise budgets), and
    the benchmark's own numbers (windows and frequency bands) that the kind needs."""

    kind: str = ""  # "" (none) or a METRIC_KINDS key
    primary: str = ""  # one of the kind's metrics, or "" (none)
    band_hz: tuple[float, float] | None = None  # band searched for the dominant vibration frequency
    min_window_s: float = 0.0  # the vibration fit needs at least this much time after its start
    coast_end_s: float | None = None  # hub_rates: Omega_z averaged from the end of the hub torque to here

    def names(self) -> tuple[str, ...]:
        """The metrics this kind computes (their names)."""
        end = f"{self.coast_end_s:g}" if self.coast_end_s is not None else "T"
        return tuple(n.format(coast_end_s=end) for n in METRIC_KINDS.get(self.kind, ()))


@dataclass(frozen=True)
class ReferenceOptions:
    """[scenes.NAME.reference]: the full-order reference that resolves the scene's primary metric, the
    default of `chart`, `advise --check` and `stability` (their --reference-elements/--reference-step
    override it). None: the tools' own default (elements max(16, 4 x superelements), the scene's step)."""

    elements: int | None = None
    step: float | None = None


@dataclass(frozen=True)
class Scene:
    name: str
    duration: float
    step: float
    rho_inf: float
    terms: str  # "linear" | "gyroscopic"
    gravity: tuple[float, float, float]
    drives: tuple[Drive, ...]
    loads: tuple[Load, ...]
    initial: Initial
    causality: tuple[tuple[str, str, str], ...] = ()  # (port, translation, rotation) overrides
    metrics: Metrics = Metrics()  # which summary metrics apply (simulate.metrics)
    outputs: tuple[str, ...] = ()  # extra probes, e.g. "tip_from_hub"
    stiffening: bool = False  # geometric stiffening inside each superelement (docs/equations.md)
    full_terms: tuple[str, ...] = FULL_TERMS  # Witteveen's terms on in the term set `full`
    reference: ReferenceOptions = ReferenceOptions()  # the reference that resolves the primary metric
    unbalances: tuple[Unbalance, ...] = ()  # rotating unbalance forces ([[scenes.NAME.unbalances]])


@dataclass(frozen=True)
class Model:
    body: Body
    scenes: tuple[Scene, ...]
    path: str = ""

    def scene(self, name: str | None = None) -> Scene:
        if name is None:
            return self.scenes[0]
        for s in self.scenes:
            if s.name == name:
                return s
        raise ModelError(f"{self.path}: no scene named {name!r} (scenes: {[s.name for s in self.scenes]})")


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
    **{k: (f"scenes.*.{k}",) for k in ("duration", "step", "rho_inf", "terms", "gravity", "metrics", "stiffening", "full_terms")},
}

# Short keys refused, with what to write instead: `elements` meant the elements of each superelement
# here, the reference beam's total in [scenes.NAME.reference] and in the peers' sweeps
RETIRED_ALIASES = {
    "elements": "the short key `elements` is ambiguous (per superelement here, the whole beam for the reference "
                "and the peers): write elements_per_superelement=N for each superelement's FE elements, or "
                "scenes.NAME.reference.elements=N for the full-order reference beam",
}

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def load_model(path, overrides: Sequence[str] = ()) -> Model:
    """Read a TOML model file, apply `--set key=value` overrides, validate, return a Model."""
    file = str(path)
    try:
        raw = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as e:
        raise ModelError(f"{file}: cannot read the model file: {e.strerror or e}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ModelError(f"{file}: not valid TOML: {e}") from None
    r = Reader(file, apply_overrides(raw, overrides, file, OVERRIDE_ALIASES, RETIRED_ALIASES))
    r.table(raw, "", TOP_KEYS, required=("body", "scenes"))
    default_name = re.sub(r"\W", "_", Path(path).stem)
    body = _parse_body(r, raw["body"], default_name if _NAME.match(default_name) else "body", file)
    scenes = r.table(raw["scenes"], "scenes", None)
    if not scenes:
        r.fail("scenes", "expected at least one scene table [scenes.NAME]")
    return Model(body, tuple(_parse_scene(r, body, name, t) for name, t in scenes.items()), file)


def _parse_body(r: Reader, t: Any, default_name: str, file: str) -> Body:
    b = "body"
    kind = r.string(r.table(t, b, None), b, "kind", BODY_KEYS["kind"], "beam", ("beam", "solid"))
    if kind == "solid":
        return _parse_solid(r, t, default_name, file)
    r.table(t, b, BODY_KEYS, required=("length", "superelements", "elements_per_superelement", "modes", "section"))
    name = r.string(t, b, "name", BODY_KEYS["name"], default_name)
    if not _NAME.match(name):  # becomes part of FMU and variable names
        r.expected(join(b, "name"), BODY_KEYS["name"], name)
    n_se = r.integer(t, b, "superelements", BODY_KEYS["superelements"], low=1)
    n_el = r.integer(t, b, "elements_per_superelement", BODY_KEYS["elements_per_superelement"], low=2)
    modes = r.integer(t, b, "modes", BODY_KEYS["modes"], low=0)
    if modes > 6 * (n_el - 1):  # the modal columns of Y live on the interior dofs (eq. 76)
        r.fail(join(b, "modes"), f"expected at most 6 * (elements_per_superelement - 1) = {6 * (n_el - 1)} "
               f"(interior dofs of a superelement), got {modes}")

    s, st = "body.section", t["section"]
    r.table(st, s, SECTION_KEYS, required=("EA", "GJ", "EI2", "EI3", "m", "m22", "m33"))
    vals = {k: r.real(st, s, k, SECTION_KEYS[k], None, ok=nonnegative if k in ("m22", "m33") else positive)
            for k in SECTION_KEYS}
    if (vals["GA2"] is None) != (vals["GA3"] is None):
        missing = "GA3" if vals["GA3"] is None else "GA2"
        r.fail(join(s, missing), "missing; expected GA2 and GA3 together (Timoshenko) or neither (Euler-Bernoulli)")
    if vals["m11"] is None and vals["m22"] + vals["m33"] == 0.0:
        r.fail(join(s, "m11"), "missing; expected a positive torsional inertia when m22 = m33 = 0")

    ports = []
    pt = r.table(t.get("ports", {}), "body.ports", None)
    for pname, p in pt.items():
        pp = join("body.ports", pname)
        if not _NAME.match(pname):  # becomes an FMU variable prefix (docs/fmu.md)
            r.fail(pp, "expected a port name of letters, digits and _ (it prefixes FMU variable names)")
        r.table(p, pp, PORT_KEYS, required=("node",))
        node = r.integer(p, pp, "node", PORT_KEYS["node"], low=-math.inf)
        if not -n_se - 1 <= node <= n_se:
            r.fail(join(pp, "node"), f"expected a boundary node in 0..{n_se} (or -{n_se + 1}..-1 from the end) "
                   f"for {n_se} superelements, got {node}")
        node = node % (n_se + 1)
        for other in ports:
            if other.node == node:
                r.fail(join(pp, "node"), f"expected a node without a port, but port {other.name!r} is on node {node}")
        tr = r.string(p, pp, "translation", PORT_KEYS["translation"], "force", PART_CAUSALITIES)
        rot = r.string(p, pp, "rotation", PORT_KEYS["rotation"], "force", PART_CAUSALITIES)
        ports.append(Port(pname, node, tr, rot, _port_coupling(r, p, pp, tr, rot)))

    length = r.real(t, b, "length", BODY_KEYS["length"], ok=positive)
    masses = []
    mt = t.get("masses", [])
    if not isinstance(mt, list):
        r.expected(join(b, "masses"), BODY_KEYS["masses"], mt)
    h = length / (n_se * n_el)  # FE element length
    for i, pm in enumerate(mt):
        mp = join(join(b, "masses"), str(i))
        r.table(pm, mp, MASS_KEYS, required=("at", "mass"))
        at = r.real(pm, mp, "at", MASS_KEYS["at"], ok=lambda x: 0.0 <= x <= length)
        if abs(at / h - round(at / h)) > 1e-9 * max(1.0, at / h):
            r.fail(join(mp, "at"), f"expected a node of the FE mesh (a multiple of length / (superelements * "
                   f"elements_per_superelement) = {h:g} m), got {at!r}")
        inertia = r.vec3(pm, mp, "inertia", MASS_KEYS["inertia"], (0.0, 0.0, 0.0))
        if min(inertia) < 0.0:
            r.expected(join(mp, "inertia"), MASS_KEYS["inertia"], list(inertia))
        masses.append(PointMass(round(at / h) * h, r.real(pm, mp, "mass", MASS_KEYS["mass"], ok=positive), inertia))

    return Body(
        name=name,
        length=length,
        origin=r.vec3(t, b, "origin", BODY_KEYS["origin"], (0.0, 0.0, 0.0)),
        direction=r.vec3(t, b, "direction", BODY_KEYS["direction"], (1.0, 0.0, 0.0), unit=True),
        section=Section(**vals),
        superelements=n_se,
        elements_per_superelement=n_el,
        modes=modes,
        ports=tuple(ports),
        source=file,
        masses=tuple(masses),
        damping=_parse_damping(r, t),
    )


def _parse_damping(r: Reader, t: dict) -> Damping | None:
    """[body.damping]: modal ratios (one for all modes or one per mode) or Rayleigh's alpha, beta, not
    both. The length of a list is checked against the reduced model by `body_damping`."""
    if "damping" not in t:
        return None
    dp = "body.damping"
    dt = r.table(t["damping"], dp, DAMPING_KEYS)
    if not dt:
        r.fail(dp, "expected ratio = ZETA (modal damping) or alpha, beta (Rayleigh damping)")
    if "ratio" in dt and ("alpha" in dt or "beta" in dt):
        r.fail(dp, "expected either ratio (modal damping) or alpha and beta (Rayleigh damping), not both")
    if "ratio" not in dt:
        return Damping((), r.real(dt, dp, "alpha", DAMPING_KEYS["alpha"], 0.0, ok=nonnegative),
                       r.real(dt, dp, "beta", DAMPING_KEYS["beta"], 0.0, ok=nonnegative))
    z = dt["ratio"]
    ratios = z if isinstance(z, list) else [z]
    if not ratios or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x >= 0
                             for x in ratios):
        r.expected(join(dp, "ratio"), DAMPING_KEYS["ratio"], z)
    return Damping(tuple(float(x) for x in ratios))


def body_damping(body: Body, n: int) -> Damping | None:
    """The body's damping for superelements of n reduced dofs: a list of ratios must have n of them
    (ModelError naming the file and key otherwise)."""
    if body.damping is not None:
        try:
            per_mode_ratios(body.damping, n)
        except ValueError as e:
            raise ModelError(f"{body.source}: body.damping.ratio: {e}") from None
    return body.damping


SOLID_KEYS = {
    "kind": BODY_KEYS["kind"],
    "name": BODY_KEYS["name"],
    "superelements": "1: a solid is one superelement",
    "modes": "an integer >= 0: the free-free modes kept (or cutoff_hz)",
    "cutoff_hz": "a positive frequency [Hz]: keep every free-free mode up to it (or modes)",
    "mesh": "a table [body.mesh] {file | box | cylinder | plate, element, thickness (shells)}",
    "material": "a table [body.material] {E, nu, rho}",
    "export": "a table [body.export] {format, files..., units}",
    "ports": "a table of ports [body.ports.NAME] {select, link, point, translation, rotation, coupling}",
    "damping": BODY_KEYS["damping"],
}
MESH_KEYS = {
    "file": "a mesh file read with meshio (Gmsh .msh, Abaqus .inp, VTK, ...), relative to the model file",
    "box": "a table {size = [lx, ly, lz] m, divisions = [nx, ny, nz], origin = [x, y, z] m}",
    "cylinder": "a table {radius m, length m, radial = cells across a radius, axial = cells along, origin} (along +Z)",
    "plate": "a table {size = [lx, ly] m, divisions = [nx, ny], origin = [x, y, z] m} (shells in the XY plane)",
    "element": "one of hex8, hex20, hex27, tet4, tet10 (hex8 and tet4 lock in bending: docs/solids.md) or the "
               "shell mitc4 (docs/shells.md)",
    "thickness": "a positive shell thickness [m], or {cell_data = NAME}: the mesh file's cell data field of the "
                 "thickness of each quad [m] (shell elements only)",
}
SOLID_ELEMENTS = ("hex8", "hex20", "hex27", "tet4", "tet10")
SHELL_ELEMENTS = ("mitc4",)
MATERIAL_KEYS = {"E": "a positive Young's modulus [Pa]", "nu": "a Poisson's ratio in [0, 0.5)",
                 "rho": "a positive density [kg/m^3]"}
EXPORT_KEYS = {
    "format": "'abaqus' (*MATRIX OUTPUT .mtx + .inp), 'ansys' (Matrix Market + dof mapping + node table) or "
              "'calculix' (a CalculiX/Abaqus deck assembled by ccx: solid/calculix_engine.py) or 'nastran' (a "
              "Nastran bulk data deck read with pyNastran: solid/nastran_body.py)",
    "deck": "the Nastran bulk data deck (.bdf, .dat; its INCLUDEs beside it)",
    "inp": "the Abaqus or CalculiX input deck (.inp): nodes and node sets",
    "stiffness": "the exported stiffness matrix file",
    "mass": "the exported mass matrix file",
    "mapping": "the Ansys dof mapping vector file (Matrix Market)",
    "nodes": "the Ansys node table (number, X, Y, Z)",
    "elements": "the Ansys element table (optional: cells for VTK output)",
    "units": "a text stating the units assumed (the files do not say)",
}
EXPORT_FILES = {"abaqus": ("inp", "stiffness", "mass"), "ansys": ("stiffness", "mass", "mapping", "nodes"),
                "calculix": ("inp",), "nastran": ("deck",)}
SOLID_PORT_KEYS = {
    "select": "a node selection table: {set = NAME} | {plane = {point, normal, tol}} | {cylinder = {point, axis, "
              "radius, tol}} | {box = {min, max}} | {near = {point | set, radius}}",
    "link": "'rigid' (RBE2: the set moves rigidly with the frame) or 'averaging' (RBE3: the frame follows the set's "
            "mean motion) (default 'rigid')",
    "point": "3 numbers [m]: the frame origin (default: the centroid of the selected nodes)",
    "translation": PORT_KEYS["translation"],
    "rotation": PORT_KEYS["rotation"],
    "coupling": PORT_KEYS["coupling"],
}


def _port_coupling(r: Reader, p: dict, pp: str, tr: str, rot: str) -> tuple:
    coupling = ()
    if "coupling" in p:
        cp = join(pp, "coupling")
        c = r.table(p["coupling"], cp, COUPLING_KEYS)
        cvals = {}
        if "step" in c:
            cvals["step"] = r.real(c, cp, "step", COUPLING_KEYS["step"], ok=positive)
        for key in ("stiffness", "damping", "rotational_stiffness", "rotational_damping"):
            if key in c:
                v = r.vec3(c, cp, key, COUPLING_KEYS[key])
                if min(v) < 0.0:
                    r.fail(join(cp, key), f"expected {COUPLING_KEYS[key]}, got {list(v)}")
                cvals[key] = v
        coupling = tuple(cvals.items())
    if "compliant" in (tr, rot) and not coupling:
        r.fail(pp, "a compliant part needs a coupling table: {step = H} (the rule of docs/cosim.md) or explicit "
               "stiffness/damping values")
    return coupling


def _frozen(v):
    """TOML values as hashable tuples (tables as sorted pairs)."""
    if isinstance(v, dict):
        return tuple(sorted((k, _frozen(x)) for k, x in v.items()))
    if isinstance(v, list):
        return tuple(_frozen(x) for x in v)
    return v


def _parse_solid(r: Reader, t: dict, default_name: str, file: str) -> Body:
    """[body] kind = "solid": a mesh + material or an export, ports as frames on node sets (SolidSpec)."""
    import json

    b = "body"
    r.table(t, b, SOLID_KEYS, required=("ports",))
    name = r.string(t, b, "name", SOLID_KEYS["name"], default_name)
    if not _NAME.match(name):
        r.expected(join(b, "name"), SOLID_KEYS["name"], name)
    n_se = r.integer(t, b, "superelements", SOLID_KEYS["superelements"], 1, low=1)
    if n_se != 1:
        r.fail(join(b, "superelements"), f"a solid is one superelement (its frames are its boundary), got {n_se}; "
               "split a solid into parts as separate bodies")
    modes = r.integer(t, b, "modes", SOLID_KEYS["modes"], 0, low=0)
    cutoff = r.real(t, b, "cutoff_hz", SOLID_KEYS["cutoff_hz"], None, ok=positive) if "cutoff_hz" in t else None
    if ("modes" in t) == (cutoff is not None):
        r.fail(b, "expected one of modes = N or cutoff_hz = F (which free-free modes to keep)")
    base = Path(file).parent
    if ("mesh" in t) == ("export" in t):
        r.fail(b, "expected exactly one of [body.mesh] (with [body.material]) or [body.export]")
    files, generated, element, material, units, thickness = [], (), "", None, "", None
    if "mesh" in t:
        mp = join(b, "mesh")
        mt = r.table(t["mesh"], mp, MESH_KEYS, required=("element",))
        element = r.string(mt, mp, "element", MESH_KEYS["element"], choices=SOLID_ELEMENTS + SHELL_ELEMENTS)
        shell = element in SHELL_ELEMENTS
        given = [k for k in ("file", "box", "cylinder", "plate") if k in mt]
        if len(given) != 1:
            r.fail(mp, f"expected exactly one of file, box, cylinder, plate, got {given or 'none'}")
        if shell != ("thickness" in mt):
            r.fail(mp, f"a shell mesh (element {SHELL_ELEMENTS}) needs thickness = T [m], a solid one has none"
                   + (f" (element {element!r})" if not shell else ""))
        if shell and given[0] in ("box", "cylinder"):
            r.fail(join(mp, given[0]), f"element {element!r} is a shell: generate a plate, or give a file of quads")
        if not shell and given[0] == "plate":
            r.fail(join(mp, "plate"), f"a plate is meshed with shells (element one of {SHELL_ELEMENTS}), not {element!r}")
        thickness = None
        if shell and isinstance(mt["thickness"], dict):
            tt = r.table(mt["thickness"], join(mp, "thickness"), {"cell_data": "the name of a cell data field"},
                         required=("cell_data",))
            if "file" not in mt:
                r.fail(join(mp, "thickness"), "a thickness from cell data needs a mesh file")
            thickness = r.string(tt, join(mp, "thickness"), "cell_data", "the name of a cell data field")
        elif shell:
            thickness = r.real(mt, mp, "thickness", MESH_KEYS["thickness"], ok=positive)
        if "file" in mt:
            f = base / r.string(mt, mp, "file", MESH_KEYS["file"])
            if not f.is_file():
                r.fail(join(mp, "file"), f"no such file: {f}")
            files.append(("mesh", str(f)))
        else:
            kind = given[0]
            gp = join(mp, kind)
            if kind == "box":
                gt = r.table(mt[kind], gp, {"size": "3 positive lengths [m]", "divisions": "3 integers >= 1",
                                             "origin": "3 numbers [m] (default [0, 0, 0])"}, required=("size", "divisions"))
                size = r.vec3(gt, gp, "size", "3 positive lengths [m]")
                div = gt["divisions"]
                if min(size) <= 0:
                    r.expected(join(gp, "size"), "3 positive lengths [m]", list(size))
                if not (isinstance(div, list) and len(div) == 3 and all(isinstance(x, int) and x >= 1 for x in div)):
                    r.expected(join(gp, "divisions"), "3 integers >= 1", div)
                params = {"size": size, "divisions": tuple(div), "origin": r.vec3(gt, gp, "origin", "3 numbers [m]",
                                                                                  (0.0, 0.0, 0.0))}
            elif kind == "plate":
                gt = r.table(mt[kind], gp, {"size": "2 positive lengths [m]", "divisions": "2 integers >= 1",
                                             "origin": "3 numbers [m] (default [0, 0, 0])"}, required=("size", "divisions"))
                size, div = gt["size"], gt["divisions"]
                if not (isinstance(size, list) and len(size) == 2 and all(isinstance(x, (int, float))
                                                                          and not isinstance(x, bool) and x > 0 for x in size)):
                    r.expected(join(gp, "size"), "2 positive lengths [m]", size)
                if not (isinstance(div, list) and len(div) == 2 and all(isinstance(x, int) and x >= 1 for x in div)):
                    r.expected(join(gp, "divisions"), "2 integers >= 1", div)
                params = {"size": tuple(float(x) for x in size), "divisions": tuple(div),
                          "origin": r.vec3(gt, gp, "origin", "3 numbers [m]", (0.0, 0.0, 0.0))}
            else:
                gt = r.table(mt[kind], gp, {"radius": "a positive radius [m]", "length": "a positive length [m]",
                                             "radial": "an integer >= 1", "axial": "an integer >= 1",
                                             "origin": "3 numbers [m] (default [0, 0, 0])"},
                             required=("radius", "length", "radial", "axial"))
                params = {"radius": r.real(gt, gp, "radius", "a positive radius [m]", ok=positive),
                          "length": r.real(gt, gp, "length", "a positive length [m]", ok=positive),
                          "radial": r.integer(gt, gp, "radial", "an integer >= 1", low=1),
                          "axial": r.integer(gt, gp, "axial", "an integer >= 1", low=1),
                          "origin": r.vec3(gt, gp, "origin", "3 numbers [m]", (0.0, 0.0, 0.0))}
            generated = (kind, _frozen(params))
        if "material" not in t:
            r.fail(b, "a mesh needs a table [body.material] {E, nu, rho}")
        mp = join(b, "material")
        mat = r.table(t["material"], mp, MATERIAL_KEYS, required=("E", "nu", "rho"))
        material = (r.real(mat, mp, "E", MATERIAL_KEYS["E"], ok=positive),
                    r.real(mat, mp, "nu", MATERIAL_KEYS["nu"], ok=lambda x: 0.0 <= x < 0.5),
                    r.real(mat, mp, "rho", MATERIAL_KEYS["rho"], ok=positive))
        source = "mesh"
    else:
        ep = join(b, "export")
        et = r.table(t["export"], ep, EXPORT_KEYS, required=("format", "units"))
        source = r.string(et, ep, "format", EXPORT_KEYS["format"], choices=tuple(EXPORT_FILES))
        units = r.string(et, ep, "units", EXPORT_KEYS["units"])
        for role in EXPORT_FILES[source] + (("elements",) if source == "ansys" and "elements" in et else ()):
            if role not in et:
                r.fail(ep, f"expected {role} = FILE ({EXPORT_KEYS[role]}) for format {source!r}")
            f = base / r.string(et, ep, role, EXPORT_KEYS[role])
            if not f.is_file():
                r.fail(join(ep, role), f"no such file: {f}")
            files.append((role, str(f)))
        extra = sorted(set(et) - set(EXPORT_FILES[source]) - {"format", "units", "elements"})
        if extra:
            r.fail(join(ep, extra[0]), f"not a file of format {source!r} (expects {', '.join(EXPORT_FILES[source])})")
    ports, frames = [], []
    pt = r.table(t["ports"], "body.ports", None)
    for i, (pname, p) in enumerate(pt.items()):
        pp = join("body.ports", pname)
        if not _NAME.match(pname):
            r.fail(pp, "expected a port name of letters, digits and _ (it prefixes FMU variable names)")
        r.table(p, pp, SOLID_PORT_KEYS, required=("select",))
        sel = r.table(p["select"], join(pp, "select"), {k: SOLID_PORT_KEYS["select"] for k in
                                                        ("set", "plane", "cylinder", "box", "near")})
        if len(sel) != 1:
            r.fail(join(pp, "select"), f"expected exactly one selection kind, got {sorted(sel) or 'none'}")
        link = r.string(p, pp, "link", SOLID_PORT_KEYS["link"], "rigid", ("rigid", "averaging"))
        point = r.vec3(p, pp, "point", SOLID_PORT_KEYS["point"], None) if "point" in p else None
        tr = r.string(p, pp, "translation", PORT_KEYS["translation"], "force", PART_CAUSALITIES)
        rot = r.string(p, pp, "rotation", PORT_KEYS["rotation"], "force", PART_CAUSALITIES)
        ports.append(Port(pname, i, tr, rot, _port_coupling(r, p, pp, tr, rot)))
        frames.append(SolidFrame(pname, json.dumps(sel, sort_keys=True), link, point))
    if len(ports) < 2:
        r.fail("body.ports", f"a solid needs at least 2 ports (interface frames), got {len(ports)}")
    spec = SolidSpec(source, tuple(files), generated, element, material, cutoff, tuple(frames), units, thickness)
    from .solid.source import solid_size  # the body's size: messages and scales of the tools that need one

    try:
        length = solid_size(spec)
    except (OSError, ValueError) as e:
        r.fail(b, f"cannot read the solid's nodes: {e}")
    return Body(name=name, length=length, origin=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), section=None,
                superelements=1, elements_per_superelement=0, modes=modes, ports=tuple(ports), source=file,
                solid=spec, damping=_parse_damping(r, t))


def _parse_time_function(r: Reader, t: dict, path: str, key: str) -> TimeFunction:
    p, v = join(path, key), t[key]
    if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
        return TimeFunction("constant", (("value", float(v)),))  # a plain number is a constant
    kinds = ", ".join(TIME_FUNCTION_KINDS)
    if not isinstance(v, dict):
        r.expected(p, f"a number or an inline table {{ kind = ..., <parameters> }} (kinds: {kinds})", v)
    kind = r.string(v, p, "kind", f"one of {kinds}")
    if kind not in TIME_FUNCTION_KINDS:
        near = nearest(kind, TIME_FUNCTION_KINDS)
        r.fail(join(p, "kind"), f"expected one of {kinds}, got {kind!r}" + (f"; did you mean {near!r}?" if near else ""))
    names, defaults = TIME_FUNCTION_KINDS[kind], TIME_FUNCTION_DEFAULTS.get(kind, {})
    what = f"a number (parameters of {kind}: {', '.join(names)})"
    r.table(v, p, {"kind": "a time-function kind", **{n: what for n in names}},
            required=[n for n in names if n not in defaults])
    params = {n: r.real(v, p, n, what, defaults.get(n, REQUIRED)) for n in names}
    if kind == "haug_spinup" and params["T"] <= 0.0:
        r.expected(join(p, "T"), "a positive spin-up time [s]", params["T"])
    if kind == "bump" and params["duration"] <= 0.0:
        r.expected(join(p, "duration"), "a positive bump duration [s]", params["duration"])
    if kind == "window" and params["t_end"] <= params["t_start"]:
        r.expected(join(p, "t_end"), f"a time after t_start = {params['t_start']}", params["t_end"])
    return TimeFunction(kind, tuple(sorted(params.items())))


def _parse_scene(r: Reader, body: Body, name: str, t: Any) -> Scene:
    sp = join("scenes", name)
    r.table(t, sp, SCENE_KEYS, required=("duration", "step"))
    ports = {p.name: p for p in body.ports}

    # causality first: drives and loads are checked against the scene's effective causality
    causality, effective = [], {p.name: (p.translation, p.rotation) for p in body.ports}
    cp = join(sp, "causality")
    for pname, c in r.table(t.get("causality", {}), cp, None).items():
        path = join(cp, pname)
        r.port_name(ports, path, pname)
        r.table(c, path, CAUSALITY_KEYS)
        tr = r.string(c, path, "translation", CAUSALITY_KEYS["translation"], ports[pname].translation, PART_CAUSALITIES)
        rot = r.string(c, path, "rotation", CAUSALITY_KEYS["rotation"], ports[pname].rotation, PART_CAUSALITIES)
        causality.append((pname, tr, rot))
        effective[pname] = (tr, rot)

    def require_part(path: str, pname: str, part: str, want: str, why: str):
        have = effective[pname][PART_INDEX[part]]
        if have != want and not (want == "motion" and have == "compliant"):  # a drive moves the spring's end
            r.fail(path, f"expected a {want}-driven {part}: port {pname!r} {part} is {have}-driven in this scene "
                   f"({why})")

    drives = []
    dp = join(sp, "drives")
    for pname, d in r.table(t.get("drives", {}), dp, None).items():
        path = join(dp, pname)
        r.port_name(ports, path, pname)
        r.table(d, path, DRIVE_KEYS)
        rotation = translation = None
        if "rotation" in d:
            rp = join(path, "rotation")
            require_part(rp, pname, "rotation", "motion", "only a motion-driven part can be prescribed")
            rt = r.table(d["rotation"], rp, ROTATION_DRIVE_KEYS, required=("axis", "angle"))
            rotation = RotationDrive(r.vec3(rt, rp, "axis", ROTATION_DRIVE_KEYS["axis"], unit=True),
                                     _parse_time_function(r, rt, rp, "angle"))
        if "translation" in d:
            tp = join(path, "translation")
            require_part(tp, pname, "translation", "motion", "only a motion-driven part can be prescribed")
            tt = r.table(d["translation"], tp, TRANSLATION_DRIVE_KEYS, required=("direction", "displacement"))
            translation = TranslationDrive(r.vec3(tt, tp, "direction", TRANSLATION_DRIVE_KEYS["direction"], unit=True),
                                           _parse_time_function(r, tt, tp, "displacement"))
        drives.append(Drive(pname, rotation, translation))

    loads = []
    lv = t.get("loads", [])
    if not isinstance(lv, list):
        r.expected(join(sp, "loads"), SCENE_KEYS["loads"], lv)
    for i, lt in enumerate(lv):
        lp = join(join(sp, "loads"), i)
        r.table(lt, lp, LOAD_KEYS, required=("port",))
        pname = r.port_name(ports, join(lp, "port"), lt["port"])
        force = r.vec3(lt, lp, "force", LOAD_KEYS["force"], (0.0, 0.0, 0.0))
        moment = r.vec3(lt, lp, "moment", LOAD_KEYS["moment"], (0.0, 0.0, 0.0))
        why = "its reaction is an output; a load needs a force-driven part"
        if any(force):
            require_part(join(lp, "force"), pname, "translation", "force", why)
        if any(moment):
            require_part(join(lp, "moment"), pname, "rotation", "force", why)
        t0 = r.real(lt, lp, "t_start", LOAD_KEYS["t_start"], 0.0)
        t1 = r.real(lt, lp, "t_end", LOAD_KEYS["t_end"], math.inf, ok=lambda x: x > t0)
        loads.append(Load(pname, force, moment, t0, t1))

    unbalances = []
    uv = t.get("unbalances", [])
    if not isinstance(uv, list):
        r.expected(join(sp, "unbalances"), SCENE_KEYS["unbalances"], uv)
    drive_of = {d.port: d for d in drives}
    for i, ut in enumerate(uv):
        up = join(join(sp, "unbalances"), i)
        r.table(ut, up, UNBALANCE_KEYS, required=("port", "mass_eccentricity", "drive"))
        pname = r.port_name(ports, join(up, "port"), ut["port"])
        require_part(join(up, "port"), pname, "translation", "force", "an unbalance is a load on the body")
        me = r.real(ut, up, "mass_eccentricity", UNBALANCE_KEYS["mass_eccentricity"], ok=positive)
        dname = r.port_name(ports, join(up, "drive"), ut["drive"])
        if dname not in drive_of or drive_of[dname].rotation is None:
            r.fail(join(up, "drive"), f"expected a port with a rotation drive in this scene, got {dname!r}")
        ref = r.vec3(ut, up, "reference", UNBALANCE_KEYS["reference"], (0.0, 1.0, 0.0))
        axis = drive_of[dname].rotation.axis
        normal = [ref[k] - sum(a * b for a, b in zip(ref, axis)) * axis[k] for k in range(3)]
        if math.sqrt(sum(x * x for x in normal)) < 1e-9 * max(1e-300, math.sqrt(sum(x * x for x in ref))):
            r.fail(join(up, "reference"), f"expected {UNBALANCE_KEYS['reference']}, got {list(ref)} along the "
                   f"spin axis {list(axis)}")
        phase = r.real(ut, up, "phase", UNBALANCE_KEYS["phase"], 0.0)
        unbalances.append(Unbalance(pname, me, dname, ref, phase))

    ip = join(sp, "initial")
    it = r.table(t.get("initial", {}), ip, INITIAL_KEYS)
    displacements = []
    pdp = join(ip, "port_displacements")
    for pname in r.table(it.get("port_displacements", {}), pdp, None):
        path = join(pdp, pname)
        r.port_name(ports, path, pname)
        require_part(path, pname, "translation", "force", "a motion-driven port starts at its reference position")
        displacements.append((pname, r.vec3(it["port_displacements"], pdp, pname, "3 numbers [m]")))
    initial = Initial(
        r.vec3(it, ip, "velocity", INITIAL_KEYS["velocity"], (0.0, 0.0, 0.0)),
        r.vec3(it, ip, "angular_velocity", INITIAL_KEYS["angular_velocity"], (0.0, 0.0, 0.0)),
        tuple(displacements),
        it.get("state", "rest"),
    )
    if initial.state not in INITIAL_STATES:
        r.expected(join(ip, "state"), INITIAL_KEYS["state"], initial.state)
    if initial.state != "rest" and (displacements or any(initial.velocity) or any(initial.angular_velocity)):
        r.fail(join(ip, "state"), f"state {initial.state!r} sets the body's deformation and velocities itself: "
               "no port_displacements, velocity or angular_velocity with it")
    if initial.state != "rest" and any("compliant" in parts for parts in effective.values()):
        r.fail(join(ip, "state"), f"state {initial.state!r} is not available with compliant ports (compliant in this "
               f"scene: {sorted(p for p, parts in effective.items() if 'compliant' in parts)})")
    if initial.state == "steady_spin":
        try:
            steady_spin_drive(name, drives)
        except ValueError as e:
            r.fail(join(ip, "state"), str(e))

    duration = r.real(t, sp, "duration", SCENE_KEYS["duration"], ok=positive)
    outputs = t.get("outputs", [])
    if not isinstance(outputs, list) or not all(isinstance(o, str) for o in outputs):
        r.expected(join(sp, "outputs"), SCENE_KEYS["outputs"], outputs)
    for o in outputs:  # probes (eq. 92): "<port>_from_<port>", the first port seen from the second's frame
        seen, sep, frame = o.partition("_from_")
        if not sep or seen not in ports or frame not in ports or seen == frame:
            r.fail(join(sp, "outputs"), f"expected probe names '<port>_from_<port>' of two ports of the body "
                   f"({', '.join(ports)}), got {o!r}")
    return Scene(
        name=name,
        duration=duration,
        step=r.real(t, sp, "step", SCENE_KEYS["step"], ok=lambda x: 0.0 < x <= duration),
        rho_inf=r.real(t, sp, "rho_inf", SCENE_KEYS["rho_inf"], 0.8, ok=lambda x: 0.0 <= x <= 1.0),
        terms=r.string(t, sp, "terms", SCENE_KEYS["terms"], "linear", TERM_SETS),
        gravity=r.vec3(t, sp, "gravity", SCENE_KEYS["gravity"], (0.0, 0.0, 0.0)),
        drives=tuple(drives),
        loads=tuple(loads),
        initial=initial,
        causality=tuple(causality),
        metrics=_metrics(r, t.get("metrics", ""), join(sp, "metrics")),
        outputs=tuple(outputs),
        stiffening=r.boolean(t, sp, "stiffening", SCENE_KEYS["stiffening"], False),
        full_terms=_full_terms(r, t, sp),
        reference=_reference(r, t, sp),
        unbalances=tuple(unbalances),
    )


def steady_spin_drive(scene_name: str, drives: Sequence[Drive], t0: float = 0.0) -> tuple[Drive, float]:
    """The rotation drive a scene with initial state 'steady_spin' spins with, and its rate at t0 [rad/s]:
    the scene's first rotation drive, which must spin steadily there (a rate, no angular acceleration).
    ValueError naming the cause otherwise (the parser reports it at the scene's initial.state)."""
    from .runtime.drives import evaluate

    rotating = [d for d in drives if d.rotation is not None]
    if not rotating:
        raise ValueError(f"scene {scene_name!r}: initial state 'steady_spin' needs a rotation drive")
    d = rotating[0]
    _, rate, acc = evaluate(d.rotation.angle.kind, dict(d.rotation.angle.params), t0)
    if rate == 0.0 or acc != 0.0:
        raise ValueError(f"scene {scene_name!r}: initial state 'steady_spin' needs the drive {d.port}.rotation to "
                         f"spin steadily at t = {t0:g} (rate {rate:g} rad/s, acceleration {acc:g} rad/s^2): e.g. a "
                         "ramp that started before t = 0")
    return d, float(rate)


def _reference(r: Reader, t: dict, sp: str) -> ReferenceOptions:
    if "reference" not in t:
        return ReferenceOptions()
    path = join(sp, "reference")
    rt = r.table(t["reference"], path, REFERENCE_KEYS)
    return ReferenceOptions(r.integer(rt, path, "elements", REFERENCE_KEYS["elements"], None, low=1),
                            r.real(rt, path, "step", REFERENCE_KEYS["step"], None, ok=positive))


def _metrics(r: Reader, v: Any, path: str) -> Metrics:
    """[scenes.NAME.metrics]: a table, or a kind alone (its primary metric: the first of the kind's
    when that is the tip deflection, else none)."""
    if isinstance(v, str) and v in OLD_METRIC_NAMES:
        r.fail(path, f"{v!r} was a benchmark's name; write the table [{path}] with kind = "
                     f"{OLD_METRIC_NAMES[v]!r} and the benchmark's windows and bands (docs/model-format.md)")
    if isinstance(v, str):
        if v and v not in METRIC_KINDS:
            r.expected(path, SCENE_KEYS["metrics"], v)
        return Metrics(v, "tip_deflection_max_m" if v == "tip_deflection" else "")
    t = r.table(v, path, METRICS_KEYS, required=("kind",))
    kind = r.string(t, path, "kind", METRICS_KEYS["kind"], choices=tuple(METRIC_KINDS))
    band = None
    if "band_hz" in t:
        b = t["band_hz"]
        if not (isinstance(b, list) and len(b) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                            for x in b) and 0 < b[0] < b[1] and math.isfinite(b[1])):
            r.expected(join(path, "band_hz"), METRICS_KEYS["band_hz"], b)
        band = (float(b[0]), float(b[1]))
    m = Metrics(kind, "", band, r.real(t, path, "min_window_s", METRICS_KEYS["min_window_s"], 0.0, ok=nonnegative),
                r.real(t, path, "coast_end_s", METRICS_KEYS["coast_end_s"], None, ok=positive)
                if "coast_end_s" in t else None)
    primary = r.string(t, path, "primary", METRICS_KEYS["primary"], "", m.names() + ("",))
    return dataclasses.replace(m, primary=primary)


def _full_terms(r: Reader, t: dict, sp: str) -> tuple[str, ...]:
    v = t.get("full_terms", list(FULL_TERMS))
    if not isinstance(v, list) or not all(isinstance(x, str) and x in FULL_TERMS for x in v) or len(set(v)) != len(v):
        r.expected(join(sp, "full_terms"), SCENE_KEYS["full_terms"], v)
    return tuple(v)


def scene_body(body: Body, scene: Scene) -> Body:
    """The body with the scene's causality overrides on its ports: the one place they are applied
    (the reduction, the standalone run, the FMU builder and the reference take the body it returns)."""
    over = {name: (tr, rot) for name, tr, rot in scene.causality}
    unknown = set(over) - {p.name for p in body.ports}
    if unknown:
        raise ModelError(f"{body.source}: scene {scene.name!r} sets the causality of unknown port(s) {sorted(unknown)}")
    ports = tuple(dataclasses.replace(p, translation=over[p.name][0], rotation=over[p.name][1]) if p.name in over else p
                  for p in body.ports)
    return dataclasses.replace(body, ports=ports)


def reduction_options(scene: Scene) -> dict:
    """reduce_body's options for a scene: stiffening (scene key) and the inertia data of `full`."""
    return {"stiffening": scene.stiffening, "inertia": scene.terms == "full"}


def write_model(raw: dict, path, comment: str = "") -> Model:
    """Write the raw tables as a model file and load it back (a ModelError names what is wrong)."""
    Path(path).write_text(toml_text(raw, comment), encoding="utf-8")
    return load_model(path)
