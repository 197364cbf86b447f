"""The C runtime's factorization of the iteration matrix as a body holds it between calls.

The C runtime factors the matrix by its structure (runtime/native/factor.c: each superelement's own unknowns,
then the boundary nodes), not as LAPACK's dense LU of the numpy path: the two are not interchangeable.
Its factors travel in BodySystem's `_lu` and state as a `NativeFactor` (a numpy array of the C
runtime's factor buffer), which the numpy path does not use (it refreshes instead), and a dense LU of
the numpy path is not handed to the C runtime (it refreshes too). Numpy only: no ctypes here.
"""
from __future__ import annotations

import numpy as np

STATE_FLAG = 2.0  # BodySystem state's `has_lu` entry for a NativeFactor (1.0: LAPACK's dense LU)


class NativeFactor(np.ndarray):
    """The factor buffer (nf x nf doubles, C order) of the C runtime."""


def is_native(lu) -> bool:
    """Whether a body's `_lu` holds the C runtime's factorization."""
    return lu is not None and isinstance(lu[0], NativeFactor)
