"""A beam's section properties per unit length: what the beam element (fe/beam.py), the Nastran reader
(solid/nastran.py) and the model file ([body.section], model.py) share, in a module of its own so that
the FE stages need not import the model file's reader."""
from __future__ import annotations

from dataclasses import dataclass


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
