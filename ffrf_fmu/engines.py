"""Established co-simulation engines that cross-check ours, loaded the same way everywhere
(tests, .ci/check_imports.py, stability maps), and how they are run.

ecospy's engine library (libecosc.so) links against TBB's libtbb.so.12, which its wheel does not
ship. The PyPI package `tbb` (in the test extra) installs that library into <prefix>/lib, which the
dynamic loader does not search; loading it by path with RTLD_GLOBAL first lets libecosc.so find
it already loaded (by its soname), so no system package is needed.
"""
from __future__ import annotations

import ctypes
import importlib
import importlib.metadata
from types import ModuleType

TBB_LIBRARY = "libtbb.so.12"


def load_tbb() -> str | None:
    """Load the `tbb` package's libtbb.so.12 globally; its path, or None when that package is not
    installed (the system's TBB, if any, is then left to the loader)."""
    try:
        files = importlib.metadata.files("tbb") or []
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files:
        if f.name == TBB_LIBRARY:
            path = str(f.locate().resolve())
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            return path
    return None


def import_ecospy() -> ModuleType:
    """`import ecospy` with its TBB dependency loaded first (module doc)."""
    load_tbb()
    return importlib.import_module("ecospy")


# ------------------------------------------------------------------------------ libcosim
#
# libcosim (Open Simulation Platform, PyPI package libcosimpy) runs FMUs with its fixed-step
# algorithm: every slave gets its inputs from the outputs at t_c, then all step: a Jacobi scheme
# with held inputs, i.e. master.CoSimulation(scheme="jacobi", extrapolation=False). A connection
# with a gain is an ssc:LinearTransformation connection of a generated SSD.


def write_ssd(path, components: dict[str, str], connections: list[tuple[str, str, float]]) -> Path:
    """Write a SystemStructure.ssd: components {name: fmu file}, connections (src, dst, factor) with
    src and dst `instance.variable`; every connected variable is declared as a connector (libcosim
    requires it)."""
    from pathlib import Path

    used: dict[str, dict[str, str]] = {name: {} for name in components}
    for src, dst, _ in connections:
        se, sc = src.split(".", 1)
        de, dc = dst.split(".", 1)
        used[se][sc] = "output"
        used[de][dc] = "input"
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             '<ssd:SystemStructureDescription name="ffrf" version="1.0" '
             'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
             'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">',
             '  <ssd:System name="ffrf">', "    <ssd:Elements>"]
    for name, src in components.items():
        lines += [f'      <ssd:Component name="{name}" source="{src}">', "        <ssd:Connectors>"]
        lines += [f'          <ssd:Connector name="{c}" kind="{k}"><ssc:Real/></ssd:Connector>' for c, k in used[name].items()]
        lines += ["        </ssd:Connectors>", "      </ssd:Component>"]
    lines += ["    </ssd:Elements>", "    <ssd:Connections>"]
    for src, dst, factor in connections:
        se, sc = src.split(".", 1)
        de, dc = dst.split(".", 1)
        head = f'      <ssd:Connection startElement="{se}" startConnector="{sc}" endElement="{de}" endConnector="{dc}"'
        if factor == 1.0:
            lines.append(head + "/>")
        else:
            lines += [head + ">", f'        <ssc:LinearTransformation factor="{factor!r}" offset="0.0"/>',
                      "      </ssd:Connection>"]
    lines += ["    </ssd:Connections>", "  </ssd:System>", '  <ssd:DefaultExperiment startTime="0.0"/>',
              "</ssd:SystemStructureDescription>"]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def libcosim_run(fmus: dict[str, str], connections: list[tuple[str, str, float]], start_values: dict[str, float],
                 H: float, duration: float, record: list[str], work_dir, sources=None):
    """Run FMUs {instance: fmu path} joined by `connections` under libcosim's fixed-step algorithm
    with communication step H; start_values and record as `instance.variable`; sources(t) ->
    {`instance.variable`: value} set before each step (an override manipulator).

    Returns (times, {recorded name: values}, stopped, wall time of the stepping): one sample per
    step, at its end; stopped is "" or the step that failed."""
    import shutil
    import time
    from pathlib import Path

    import numpy as np
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    comps = {}
    for name, fmu in fmus.items():
        shutil.copy(fmu, work / Path(fmu).name)
        comps[name] = Path(fmu).name
    ssd = write_ssd(work / "SystemStructure.ssd", comps, connections)
    ex = CosimExecution.from_ssp_file(str(ssd), step_size=int(round(H * 1e9)))
    index = {info.name.decode(): info.index for info in ex.slave_infos()}
    refs = {n: {v.name.decode(): v.reference for v in ex.slave_variables(i)} for n, i in index.items()}

    def ref(full: str) -> tuple[int, int]:
        inst, var = full.split(".", 1)
        return index[inst], refs[inst][var]

    for full, value in start_values.items():
        ex.real_initial_value(*ref(full), float(value))
    observer = CosimObserver.create_last_value()
    ex.add_observer(observer)
    manip = CosimManipulator.create_override()
    ex.add_manipulator(manip)
    by_instance: dict[str, list[str]] = {}
    for full in record:
        by_instance.setdefault(full.split(".", 1)[0], []).append(full)

    def apply_sources(t: float) -> None:
        if sources:
            for full, value in sources(t).items():
                i, r = ref(full)
                manip.slave_real_values(i, [r], [value])

    t0 = time.perf_counter()
    rows, times, stopped = [], [], ""
    apply_sources(0.0)
    for k in range(int(round(duration / H))):
        apply_sources(k * H)
        if not ex.step(1):
            stopped = f"libcosim: step at t = {k * H:.6g} s failed"
            break
        row = {}
        for inst, names in by_instance.items():
            row.update(zip(names, observer.last_real_values(index[inst], [ref(n)[1] for n in names])))
        rows.append(row)
        times.append((k + 1) * H)
    wall = time.perf_counter() - t0
    del ex
    return np.array(times), {n: np.array([r[n] for r in rows]) for n in record}, stopped, wall
