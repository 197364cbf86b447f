"""Full-order geometrically exact beam: the independent reference for the superelement path.

See `solver` (dynamics, statics, scene semantics) and `beam` (element). Shares no dynamics code
with the superelement path: it uses only the model dataclasses and the drive time functions.
"""
from .solver import ReferenceResult, StaticResult, Mesh, simulate_reference, static_reference, tip_from_hub

__all__ = ["ReferenceResult", "StaticResult", "Mesh", "simulate_reference", "static_reference", "tip_from_hub"]
