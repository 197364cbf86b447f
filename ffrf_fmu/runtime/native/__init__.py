"""The C runtime of a body (one library for the standalone run and the FMU): the body struct and its
equations, integrator, inputs and records in C (body.h, so3.c, superelement.c, step.c, advance.c,
accel.c, body.c), the body image that creates it (image.py), its compilation into the user cache (build.py) and
its Python binding (binding.py)."""
