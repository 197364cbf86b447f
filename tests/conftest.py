"""Benchmark beam sections of benchmarks.md (B1, B2), built directly from model.Section."""
import os

# as the CLI does (ffrf_fmu/cli.py): one BLAS thread for the small body matrices, before numpy loads
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402

from ffrf_fmu.model import Section

_E, _NU, _A, _I, _RHO = 2.1e6, 0.3, 9.0, 6.75, 7.8e-3
BEAMS = {
    # B1 (geradin 9.2), L = 8: m22 = m33 = 22.7e-6 (benchmarks.md note 2)
    "B1": (Section(EA=5.03e6, GJ=435.0, EI2=566.0, EI3=566.0, m=0.201, m22=22.7e-6, m33=22.7e-6, GA2=1.94e6, GA3=1.94e6), 8.0),
    # B2 (geradin 9.1), L = 141.42: E = 2.1e6, nu = 0.3, A = 9, I = 6.75 both axes, rho = 7.8e-3, Euler-Bernoulli
    "B2": (Section(EA=_E * _A, GJ=_E / (2 * (1 + _NU)) * 2 * _I, EI2=_E * _I, EI3=_E * _I, m=_RHO * _A, m22=_RHO * _I, m33=_RHO * _I), 141.42),
}


@pytest.fixture
def b1():
    """(Section, length) of benchmark B1."""
    return BEAMS["B1"]


@pytest.fixture
def b2():
    """(Section, length) of benchmark B2."""
    return BEAMS["B2"]


@pytest.fixture(params=sorted(BEAMS))
def beam(request):
    """(Section, length) of each benchmark beam in turn."""
    return BEAMS[request.param]
