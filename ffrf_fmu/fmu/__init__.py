"""Body FMUs: the builder (reduced data + private runtime + pythonfmu script) and the slave core.

`build_fmu(model_path, dest, scene=...)` writes the FMU of a model file's scene (the public
ffrf_fmu.build_fmu; native runtime by default, FMI 2.0 or 3.0); `build_python_fmu(data, dest,
SceneParameters(...))` the pythonfmu FMU (FMI 2.0) of any BodyData. Both return the FMU's path.
See docs/fmu.md.
"""
from .builder import BuildError, SceneParameters, build_fmu, build_python_fmu, read_fmu_config
from .builder import __getattr__  # noqa: F401  (refuses the old name build_from_model)

__all__ = ["BuildError", "SceneParameters", "build_fmu", "build_python_fmu", "read_fmu_config"]

