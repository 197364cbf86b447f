"""Model files: a body (beam, superelements, ports) and named scenes, as frozen dataclasses.

The TOML format is documented in docs/model-format.md; `load_model` parses, applies
`--set key=value` overrides and validates, raising `ModelError` that names the file, the key
and what was expected.
"""
from __future__ import annotations

from dataclasses import dataclass, field

PART_CAUSALITIES = ("motion", "force")
TERM_SETS = ("linear", "gyroscopic")


class ModelError(ValueError):
    """A model file (or an override) is malformed; the message names file, key and expectation."""


@dataclass(frozen=True)
class Section:
    """Beam section properties per unit length (SI). GA2/GA3 None -> Euler-Bernoulli."""

    EA: float
    GJ: float
    EI2: float  # bending about local axis 2 (deflection along axis 3)
    EI3: float  # bending about local axis 3 (deflection along axis 2)
    m: float  # mass per unit length [kg/m]
    m22: float  # rotary inertia per unit length about axis 2 [kg m]
    m33: float  # rotary inertia per unit length about axis 3 [kg m]
    m11: float | None = None  # torsional inertia; None -> m22 + m33
    GA2: float | None = None
    GA3: float | None = None


@dataclass(frozen=True)
class Port:
    """A named boundary node of the body and the causality of its two parts (ports.md)."""

    name: str
    node: int  # boundary node index 0..superelements (negative counts from the end), normalized >= 0
    translation: str  # "motion" | "force"
    rotation: str  # "motion" | "force"


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

    def port(self, name: str) -> Port:
        for p in self.ports:
            if p.name == name:
                return p
        raise ModelError(f"{self.source}: no port named {name!r} (ports: {[p.name for p in self.ports]})")


@dataclass(frozen=True)
class TimeFunction:
    """A scalar time function s(t) with its first two derivatives (see drives.py for kinds).

    kind: "constant" (value), "haug_spinup" (omega, T: angle profile of Wu-Haug, benchmarks.md B1),
    "ramp" (rate, t_start), "window" (value, t_start, t_end: value inside [t_start, t_end), else 0),
    "sine" (amplitude, frequency_hz, phase).
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
    rotation: RotationDrive | None = None  # None: held at the reference orientation
    translation: TranslationDrive | None = None  # None: held at the reference position


@dataclass(frozen=True)
class Load:
    """A force and/or moment (world axes) on a force-driven port part, scaled by a time function."""

    port: str
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    moment: tuple[float, float, float] = (0.0, 0.0, 0.0)
    t_start: float = 0.0
    t_end: float = float("inf")


@dataclass(frozen=True)
class Initial:
    """Initial state: rigid velocity field v + w x (X - origin) of the whole body; port offsets."""

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    port_displacements: tuple[tuple[str, tuple[float, float, float]], ...] = ()


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
    metrics: str = ""  # "haug" | "spherical" | "free" | "" : which summary metrics apply
    outputs: tuple[str, ...] = ()  # extra probes, e.g. "tip_from_hub"


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
