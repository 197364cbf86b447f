"""SSP 1.0 system packages: one file that libcosim, ecos and this project's master all run.

A package (`.ssp`, a zip) holds
    SystemStructure.ssd   the system: components (FMUs), their connectors, the connections
                          (a gain as ssc:LinearTransformation), the parameters (an inline
                          ssv:ParameterSet named PARAMETER_SET in each component's
                          ssd:ParameterBindings) and the default experiment (start, stop, and the
                          communication step as libcosim's fixed-step annotation);
    resources/NAME.fmu    every FMU the components name.

`write_ssp` writes one; `read_ssp` reads one back (a `System`); `run_ssp` runs one under
    "master"    ffrf_fmu.master.CoSimulation, scheme "jacobi" (inputs from the outputs at t_c, held);
    "libcosim"  libcosimpy's fixed-step algorithm (the same Jacobi with held inputs);
    "ecos"      ecospy's fixed-step algorithm (the same).
So the three run the same discrete map and agree to round-off (tests/test_ssp.py). What each
engine does on a step an FMU refuses: docs/cosim.md, "The engines".

Connections join scalar variables; `expand` turns a port field (`beam.hub.R`) into its scalars
(docs/fmu.md names, runtime/outputs.port_variables) and `body_port_connections` wires two body ports
(master.body_port_links: the motion-driven side gets the frame and rates, the force-driven side
minus the reaction) as plain connections, which is what an SSP engine can run.
"""
from __future__ import annotations

import shutil
import tempfile
import time
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..runtime.steps import divides, whole_steps

SSD = "SystemStructure.ssd"
PARAMETER_SET = "initial"  # the one parameter set of a package (ecos applies sets by name at init)
NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
      "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}
ENGINES = ("master", "libcosim", "ecos")


class SspError(ValueError):
    """A package or a system description that cannot be written, read or run as asked."""


@dataclass(frozen=True)
class Connection:
    """dst <- factor * src + offset, src and dst `instance.variable` (scalars)."""

    src: str
    dst: str
    factor: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class System:
    """What a package describes. components: instance -> FMU path (inside the package: its
    `resources/...` source; after read_ssp: the extracted file)."""

    name: str
    components: dict[str, str]
    connections: tuple[Connection, ...]
    parameters: dict[str, float] = field(default_factory=dict)  # instance.variable -> value
    step: float = 1e-3
    start: float = 0.0
    stop: float = 1.0


@dataclass
class SspRun:
    """A run of a package: one sample per communication step at its end (t > start), the recorded
    variables by name; stopped is "" or what stopped the run early; wall: seconds of stepping."""

    t: np.ndarray
    columns: dict[str, np.ndarray]
    stopped: str
    wall: float
    engine: str


def _split(full: str) -> tuple[str, str]:
    inst, sep, var = full.partition(".")
    if not sep or not var:
        raise SspError(f"{full!r}: expected '<instance>.<variable>'")
    return inst, var


def expand(full: str, variables: Sequence[str]) -> list[str]:
    """`inst.var` when var is one of `variables` (an FMU's names), else the scalars of a port field
    `inst.port.field` (docs/fmu.md: r, v, a, f, t, w, dw as [1..3], R as [i,j] row by row)."""
    from ..fmu.variables import port_variables

    inst, var = _split(full)
    if var in variables:
        return [full]
    port, _, fld = var.rpartition(".")
    if port:
        try:
            names = port_variables(port, fld)
        except (KeyError, ValueError):
            names = []
        if names and all(n in variables for n in names):
            return [f"{inst}.{n}" for n in names]
    raise SspError(f"{full!r}: no such variable, nor a port field whose variables the FMU has")


def body_port_connections(a: str, port_a: str, b: str, port_b: str, fmus: dict[str, str]) -> list[Connection]:
    """The connections of a rigid joint of two body ports (master.body_port_links) as plain signals."""
    from .instance import FmuInstance
    from .links import Motion, body_port_links, port_causality

    ia, ib = FmuInstance(a, fmus[a]), FmuInstance(b, fmus[b])
    try:
        links = body_port_links(a, port_a, b, port_b, port_causality(ia, port_a), port_causality(ib, port_b))
    finally:
        ia.close()
        ib.close()
    out = []
    for link in links:
        if isinstance(link, Motion):
            out += [Connection(s, d) for s, d in zip(link.src, link.dst)]
        else:
            out.append(Connection(link.src, link.dst, link.gain))
    return out


def _model_variables(fmu: str) -> dict[str, object]:
    from fmpy import read_model_description

    return {v.name: v for v in read_model_description(str(fmu)).modelVariables}


def check(system: System) -> None:
    """Every connection joins an output to an input of Real variables of named components, every
    input has at most one source, every parameter exists and is settable: else SspError naming it."""
    vars_of = {name: _model_variables(path) for name, path in system.components.items()}

    def var(full: str):
        inst, v = _split(full)
        if inst not in vars_of:
            raise SspError(f"{full!r}: no component {inst!r} (components: {', '.join(vars_of)})")
        if v not in vars_of[inst]:
            raise SspError(f"{full!r}: FMU {Path(system.components[inst]).name} has no variable {v!r}")
        return vars_of[inst][v]

    sinks = set()
    for c in system.connections:
        s, d = var(c.src), var(c.dst)
        if s.causality != "output":
            raise SspError(f"connection {c.src} -> {c.dst}: {c.src} is a {s.causality}, not an output")
        if d.causality != "input":
            raise SspError(f"connection {c.src} -> {c.dst}: {c.dst} is a {d.causality}, not an input")
        if s.type != "Real" or d.type != "Real":
            raise SspError(f"connection {c.src} -> {c.dst}: only Real variables are connected")
        if c.dst in sinks:
            raise SspError(f"{c.dst} has two sources")
        sinks.add(c.dst)
    for full in system.parameters:
        v = var(full)
        if v.causality not in ("parameter", "input") or v.variability == "constant":
            raise SspError(f"parameter {full}: a {v.causality} ({v.variability}) variable cannot be set")
    if not (system.step > 0 and system.stop > system.start):
        raise SspError(f"step {system.step!r} must be > 0 and stop {system.stop!r} > start {system.start!r}")


def _text(system: System, sources: dict[str, str]) -> str:
    """The SystemStructure.ssd of a system whose components are `sources` (paths in the package)."""
    vars_of = {name: _model_variables(path) for name, path in system.components.items()}
    used: dict[str, dict[str, str]] = {name: {} for name in system.components}
    for c in system.connections:
        (si, sv), (di, dv) = _split(c.src), _split(c.dst)
        used[si][sv], used[di][dv] = "output", "input"
    params: dict[str, dict[str, float]] = {name: {} for name in system.components}
    for full, value in system.parameters.items():
        inst, v = _split(full)
        params[inst][v] = float(value)
        used[inst].setdefault(v, vars_of[inst][v].causality)
    q = lambda s: s.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")  # noqa: E731
    L = ['<?xml version="1.0" encoding="UTF-8"?>',
         f'<ssd:SystemStructureDescription name="{q(system.name)}" version="1.0" xmlns:ssd="{NS["ssd"]}" '
         f'xmlns:ssc="{NS["ssc"]}" xmlns:ssv="{NS["ssv"]}" xmlns:osp="{NS["osp"]}">',
         f'  <ssd:System name="{q(system.name)}">', "    <ssd:Elements>"]
    for name in system.components:
        L += [f'      <ssd:Component name="{q(name)}" source="{q(sources[name])}" type="application/x-fmu-sharedlibrary">',
              "        <ssd:Connectors>"]
        L += [f'          <ssd:Connector name="{q(v)}" kind="{k}"><ssc:Real/></ssd:Connector>' for v, k in used[name].items()]
        L.append("        </ssd:Connectors>")
        if params[name]:
            L += ["        <ssd:ParameterBindings>", "          <ssd:ParameterBinding>", "            <ssd:ParameterValues>",
                  f'              <ssv:ParameterSet version="1.0" name="{PARAMETER_SET}">', "                <ssv:Parameters>"]
            L += [f'                  <ssv:Parameter name="{q(v)}"><ssv:Real value="{x!r}"/></ssv:Parameter>'
                  for v, x in params[name].items()]
            L += ["                </ssv:Parameters>", "              </ssv:ParameterSet>", "            </ssd:ParameterValues>",
                  "          </ssd:ParameterBinding>", "        </ssd:ParameterBindings>"]
        L.append("      </ssd:Component>")
    L += ["    </ssd:Elements>", "    <ssd:Connections>"]
    for c in system.connections:
        (si, sv), (di, dv) = _split(c.src), _split(c.dst)
        head = (f'      <ssd:Connection startElement="{q(si)}" startConnector="{q(sv)}" endElement="{q(di)}" '
                f'endConnector="{q(dv)}"')
        if c.factor == 1.0 and c.offset == 0.0:
            L.append(head + "/>")
        else:
            L += [head + ">", f'        <ssc:LinearTransformation factor="{c.factor!r}" offset="{c.offset!r}"/>',
                  "      </ssd:Connection>"]
    L += ["    </ssd:Connections>", "  </ssd:System>",
          f'  <ssd:DefaultExperiment startTime="{system.start!r}" stopTime="{system.stop!r}">',
          "    <ssd:Annotations>", '      <ssc:Annotation type="com.opensimulationplatform">',
          f'        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="{system.step!r}"/></osp:Algorithm>',
          "      </ssc:Annotation>", "    </ssd:Annotations>", "  </ssd:DefaultExperiment>",
          "</ssd:SystemStructureDescription>"]
    return "\n".join(L) + "\n"


def write_ssp(path, system: System) -> Path:
    """Write `system` (components: FMU files on disk) as an SSP 1.0 package at `path` (.ssp), the
    FMUs copied to resources/<instance>.fmu; checked first (`check`)."""
    check(system)
    path = Path(path)
    sources = {name: f"resources/{name}.fmu" for name in system.components}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(SSD, _text(system, sources))
        for name, fmu in system.components.items():
            z.write(fmu, sources[name])
    return path


def read_ssp(path, into=None) -> System:
    """A package (or a directory holding SystemStructure.ssd) as a System whose components are the
    extracted FMU files (into: a directory, default a new temporary one)."""
    path = Path(path)
    if path.is_dir():
        root = path
    else:
        if not zipfile.is_zipfile(path):
            raise SspError(f"{path}: not an SSP package (a zip with {SSD})")
        root = Path(into) if into else Path(tempfile.mkdtemp(prefix="ffrf_ssp_"))
        with zipfile.ZipFile(path) as z:
            z.extractall(root)
    if not (root / SSD).is_file():
        raise SspError(f"{path}: no {SSD}")
    doc = ET.parse(root / SSD).getroot()
    if doc.get("version") != "1.0":
        raise SspError(f"{path}: SSP version {doc.get('version')!r}, expected 1.0")
    sysnode = doc.find("ssd:System", NS)
    comps, params = {}, {}
    for c in sysnode.findall("ssd:Elements/ssd:Component", NS):
        name, src = c.get("name"), c.get("source")
        if not (root / src).is_file():
            raise SspError(f"{path}: component {name!r}: no file {src!r} in the package")
        comps[name] = str(root / src)
        for p in c.findall("ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterValues/ssv:ParameterSet/"
                           "ssv:Parameters/ssv:Parameter", NS):
            real = p.find("ssv:Real", NS)
            if real is None:
                raise SspError(f"{path}: parameter {name}.{p.get('name')}: only ssv:Real values are read")
            params[f"{name}.{p.get('name')}"] = float(real.get("value"))
    conns = []
    for c in sysnode.findall("ssd:Connections/ssd:Connection", NS):
        lt = c.find("ssc:LinearTransformation", NS)
        conns.append(Connection(f"{c.get('startElement')}.{c.get('startConnector')}",
                                f"{c.get('endElement')}.{c.get('endConnector')}",
                                float(lt.get("factor", 1.0)) if lt is not None else 1.0,
                                float(lt.get("offset", 0.0)) if lt is not None else 0.0))
    ex = doc.find("ssd:DefaultExperiment", NS)
    start = float(ex.get("startTime", 0.0)) if ex is not None else 0.0
    stop = float(ex.get("stopTime", start + 1.0)) if ex is not None else start + 1.0
    fixed = doc.find("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation/osp:Algorithm/osp:FixedStepAlgorithm", NS)
    step = float(fixed.get("baseStepSize")) if fixed is not None else 1e-3
    return System(sysnode.get("name") or doc.get("name") or "system", comps, tuple(conns), params, step, start, stop)


# ------------------------------------------------------------------------------------------ running
def run_ssp(path, engine: str, record: Sequence[str], step: float | None = None, stop: float | None = None,
            sources: Callable[[float], dict] | None = None, work_dir=None) -> SspRun:
    """Run a package under `engine` (ENGINES) with the communication step and stop time of its
    default experiment (or `step`, `stop`), recording `record` (`instance.variable`) at the end of
    every step; sources(t) -> {`instance.variable`: value} overrides inputs before each step
    (master and libcosim)."""
    if engine not in ENGINES:
        raise SspError(f"engine {engine!r}: one of {', '.join(ENGINES)}")
    work = Path(work_dir) if work_dir else Path(tempfile.mkdtemp(prefix="ffrf_ssp_run_"))
    system = read_ssp(path, work / "package")
    H = system.step if step is None else float(step)
    T = (system.stop if stop is None else float(stop)) - system.start
    if not (T > 0.0 and H > 0.0) or not divides(T, H):  # runtime/steps.py: the project's one rule
        raise SspError(f"{path}: duration {T!r} s is not a whole number of steps {H!r} s")
    n = whole_steps(T, H).n
    if engine == "master":
        out = _run_master(system, H, n, record, sources)
    elif engine == "libcosim":
        from ..engines import libcosim_run_ssp

        out = libcosim_run_ssp(Path(path), H, n, record, system.start, sources)
    else:
        if sources is not None:
            raise SspError("ecos: input sources are not supported (connect a source FMU instead)")
        from ..engines import ecos_run_ssp

        out = ecos_run_ssp(Path(path), H, n, record, PARAMETER_SET if system.parameters else None)
    t, cols, stopped, wall = out
    if work_dir is None:
        shutil.rmtree(work, ignore_errors=True)
    return SspRun(np.asarray(t, float), {k: np.asarray(v, float) for k, v in cols.items()}, stopped, wall, engine)


def _run_master(system: System, H: float, n: int, record, sources):
    from .schemes import CoSimulation

    for c in system.connections:
        if c.offset != 0.0:
            raise SspError(f"connection {c.src} -> {c.dst}: the master takes gains only (offset {c.offset!r})")
    t0 = time.perf_counter()
    with CoSimulation(system.components, step=H, scheme="jacobi", start_values=dict(system.parameters)) as sim:
        for c in system.connections:
            sim.connect(c.src, c.dst, c.factor)
        res = sim.run(system.start + n * H, start_time=system.start, record=list(record), sources=sources)
    # the master records the start point too; the engines sample the step ends only
    keep = res.t > system.start + 0.5 * H
    return res.t[keep], {k: np.asarray(v)[keep] for k, v in res.columns.items()}, res.stopped_early, time.perf_counter() - t0


# ------------------------------------------------------------------------------------ command line
def parse_connection(text: str, variables: dict[str, Sequence[str]]) -> list[Connection]:
    """`SRC:DST` or `SRC:DST:GAIN`, each side a variable or a port field of one component
    (`expand`; fields join element by element)."""
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise SspError(f"--connect {text!r}: expected SRC:DST or SRC:DST:GAIN")
    try:
        gain = float(parts[2]) if len(parts) == 3 else 1.0
    except ValueError:
        raise SspError(f"--connect {text!r}: gain {parts[2]!r} is not a number") from None
    side = lambda full: expand(full, variables.get(_split(full)[0], ()))  # noqa: E731
    src, dst = side(parts[0]), side(parts[1])
    if len(src) != len(dst):
        raise SspError(f"--connect {text!r}: {len(src)} source variables against {len(dst)} sinks")
    return [Connection(s, d, gain) for s, d in zip(src, dst)]


def system_from_arguments(name: str, fmus: Sequence[str], ports: Sequence[str], connects: Sequence[str],
                          sets: Sequence[str], step: float, stop: float) -> System:
    """The `ffrf-fmu system write` arguments as a System: --fmu NAME=FILE, --ports A.P:B.Q (a rigid
    joint of two body ports), --connect SRC:DST[:GAIN], --set INSTANCE.VARIABLE=VALUE."""
    comps = {}
    for f in fmus:
        inst, sep, file = f.partition("=")
        if not sep or not inst or not file:
            raise SspError(f"--fmu {f!r}: expected NAME=FILE.fmu")
        if not Path(file).is_file():
            raise SspError(f"--fmu {f!r}: no file {file!r}")
        comps[inst] = file
    variables = {inst: list(_model_variables(path)) for inst, path in comps.items()}
    conns: list[Connection] = []
    for p in ports:
        a, sep, b = p.partition(":")
        (ia, pa), (ib, pb) = _split(a), _split(b) if sep else ("", "")
        if not sep or ia not in comps or ib not in comps:
            raise SspError(f"--ports {p!r}: expected A.PORT:B.PORT with A and B among the --fmu names")
        conns += body_port_connections(ia, pa, ib, pb, comps)
    for c in connects:
        conns += parse_connection(c, variables)
    params = {}
    for s in sets:
        k, sep, v = s.partition("=")
        try:
            params[k] = float(v)
        except ValueError:
            raise SspError(f"--set {s!r}: expected INSTANCE.VARIABLE=NUMBER") from None
        if not sep:
            raise SspError(f"--set {s!r}: expected INSTANCE.VARIABLE=NUMBER")
    return System(name, comps, tuple(conns), params, float(step), 0.0, float(stop))


def write_csv(path, run: SspRun) -> None:
    import csv

    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        names = list(run.columns)
        w.writerow(["time", *names])
        for i, t in enumerate(run.t):
            w.writerow([repr(float(t)), *(repr(float(run.columns[n][i])) for n in names)])
