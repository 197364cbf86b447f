"""The native body FMU: an FMI 2.0 (or 3.0) co-simulation FMU in C over the C runtime, with nothing installed beside it.

    binaries/linux64/<id>.so, binaries/win64/<id>.dll   fmi2Functions.c over model.c over runtime/native:
                                                        body-independent, built once per source version and
                                                        target into the cache (fmu/native/build.py)
    resources/body.bin                                  the body: variables, maps and runtime images
                                                        (fmu/native/resource.py), scrambled
    documentation/index.html                            the body's datasheet
    documentation/build.json                            how it was built (model file name and digest, scene)
    modelDescription.xml

FMI 3.0 (`fmi=3`): the same resource and model, fmi3Functions.c in binaries/x86_64-linux/<id>.so and
binaries/x86_64-windows/<id>.dll, and a modelDescription.xml whose port fields are arrays (`fmi3_variables`).

No Python, numpy, .npz, model file or source in the FMU. `build_native_fmu` writes one; the pythonfmu
route (fmu/builder.py `build_fmu`) stays for `--runtime python`.
"""
from __future__ import annotations

import hashlib
import html
from dataclasses import dataclass
import json
import os
import uuid
import zipfile
from datetime import datetime, timezone
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, indent, tostring

import numpy as np

from ... import __version__
from ...runtime.body import BodySystem
from ...runtime.data import BodyData
from ...runtime.terms import TERM_SETS
from ..variables import (DESCRIPTION_BASE, DIRECTIONAL_DERIVATIVES, modal_shape, INPUTS_BETWEEN_COMMUNICATION_POINTS, INTERNAL_STEPS, UNITS,
                         body_variables, equations_text, identifier)
from . import build as native_build
from .resource import ResourceContent, pack

DESCRIPTION = DESCRIPTION_BASE + " (serialized with a version and a checksum)."
RESOURCE_FILE = "body.bin"
PLATFORMS = ("linux64", "win64")


def _images(data: BodyData, config: dict) -> tuple[dict[str, bytes], BodySystem]:
    """One runtime image per term set the body's data allows (full needs W1, W2), with the scene's
    rho_inf and gravity (parameters: the FMU sets them again at initialization); and the default set's body."""
    from ...runtime.native.image import body_image

    images, default = {}, None
    for terms in TERM_SETS:
        if terms == "full" and any(se.W2 is None for se in data.superelements):
            continue
        system = BodySystem(data, terms=terms, rho_inf=config["rho_inf"], gravity=config["gravity"],
                            full_terms=tuple(config["full_terms"]))
        images[terms] = body_image(system)
        if terms == config["terms"]:
            default = system
    return images, default


def _start(v) -> str:
    return str(int(v.start)) if v.type == "Integer" else repr(float(v.start))


# The log categories of the C layer (model.h FMU_LOG_CATEGORIES, model.c fmu_log_category: the same names in the
# same order; tests/test_native_fmu.py switches each by name).
LOG_CATEGORIES = {"logStatusWarning": "warnings", "logStatusDiscard": "discarded steps and why",
                  "logStatusError": "errors and their causes", "logStatusFatal": "fatal errors",
                  "logAll": "everything else"}


def _shared_sections(root, variables, experiment) -> None:
    """The sections FMI 2.0 and 3.0 model descriptions write alike, in the order both schemas want them
    after the interface element: UnitDefinitions (the units the variables use), LogCategories and the
    DefaultExperiment."""
    used = sorted({v.unit for v in variables if v.unit})
    units = SubElement(root, "UnitDefinitions")
    for u in used:
        SubElement(SubElement(units, "Unit", {"name": u}), "BaseUnit", {k: str(e) for k, e in UNITS[u].items()})
    cats = SubElement(root, "LogCategories")
    for cat, text in LOG_CATEGORIES.items():
        SubElement(cats, "Category", {"name": cat, "description": text})
    if experiment:
        SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stopTime": repr(experiment["stop_time"]),
                                               "stepSize": repr(experiment["step_size"])})


def model_description(variables, *, name: str, identifier: str, guid: str, description: str,
                      experiment: dict | None) -> bytes:
    """modelDescription.xml: the variables of fmu/variables.py with units and min/max, co-simulation
    capabilities of the C layer, ModelStructure (no output depends directly on an input:
    fmu/variables.py patch_model_description)."""
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": name, "guid": guid, "description": description,
        "author": "ffrf-fmu", "version": __version__, "generationTool": f"ffrf-fmu {__version__} (native)",
        "generationDateAndTime": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "variableNamingConvention": "structured", "numberOfEventIndicators": "0"})
    SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "needsExecutionTool": "false", "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "false", "maxOutputDerivativeOrder": "0", "canRunAsynchronuously": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true", "providesDirectionalDerivative": "true"})
    _shared_sections(root, variables, experiment)
    mv = SubElement(root, "ModelVariables")
    for vr, v in enumerate(variables):
        attrs = {"name": v.name, "valueReference": str(vr), "description": v.description, "causality": v.causality,
                 "variability": v.variability}
        if v.causality == "output":
            attrs["initial"] = "calculated"
        elif v.causality == "parameter":
            attrs["initial"] = "exact"
        sv = SubElement(mv, "ScalarVariable", attrs)
        typ = {}
        if v.unit:
            typ["unit"] = v.unit
        if v.start is not None:
            typ["start"] = _start(v)
        for key in ("min", "max"):
            bound = getattr(v, key)
            if bound is not None:
                typ[key] = repr(float(bound)) if v.type == "Real" else str(int(bound))
        SubElement(sv, v.type, typ)
    structure = SubElement(root, "ModelStructure")
    outputs = [i + 1 for i, v in enumerate(variables) if v.causality == "output"]
    if outputs:
        o = SubElement(structure, "Outputs")
        for i in outputs:  # no direct feedthrough (fmu/variables.py patch_model_description)
            SubElement(o, "Unknown", {"index": str(i), "dependencies": ""})
        iu = SubElement(structure, "InitialUnknowns")
        for i in outputs:
            SubElement(iu, "Unknown", {"index": str(i)})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


@dataclass(frozen=True)
class Fmi3Variable:
    """One FMI 3.0 variable: a run of consecutive FMI 2.0 scalars of one name (`tip.R[1,1]` .. `tip.R[3,3]` is
    `tip.R` of dimensions [3, 3], row-major, the order of the scalars) or a scalar; fmi3Functions.c
    `build_arrays` groups the same way (consecutive, one base name, type and causality)."""

    name: str
    value_reference: int  # 1.. (0 is time)
    first: int  # the FMI 2.0 value reference of its first element
    shape: tuple[int, ...]  # () for a scalar
    members: tuple  # the fmu/variables.py Variable of each element, in order


def fmi3_variables(variables) -> list[Fmi3Variable]:
    """The FMI 3.0 variables of the FMI 2.0 table `variables` (value references 1, 2, ...; 0 is time)."""
    runs: list[list[int]] = []
    for i, v in enumerate(variables):
        if runs and "[" in v.name:
            f = variables[runs[-1][0]]
            if (v.name.partition("[")[0] == f.name.partition("[")[0] and "[" in f.name and v.type == f.type
                    and v.causality == f.causality):
                runs[-1].append(i)
                continue
        runs.append([i])
    out = []
    for k, run in enumerate(runs):
        members = tuple(variables[i] for i in run)
        first = members[0]
        # the shape of an array: its last element's index, 1-based (P.R[3,3]: (3, 3); modal.eta[E,nm]: (E, nm))
        shape = () if "[" not in first.name else tuple(int(i) for i in members[-1].name.rpartition("[")[2][:-1].split(","))
        out.append(Fmi3Variable(first.name.partition("[")[0], k + 1, run[0], shape, members))
    return out


def _description3(members) -> str:
    texts = {v.description for v in members}
    if len(texts) == 1:
        return members[0].description
    # per-element texts (the probes: "axis 1 of the frame"): said once for the array
    return members[0].description.replace("axis 1 of", "axes 1, 2, 3 (the elements) of")


def model_description3(variables, *, name: str, identifier: str, token: str, description: str,
                       experiment: dict | None) -> bytes:
    """FMI 3.0 modelDescription.xml: the FMI 2.0 FMU's variables as arrays (`fmi3_variables`; Float64 and
    Int32), units, descriptions, start, min and max as in 2.0, the independent variable `time` (value
    reference 0), co-simulation without event mode or intermediate update, directional and adjoint
    derivatives, the ModelStructure of 2.0 (every output depends on every input)."""
    root = Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": name, "instantiationToken": token, "description": description,
        "author": "ffrf-fmu", "version": __version__, "generationTool": f"ffrf-fmu {__version__} (native)",
        "generationDateAndTime": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "variableNamingConvention": "structured"})
    SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "needsExecutionTool": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
        "canGetAndSetFMUState": "true", "canSerializeFMUState": "true", "providesDirectionalDerivatives": "true",
        "providesAdjointDerivatives": "true", "providesPerElementDependencies": "false",
        "canHandleVariableCommunicationStepSize": "true", "maxOutputDerivativeOrder": "0",
        "providesIntermediateUpdate": "false", "mightReturnEarlyFromDoStep": "false",
        "canReturnEarlyAfterIntermediateUpdate": "false", "hasEventMode": "false",
        "providesEvaluateDiscreteStates": "false"})
    _shared_sections(root, variables, experiment)
    mv = SubElement(root, "ModelVariables")
    SubElement(mv, "Float64", {"name": "time", "valueReference": "0", "causality": "independent",
                               "variability": "continuous", "unit": "s", "description": "simulation time"})
    arrays = fmi3_variables(variables)
    for a in arrays:
        v = a.members[0]
        attrs = {"name": a.name, "valueReference": str(a.value_reference), "description": _description3(a.members),
                 "causality": v.causality, "variability": v.variability}
        if v.causality == "output":
            attrs["initial"] = "calculated"
        elif v.causality == "parameter":
            attrs["initial"] = "exact"
        if v.unit:
            attrs["unit"] = v.unit
        for key in ("min", "max"):
            bound = getattr(v, key)
            if bound is not None:
                attrs[key] = repr(float(bound)) if v.type == "Real" else str(int(bound))
        if v.start is not None:
            attrs["start"] = " ".join(_start(m) for m in a.members)
        el = SubElement(mv, "Float64" if v.type == "Real" else "Int32", attrs)
        for n in a.shape:
            SubElement(el, "Dimension", {"start": str(n)})
    structure = SubElement(root, "ModelStructure")
    inputs = [str(a.value_reference) for a in arrays if a.members[0].causality == "input"]
    outputs = [a for a in arrays if a.members[0].causality == "output"]
    deps = {"dependencies": " ".join(inputs), "dependenciesKind": " ".join(["dependent"] * len(inputs))}
    for a in outputs:
        SubElement(structure, "Output", {"valueReference": str(a.value_reference), **deps})
    for a in outputs:
        SubElement(structure, "InitialUnknown", {"valueReference": str(a.value_reference)})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


def datasheet(data: BodyData, system: BodySystem, config: dict, build_info: dict, images: dict, fmi: int = 2,
              start: dict | None = None) -> str:
    """documentation/index.html: what a partner needs to know of the body without its matrices."""
    mass, cm, J = system.mass_properties()
    e = html.escape
    rows = "".join(f"<tr><td>{e(p.name)}</td><td>{np.array2string(data.node_positions[p.node], precision=6)}</td>"
                   f"<td>{e(p.translation)}</td><td>{e(p.rotation)}</td></tr>" for p in data.ports)
    freqs = "".join(f"<tr><td>{k + 1}</td><td>{', '.join(f'{f:.6g}' for f in se.frequencies_hz)}</td></tr>"
                    for k, se in enumerate(data.superelements))
    stiff = all(se.stiffening for se in data.superelements)
    scene = build_info.get("scene")
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{e(data.name)}: body datasheet</title></head>
<body>
<h1>Flexible body {e(data.name)}</h1>
<p>FMI {fmi}.0 co-simulation FMU made by ffrf-fmu {e(__version__)} (native runtime). The body is {len(data.superelements)}
two-field floating-frame superelement(s), each a linear FE beam reduced to its boundary frames and free-free modes,
moving with large rigid motions. All values SI, world axes, at the reference (undeformed) configuration.</p>
<h2>Mass properties</h2>
<p>Mass {mass:.9g} kg; centre of mass {np.array2string(cm, precision=9)} m;
inertia about the centre of mass (kg m<sup>2</sup>):</p><pre>{np.array2string(J, precision=9)}</pre>
<h2>Ports</h2>
<table border="1"><tr><th>port</th><th>reference position (m)</th><th>translation</th><th>rotation</th></tr>{rows}</table>
<h2>Free-free frequencies of the kept modes (Hz), per superelement</h2>
<table border="1"><tr><th>superelement</th><th>frequencies</th></tr>{freqs}</table>
<h2>Equations</h2>
<p>{e(equations_text(config['terms'], config['full_terms'], stiff))}</p>
<p>Term sets in this FMU (parameter solver.terms): {e(', '.join(f'{TERM_SETS.index(t)} = {t}' for t in images))}.</p>
<h2>Validated for</h2>
<p>Built from {e(str(build_info.get('model_file', 'a reduced body')))}{(', scene ' + e(str(scene))) if scene else ''}:
internal step solver.step = {config['step']:g} s by default{(', ' + format(build_info['duration'], 'g') + ' s of simulated time') if build_info.get('duration') else ''}.
Other scenes (speeds, loads, steps) are outside what was checked at build time: compare with a standalone run
(<code>ffrf-fmu validate</code>) before relying on them.</p>
<h2>Initial state</h2>
<p>{('The body starts at the scene&#39;s ' + e(start['state'].replace('_', ' ')) + ' state, made at build time (the '
     'standalone run&#39;s own start): it holds for gravity ' + e(str(start['gravity'])) + ', no initial velocity or '
     'displacement parameters, and the motion inputs the scene&#39;s drives give at t0; other values make the '
     'initialization an error that names them.') if start else
    'The body starts undeformed, with the rigid velocity field of its motion inputs and initial velocity parameters.'}</p>
<h2>Behaviour between communication points</h2>
<p>{e(INPUTS_BETWEEN_COMMUNICATION_POINTS)}</p><p>{e(INTERNAL_STEPS)}</p><p>{e(DIRECTIONAL_DERIVATIVES)}</p>
</body></html>
"""


def build_native_fmu(data: BodyData, dest, params, *, origin=None, build_info: dict | None = None,
                     platforms=PLATFORMS, compiler: str = "zig", log=None, fmi: int = 2, start: dict | None = None) -> Path:
    """Write the native FMU of `data` to `dest` (a .fmu file name or a directory) and return its path.

    params: builder.SceneParameters (parameter defaults); origin: the initial rigid velocity field's origin
    (default: node 0); platforms: binaries to include (linux64, win64); compiler: "zig" (ziglang, every
    platform) or "system" (linux64 only); start: builder.start_states (the FMU initializes there), None: from rest."""
    config = params.as_config()
    build_info = dict(build_info or {})
    if params.duration is not None:
        build_info.setdefault("duration", float(params.duration))
    dest = Path(dest)
    if dest.suffix != ".fmu":
        if dest.suffix and not dest.is_dir():
            raise native_build.NativeBuildError(f"{dest}: an FMU file name must end in .fmu (or name a directory)")
        dest = dest / f"{data.name}.fmu"
    variables = body_variables(data.ports, data.node_positions, config, data.damping, modal_shape(data))
    images, system = _images(data, config)
    if system is None:
        raise native_build.NativeBuildError(f"term set {config['terms']!r} needs the inertia data W1, W2 (build the "
                                            "body with them)")
    from ...runtime.native.image import VERSION as RUNTIME_VERSION

    origin = np.asarray(origin if origin is not None else data.node_positions[0], dtype=float)
    ports_text = ", ".join(f"{p.name} (translation {p.translation}, rotation {p.rotation})" for p in data.ports)
    stiff = all(se.stiffening for se in data.superelements)
    description = (DESCRIPTION.format(body=data.name, n_se=len(data.superelements), ports=ports_text) + " "
                   + equations_text(config["terms"], config["full_terms"], stiff) + " " + DIRECTIONAL_DERIVATIVES)
    # the GUID: a digest of everything the binary reads (same body and settings, same GUID)
    digest = hashlib.sha256()
    for image in images.values():
        digest.update(image)
    for arrays in (start or {}).get("terms", {}).values():  # a start state is part of what the binary reads
        for k in sorted(arrays):
            digest.update(np.ascontiguousarray(arrays[k], dtype=float).tobytes())
    digest.update(json.dumps({"config": config, "origin": origin.tolist(),
                              "variables": [(v.name, v.causality, v.start) for v in variables]}).encode())
    guid = "{" + str(uuid.UUID(bytes=digest.digest()[:16], version=4)) + "}"
    model_id = f"{identifier(data.name)}_{digest.hexdigest()[:8]}"
    content = ResourceContent(guid=guid, about=f"body {data.name} (ffrf-fmu {__version__})", variables=variables,
                              ports=list(data.ports), probes=list(config.get("probes", ())),
                              node_positions=np.asarray(data.node_positions, dtype=float), origin=origin,
                              images=images, start=start)
    experiment = {"stop_time": float(params.duration), "step_size": float(params.step)} if params.duration else None
    if fmi == 3:
        xml = model_description3(variables, name=data.name, identifier=model_id, token=guid,
                                 description=description.replace("fmi2", "fmi3").replace("SetFMUstate", "SetFMUState"),
                                 experiment=experiment)
    elif fmi == 2:
        xml = model_description(variables, name=data.name, identifier=model_id, guid=guid, description=description,
                                experiment=experiment)
    else:
        raise native_build.NativeBuildError(f"FMI version must be 2 or 3, got {fmi!r}")
    binaries = {p: native_build.binary(p, compiler, log=log, fmi=fmi) for p in platforms}
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_name(dest.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", xml)
        z.writestr(f"resources/{RESOURCE_FILE}", pack(content, RUNTIME_VERSION))
        z.writestr("documentation/index.html", datasheet(data, system, config, build_info, images, fmi, start))
        z.writestr("documentation/build.json", json.dumps({  # how it was made (no body data)
            "ffrf_fmu_version": __version__, "runtime_version": RUNTIME_VERSION, "body": data.name,
            "term_sets": list(images), "platforms": list(binaries), "compiler": compiler, "fmi_version": f"{fmi}.0",
            "build": build_info},
            indent=1))
        for platform, path in binaries.items():
            target = native_build.TARGETS[platform]
            z.write(path, f"binaries/{target.platform if fmi == 2 else target.platform3}/{model_id}{target.suffix}")
    os.replace(tmp, dest)
    return dest
