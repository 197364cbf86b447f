"""The term sets of the body equations, defined once (the model file's `terms`, the FMU's
`solver.terms` enumeration, BodySystem and the C runtime's image all name them from here). Standard library
only: the model parser and the FMU variable table import it without numpy.

- `linear`: the two-field FFRF equations (geradin eqs. 77-79) without the inertia coupling S(q)
  and the elastic Coriolis force G(W0): rigid motion and elastic deformation couple through the
  boundary frames and the CM frame only;
- `gyroscopic`: adds S(q) (eq. 55) and G(W0) (eq. 53), the terms a spinning body needs;
- `full`: Witteveen's deformation-dependent inertia on top, each term switchable (FULL_TERMS;
  needs the inertia data W1, W2 in the reduced body, docs/inertia-terms.md).
"""
TERM_SETS = ("linear", "gyroscopic", "full")  # FMU solver.terms = the index into this tuple
# Witteveen's terms, switchable within `full` (docs/inertia-terms.md): the inertia tensor's change W1 q
# (with the constant centrifugal load) and q W2 q (with the elastic centrifugal force), the inertia coupling
# S(q) in the angular momentum, the elastic Coriolis force G(W0) on the elastic coordinates
FULL_TERMS = ("inertia_W1", "inertia_W2", "inertia_coupling", "coriolis")
