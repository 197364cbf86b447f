"""ffrf-fmu: flexible beams as two-field FFRF superelement chains, shipped as FMI co-simulation FMUs."""
import os as _os
import sys as _sys

__version__ = "0.1.0"

# One BLAS thread whenever ffrf_fmu is imported: the body's matrices are a few hundred rows and
# BLAS threads cost more than they save (an LU of 174 x 174 took 11 ms with two OpenBLAS threads,
# 1.6 ms with one). A thread count the user exported wins. Before numpy loads, the environment
# defaults do it; when numpy is already loaded, threadpoolctl limits the loaded BLAS libraries.
# Inside an FMU the limit is scoped to the FMU's own calls instead (fmu/core.py).
_BLAS_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
if not any(v in _os.environ for v in _BLAS_VARS):
    if "numpy" not in _sys.modules:
        for _var in _BLAS_VARS:
            _os.environ[_var] = "1"
    else:
        try:
            from threadpoolctl import threadpool_limits as _limits
        except ImportError:  # then numpy keeps its threads; docs/fmu.md says how to set them
            pass
        else:
            _limits(limits=1, user_api="blas")
