"""Body FMUs: the builder (reduced data + private runtime + pythonfmu script) and the slave core.

`build_fmu(data, dest, SceneParameters(...))` writes an FMI 2.0 co-simulation FMU of a BodyData;
`build_from_model(path, dest, scene=...)` does it from a model file. See docs/fmu.md.
"""
from .builder import BuildError, SceneParameters, build_fmu, build_from_model, read_fmu_config

__all__ = ["BuildError", "SceneParameters", "build_fmu", "build_from_model", "read_fmu_config"]
