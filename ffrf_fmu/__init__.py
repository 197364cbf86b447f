"""ffrf-fmu: flexible beams as two-field FFRF superelement chains, shipped as FMI co-simulation FMUs."""

__version__ = "0.1.0"
