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
    {`instance.variable`: value} set before each step (an override manipulator). The system is a
    SystemStructure.ssd written by `write_ssd` next to copies of the FMUs (master/ssp.py writes
    whole packages; it imports this module, not the other way round).

    Returns (times, {recorded name: values}, stopped, wall time of the stepping): one sample per
    step, at its end; stopped is "" or the step that failed."""
    import shutil
    from pathlib import Path

    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    comps = {}
    for name, fmu in fmus.items():
        shutil.copy(fmu, work / Path(fmu).name)
        comps[name] = Path(fmu).name
    ssd = write_ssd(work / "SystemStructure.ssd", comps, connections)
    return libcosim_run_ssp(ssd, H, int(round(duration / H)), record, 0.0, sources, start_values)


def libcosim_run_ssp(path, H: float, n: int, record: list[str], start: float = 0.0, sources=None,
                     start_values: dict[str, float] | None = None):
    """n steps of H of an SSP package (or a SystemStructure.ssd) under libcosim's fixed-step
    algorithm (libcosimpy `CosimExecution.from_ssp_file`: components, connections with their linear
    transformations and the package's parameter set as initial values; start_values, if given, as
    further initial values); returns as `libcosim_run`."""
    import time

    import numpy as np
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    ex = CosimExecution.from_ssp_file(str(path), step_size=int(round(H * 1e9)))
    index = {info.name.decode(): info.index for info in ex.slave_infos()}
    refs = {name: {v.name.decode(): v.reference for v in ex.slave_variables(i)} for name, i in index.items()}

    def ref(full: str) -> tuple[int, int]:
        inst, var = full.split(".", 1)
        return index[inst], refs[inst][var]

    for full, value in (start_values or {}).items():
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
    apply_sources(start)
    for k in range(n):
        apply_sources(start + k * H)
        if not ex.step(1):
            stopped = f"libcosim: step at t = {start + k * H:.6g} s failed"
            break
        row = {}
        for inst, names in by_instance.items():
            row.update(zip(names, observer.last_real_values(index[inst], [ref(n)[1] for n in names])))
        rows.append(row)
        times.append(start + (k + 1) * H)
    wall = time.perf_counter() - t0
    del ex
    return np.array(times), {n: np.array([r[n] for r in rows]) for n in record}, stopped, wall


def ecos_run_ssp(path, H: float, n: int, record: list[str], parameter_set: str | None):
    """n steps of H of an SSP package under ecos's fixed-step algorithm (ecospy
    `EcosSimulation(ssp_path=...)`, the package's parameter set applied at init); returns as
    `libcosim_run`. ecos names variables `instance::variable`. ecos goes on after an FMU refused a
    step (docs/cosim.md, "The engines"): a failure shows only as an exception of its step call."""
    import time

    import numpy as np

    ecospy = import_ecospy()
    t0 = time.perf_counter()
    rows, times, stopped = [], [], ""
    names = [full.replace(".", "::", 1) for full in record]
    with ecospy.EcosSimulation(step_size=H, ssp_path=str(path)) as sim:
        sim.init(parameter_set=parameter_set) if parameter_set else sim.init()
        t_start = sim.get_time() if hasattr(sim, "get_time") else 0.0
        for k in range(n):
            try:
                sim.step(1)
            except Exception as e:  # noqa: BLE001 - the engine's report, kept as the run's failure
                stopped = f"ecos: step at t = {t_start + k * H:.6g} s failed: {e}"
                break
            rows.append([sim.get_real(v) for v in names])
            times.append(t_start + (k + 1) * H)
        sim.terminate()
    cols = {full: np.array([r[i] for r in rows]) for i, full in enumerate(record)}
    return np.array(times), cols, stopped, time.perf_counter() - t0
