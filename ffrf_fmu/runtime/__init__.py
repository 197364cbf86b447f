"""Run-time code of a body: reduced data, equations, integrator. Shipped inside every FMU.

Modules here import only numpy, scipy and each other (relative imports), never the rest of
ffrf_fmu, so the builder can copy this package into an FMU under a unique name.
"""
