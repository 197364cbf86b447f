"""The C runtime of a body (one library for the standalone run and the FMU): the body struct and its
equations, integrator, inputs and records in C (body.h; in layers so3.c, lu.c, superelement.c,
factor.c, step.c, accel.c, advance.c, body.c: docs/runtime.md), the body image that creates it (image.py), its compilation into the user cache (build.py) and
its Python binding (binding.py)."""
