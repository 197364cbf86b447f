"""ffrf-fmu: flexible bodies (beams as chains of two-field FFRF superelements, solids as one) as FMI co-simulation FMUs.

The public API: `load_model(path, overrides)`, `build_body(model, scene)` (the reduced body as the
scene runs it), `run_scene(model, scene)` (the standalone run), `build_fmu(model_path, dest,
scene=...)` and `validate_fmu(fmu_or_model, model=..., scene=...)` (the FMU under fmpy against the
standalone run). From the repository root:

    >>> import ffrf_fmu
    >>> model = ffrf_fmu.load_model("models/haug_beam.toml", ["superelements=2", "duration=0.2"])
    >>> len(ffrf_fmu.build_body(model, "spinup").superelements)
    2
    >>> result = ffrf_fmu.run_scene(model, "spinup")
    >>> result.summary["completed"], float(result.columns["tip.r[1]"][0])  # the tip starts at x = L
    (True, 8.0)
"""
import os as _os
import sys as _sys

__version__ = "0.1.0"

# One BLAS thread whenever ffrf_fmu is imported: the body's matrices are a few hundred rows and
# BLAS threads cost more than they save (an LU of 174 x 174 took 11 ms with two OpenBLAS threads,
# 1.6 ms with one). A thread count the user exported wins. The environment defaults reach every BLAS
# loaded later (scipy ships its own OpenBLAS, loaded by `import scipy.linalg`: with numpy imported
# first and only threadpoolctl's limit, it ran two threads, one of them spinning 0.4 s of CPU per
# 0.4 s B1 run); threadpoolctl limits the BLAS libraries already loaded.
# Inside an FMU the limit is scoped to the FMU's own calls instead (fmu/core.py).
_BLAS_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
if not any(v in _os.environ for v in _BLAS_VARS):
    for _var in _BLAS_VARS:
        _os.environ[_var] = "1"
    if "numpy" in _sys.modules:
        try:
            from threadpoolctl import threadpool_limits as _limits
        except ImportError:  # then numpy keeps its threads; docs/fmu.md says how to set them
            pass
        else:
            _limits(limits=1, user_api="blas")

# The public API, imported on first use (importing ffrf_fmu stays cheap and sets the BLAS threads
# above before numpy loads). `simulate` names the submodule ffrf_fmu.simulate, so the standalone run
# is `run_scene`. Each name's object in the entry-point notation of the packaging specifications (module:attr).
_API = {"load_model": "ffrf_fmu.model:load_model", "build_body": "ffrf_fmu.reduction:build_body",
        "run_scene": "ffrf_fmu.simulate:run_scene", "build_fmu": "ffrf_fmu.fmu.builder:build_fmu",
        "validate_fmu": "ffrf_fmu.validate:validate"}
__all__ = ["__version__", *_API]


def __getattr__(name):
    if name in _API:
        import importlib

        module, attr = _API[name].split(":")
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'ffrf_fmu' has no attribute {name!r}")
