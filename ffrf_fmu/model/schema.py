"""The model file's content as frozen dataclasses: a body (beam or solid, ports, point masses) and
its scenes (drives, loads, initial state, metrics); docs/model-format.md gives each key's meaning."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..checked_toml import ModelError
from ..runtime.damping import Damping
from ..section import Section
from ..runtime.terms import FULL_TERMS


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
    max_newton_iterations: int = 0  # Newton iterations of a step at most (0: no cap; docs/fmu.md, real time)


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
