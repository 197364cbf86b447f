"""Zero-work FMUs with exactly the model variables of a given FMU (names, types, causalities,
variabilities, value references, start values): what a master costs per doStep for an FMU of that
interface before the FMU does any work (benchmarks/fmu_overhead.py).

  c_floor       a C FMU, compiled with the C compiler that builds the body FMUs' native loader
                (fmu/builder.py): the values in one array indexed by value reference, doStep returns
                fmi2OK at once. Under fmpy: fmpy's own cost per doStep (input table, setters,
                getters, recorder, ctypes), the least any FMU of this interface can cost.
  python_floor  a pythonfmu FMU (pythonfmu's builder, no native loader): the values in one Python
                list, the getters and setters overridden to one list read or write per value (the
                body slave's are one gather/scatter too), do_step returns True. Under fmpy: fmpy's
                cost plus pythonfmu's (its C++ wrapper, the Python calls and their list marshalling),
                the least any pythonfmu FMU of this interface can cost.

Both are built into `dest` from the given FMU's modelDescription.xml; a missing compiler raises.
"""
from __future__ import annotations

import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from ffrf_fmu.fmu.builder import c_compiler

C_SOURCE = r"""
/* zero-work FMI 2.0 co-simulation FMU: {n} values indexed by value reference (benchmarks/_fmu_floor.py) */
#include <stdlib.h>
#include <stddef.h>
#define API __attribute__((visibility("default")))
typedef unsigned int vr_t;
enum {{ OK = 0, ERROR = 3 }};
typedef struct {{ double v[{n}]; }} Instance;

API const char* fmi2GetTypesPlatform(void) {{ return "default"; }}
API const char* fmi2GetVersion(void) {{ return "2.0"; }}
API int fmi2SetDebugLogging(void* c, int on, size_t n, const char* const* cat) {{ return OK; }}
API void* fmi2Instantiate(const char* name, int type, const char* guid, const char* res, const void* cb, int vis, int log) {{
    return calloc(1, sizeof(Instance));
}}
API void fmi2FreeInstance(void* c) {{ free(c); }}
API int fmi2SetupExperiment(void* c, int tol_defined, double tol, double t0, int stop_defined, double t1) {{ return OK; }}
API int fmi2EnterInitializationMode(void* c) {{ return OK; }}
API int fmi2ExitInitializationMode(void* c) {{ return OK; }}
API int fmi2Terminate(void* c) {{ return OK; }}
API int fmi2Reset(void* c) {{ return OK; }}
API int fmi2GetReal(void* c, const vr_t* r, size_t n, double* x) {{
    for (size_t i = 0; i < n; i++) {{ if (r[i] >= {n}) return ERROR; x[i] = ((Instance*)c)->v[r[i]]; }}
    return OK;
}}
API int fmi2SetReal(void* c, const vr_t* r, size_t n, const double* x) {{
    for (size_t i = 0; i < n; i++) {{ if (r[i] >= {n}) return ERROR; ((Instance*)c)->v[r[i]] = x[i]; }}
    return OK;
}}
API int fmi2GetInteger(void* c, const vr_t* r, size_t n, int* x) {{
    for (size_t i = 0; i < n; i++) {{ if (r[i] >= {n}) return ERROR; x[i] = (int)((Instance*)c)->v[r[i]]; }}
    return OK;
}}
API int fmi2SetInteger(void* c, const vr_t* r, size_t n, const int* x) {{
    for (size_t i = 0; i < n; i++) {{ if (r[i] >= {n}) return ERROR; ((Instance*)c)->v[r[i]] = x[i]; }}
    return OK;
}}
API int fmi2GetBoolean(void* c, const vr_t* r, size_t n, int* x) {{ return n ? ERROR : OK; }}
API int fmi2SetBoolean(void* c, const vr_t* r, size_t n, const int* x) {{ return n ? ERROR : OK; }}
API int fmi2GetString(void* c, const vr_t* r, size_t n, const char** x) {{ return n ? ERROR : OK; }}
API int fmi2SetString(void* c, const vr_t* r, size_t n, const char* const* x) {{ return n ? ERROR : OK; }}
API int fmi2DoStep(void* c, double t, double h, int no_prior) {{ return OK; }}
API int fmi2CancelStep(void* c) {{ return ERROR; }}
API int fmi2GetStatus(void* c, int k, int* s) {{ return ERROR; }}
API int fmi2GetRealStatus(void* c, int k, double* s) {{ return ERROR; }}
API int fmi2GetIntegerStatus(void* c, int k, int* s) {{ return ERROR; }}
API int fmi2GetBooleanStatus(void* c, int k, int* s) {{ return ERROR; }}
API int fmi2GetStringStatus(void* c, int k, const char** s) {{ return ERROR; }}
API int fmi2GetFMUstate(void* c, void** s) {{ return ERROR; }}
API int fmi2SetFMUstate(void* c, void* s) {{ return ERROR; }}
API int fmi2FreeFMUstate(void* c, void** s) {{ return ERROR; }}
API int fmi2SerializedFMUstateSize(void* c, void* s, size_t* n) {{ return ERROR; }}
API int fmi2SerializeFMUstate(void* c, void* s, char* b, size_t n) {{ return ERROR; }}
API int fmi2DeSerializeFMUstate(void* c, const char* b, size_t n, void** s) {{ return ERROR; }}
API int fmi2GetDirectionalDerivative(void* c, const vr_t* a, size_t na, const vr_t* b, size_t nb, const double* x, double* y) {{ return ERROR; }}
API int fmi2SetRealInputDerivatives(void* c, const vr_t* a, size_t n, const int* o, const double* x) {{ return ERROR; }}
API int fmi2GetRealOutputDerivatives(void* c, const vr_t* a, size_t n, const int* o, double* x) {{ return ERROR; }}
"""

PY_SOURCE = '''"""Zero-work pythonfmu FMU with the model variables of {source} (benchmarks/_fmu_floor.py)."""
from pythonfmu import Fmi2Slave, Integer, Real
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability

VARIABLES = {variables!r}  # (name, type, causality, variability, start), in value-reference order


class {cls}(Fmi2Slave):

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._v = [float(start) if start is not None else 0.0 for *_, start in VARIABLES]
        for vr, (name, kind, causality, variability, start) in enumerate(VARIABLES):
            make = Real if kind == "Real" else Integer
            initial = {{"output": Fmi2Initial.calculated, "parameter": Fmi2Initial.exact}}.get(causality)
            self.register_variable(make(name, start=start, causality=Fmi2Causality[causality],
                                        variability=Fmi2Variability[variability], initial=initial,
                                        getter=lambda i=vr: self._v[i],
                                        setter=lambda x, i=vr: self._v.__setitem__(i, x)), nested=False)

    def get_real(self, vrs):
        v = self._v
        return [v[i] for i in vrs]

    def set_real(self, vrs, values):
        v = self._v
        for i, x in zip(vrs, values):
            v[i] = x

    def get_integer(self, vrs):
        v = self._v
        return [int(v[i]) for i in vrs]

    def set_integer(self, vrs, values):
        v = self._v
        for i, x in zip(vrs, values):
            v[i] = x

    def do_step(self, current_time, step_size):
        return True
'''


def _variables(fmu: Path) -> list[tuple]:
    """(name, type, causality, variability, start) of every model variable, in value-reference order
    (which must be 0 .. n-1: the order pythonfmu gives them)."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    out = sorted(md.modelVariables, key=lambda v: v.valueReference)
    if [v.valueReference for v in out] != list(range(len(out))):
        raise ValueError(f"{fmu}: value references are not 0 .. {len(out) - 1}")
    if any(v.type not in ("Real", "Integer") for v in out):
        raise ValueError(f"{fmu}: the floor FMUs hold Real and Integer variables only")
    start = lambda v: None if v.start is None else (int(v.start) if v.type == "Integer" else float(v.start))  # noqa: E731
    return [(v.name, v.type, v.causality, v.variability, start(v)) for v in out]


def c_floor(fmu, dest) -> Path:
    """The zero-work C FMU of `fmu`'s interface, built in directory `dest`: dest/floor_c.fmu."""
    fmu, dest = Path(fmu), Path(dest)
    cc = c_compiler()  # the one our FMU's native loader is built with
    if not cc:
        raise RuntimeError("no C compiler found (set CC or install gcc)")
    n = len(_variables(fmu))
    stage = dest / "floor_c"
    (stage / "binaries" / "linux64").mkdir(parents=True, exist_ok=True)
    (stage / "floor_c.c").write_text(C_SOURCE.format(n=n), encoding="utf-8")
    done = subprocess.run([cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o",
                           str(stage / "binaries" / "linux64" / "floor_c.so"), str(stage / "floor_c.c")],
                          capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"{cc} failed: {done.stderr.strip()[:2000]}")
    with zipfile.ZipFile(fmu) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    root.set("modelName", "floor_c")
    cs = root.find("CoSimulation")
    cs.set("modelIdentifier", "floor_c")
    for flag in ("needsExecutionTool", "canGetAndSetFMUstate", "canSerializeFMUstate", "providesDirectionalDerivative"):
        if flag in cs.attrib:
            cs.set(flag, "false")
    out = dest / "floor_c.fmu"
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", ET.tostring(root, encoding="unicode", xml_declaration=True))
        z.write(stage / "binaries" / "linux64" / "floor_c.so", "binaries/linux64/floor_c.so")
    return out


def python_floor(fmu, dest) -> Path:
    """The zero-work pythonfmu FMU of `fmu`'s interface, built in directory `dest`: dest/FloorPy.fmu."""
    from pythonfmu import FmuBuilder

    fmu, dest = Path(fmu), Path(dest)
    stage = dest / "floor_py"
    stage.mkdir(parents=True, exist_ok=True)
    script = stage / "floor_py.py"
    script.write_text(PY_SOURCE.format(source=fmu.name, variables=_variables(fmu), cls="FloorPy"), encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=dest, canHandleVariableCommunicationStepSize=True))
