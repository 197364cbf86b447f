"""The FMU variables of a body (docs/fmu.md): names, causality, units, descriptions.

One table, `body_variables`, drives everything: the slave registers it with pythonfmu, the
builder writes the unit definitions and the ModelStructure from it, validate.py and master/
read names from it. Shipped inside every FMU: the standard library and the runtime's constants
(runtime.terms, runtime.rotation), no pythonfmu.

Value references are the positions in the returned list. Index conventions: `P.r[i]` i = 1..3,
`P.R[i,j]` = component i (world axis) of nodal axis j, both 1-based. The names are made by
`port_variable` / `port_variables` (and `component_name` for the non-port vectors) and read back
by `parse_port_variable`, all in runtime/outputs.py (imported here): the standalone run's columns,
the master's connections, the fmpy input tables and the studies all use these.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from xml.etree.ElementTree import Element, SubElement

from ..runtime.outputs import (ENERGIES, FIELDS, OUTPUT_FIELDS, _indices, component_name, field_shape,  # noqa: F401
                               parse_port_variable, port_variable, port_variables)
from ..runtime.rotation import ROTATION_TOL
from ..runtime.terms import TERM_SETS

# FMI 2.0 unit definitions (BaseUnit exponents of SI base units; rad is FMI's extra base unit)
UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
    "J": {"kg": 1, "m": 2, "s": -2},
    "s": {"s": 1},
    "1/s": {"s": -1},
}

# Witteveen's terms of the set `full` (runtime.terms.FULL_TERMS, docs/inertia-terms.md), what each adds
FULL_TERM_TEXT = {
    "inertia_W1": "inertia_W1 (inertia tensor change W1 q, with the constant centrifugal load on the modes)",
    "inertia_W2": "inertia_W2 (inertia tensor change q W2 q, with the elastic centrifugal force)",
    "inertia_coupling": "inertia_coupling (rotation-elastic coupling S(q) in the angular momentum)",
    "coriolis": "coriolis (elastic Coriolis force G(W0) on the elastic coordinates)",
}


def identifier(text: str) -> str:
    """A C/Python identifier made of a body name (the FMU's model identifier, module and class names)."""
    s = re.sub(r"\W", "_", text)
    return s if re.match(r"[A-Za-z_]", s) else f"b_{s}"


def equations_text(terms: str, full_terms, stiffening: bool) -> str:
    """The sentence of the modelDescription that says which terms the body equations hold (the one
    source of that text: builder.py's description, docs/fmu.md)."""
    on = [FULL_TERM_TEXT[k] for k in FULL_TERM_TEXT if k in full_terms]
    full = f"Witteveen's terms on in `full`: {', '.join(on) if on else 'none'}"
    off = [k for k in FULL_TERM_TEXT if k not in full_terms]
    return (f"Term set (parameter solver.terms): {terms} by default. {full}"
            + (f"; off: {', '.join(off)}" if off else "") + " (fixed at build). "
            + "Geometric stiffening inside each superelement: "
            + ("on (centrifugal correction modes, W1 inertia, second-order membrane strain; built into the reduced data)."
               if stiffening else "off."))

PART_FIELDS = {"translation": ("r", "v", "f", "a"), "rotation": ("R", "w", "t", "dw")}
# a, dw: inputs of a motion-driven part (extrapolation), outputs of a force-driven one (the node's accelerations)
ACCELERATION_OUTPUT = (
    "the true acceleration at the communication point: the time derivative of the node's velocity there, from "
    "the rates of the velocity field the step ending there solved for (not the generalized-alpha "
    "acceleration-like variable; docs/fmu.md)"
)

# The rules below are the one source of what the FMU does between communication points: the
# variable descriptions, the modelDescription text (builder.DESCRIPTION) and docs/fmu.md quote them
# (tests/test_fmu.py checks that the docs carry them verbatim).
INPUTS_BETWEEN_COMMUNICATION_POINTS = (
    "The values set before doStep(t_c, H) are the values at t_c. Over [t_c, t_c + H] motion inputs are "
    "extrapolated to second order with their rates and accelerations (world axes): "
    "r(t) = r_c + v_c s + a_c s^2/2, v(t) = v_c + a_c s, R(t) = expm(skew(w_c s + dw_c s^2/2)) R_c, "
    "w(t) = w_c + dw_c s, with s = t - t_c (the accelerations default to 0: first order); force and "
    "moment inputs are held."
)
INTERNAL_STEPS = (
    "The body takes n equal internal steps H/n, n = ceil(H/solver.step) (n = H/solver.step when that "
    "is a whole number up to 1e-6 relative): no step is shortened, so the body keeps its Newton "
    "iteration matrix."
)
# The modelDescription's description of a body FMU (the Python and the native FMU end it each with
# what their state serialization adds): str.format with body, n_se, ports.
DESCRIPTION_BASE = (
    "Flexible body {body!r} (two-field FFRF superelements, {n_se} superelement(s), ports: {ports}). "
    "All vectors in world axes, SI units. " + INPUTS_BETWEEN_COMMUNICATION_POINTS + " " + INTERNAL_STEPS + " "
    "The run converges to the standalone run as H shrinks. Outputs are the values at "
    "the end of the last communication step (no direct feedthrough). A failed step (Newton, NaN input, "
    "an R input that is not a rotation) returns fmi2Discard with a logged message and leaves the FMU "
    "at t_c; invalid parameters, calls out of sequence, stepping on after a discard, unknown value "
    "references and internal errors return fmi2Error with the cause logged. FMU state get/set/serialize "
    "save the complete integrator state"
)
DIRECTIONAL_DERIVATIVES = (
    "fmi2GetDirectionalDerivative (FMI 3.0: fmi3GetDirectionalDerivative, fmi3GetAdjointDerivative) gives what FMI "
    "defines, in step mode: the partial derivatives of the outputs with respect to the inputs at the current "
    "communication point, all zero, since no output depends directly on an input (ModelStructure "
    "dependencies=\"\"). The derivatives of the last communication step, which an implicit co-simulation master "
    "needs, are not an FMI function: the binary also exports ffrf2GetStepDerivative (FMI 3.0: "
    "ffrf3GetStepDirectionalDerivative, ffrf3GetStepAdjointDerivative) with the arguments and statuses of "
    "the directional (and adjoint) derivative. They are of the outputs at t_c + H with respect to the inputs as "
    "set for doStep(t_c, H), held and extrapolated over the step as above, with the state at t_c fixed; "
    "available after a successful doStep until the next doStep or fmi2SetFMUstate; taken by central "
    "differences of two re-runs of that step from the saved state at t_c (input steps: 1e-2 max(1, |load|) for "
    "forces and moments, 1e-5 m or rad of displacement over the step for motions), not by an analytic tangent."
)
# fmi2GetDirectionalDerivative and ffrf2GetStepDerivative reach the slave through pythonfmu's own per-instance
# fmi2SetReal and fmi2GetReal on value references offset by these (no FMU has 2^28 variables): the native
# loader sets the seeds at SEED + known, then reads the step's derivatives at OUTPUT + unknown, FMI's at
# POINT + unknown (docs/fmu.md). The builder compiles the loader with these values.
DERIVATIVE_CHANNEL = {"SEED": 1 << 28, "OUTPUT": 2 << 28, "POINT": 3 << 28}  # OUTPUT: the step's, POINT: FMI's
INPUT_RULE = {
    "r": "extrapolated from t_c with {p}.v and {p}.a: r(t) = r_c + v_c s + a_c s^2/2, s = t - t_c",
    "v": "extrapolated from t_c with {p}.a: v(t) = v_c + a_c s (the slope of the extrapolation of {p}.r)",
    "a": "held constant over the communication step (0 by default: first-order extrapolation of {p}.r, {p}.v)",
    "R": "extrapolated with {p}.w and {p}.dw: R(t) = expm(skew(w_c s + dw_c s^2/2)) R_c; must be a rotation "
    f"(|R^T R - I| <= {ROTATION_TOL:g}, det > 0, re-orthonormalized when not exact)",
    "w": "extrapolated from t_c with {p}.dw: w(t) = w_c + dw_c s (the rate of the extrapolation of {p}.R)",
    "dw": "held constant over the communication step (0 by default: first-order extrapolation of {p}.R, {p}.w)",
    "f": "held constant over the communication step",
    "t": "held constant over the communication step",
}


@dataclass(frozen=True)
class Variable:
    name: str
    type: str  # "Real" | "Integer"
    causality: str  # "input" | "output" | "parameter"
    variability: str  # "continuous" | "discrete" | "fixed"
    unit: str | None
    description: str
    start: float | int | None  # None for calculated outputs
    kind: str  # "port" | "energy" | "solver" | "parameter"
    port: str = ""
    field: str = ""  # port field (r R v w f t), energy key, or parameter key
    index: tuple[int, ...] = ()  # 0-based component
    min: float | None = None  # declared min/max (FMI: inclusive); checked at initialization
    max: float | None = None


def port_field_causality(translation: str, rotation: str, field: str) -> str:
    """'input' or 'output' for one field of a port with the given part causalities (docs/fmu.md)."""
    part = "translation" if field in PART_FIELDS["translation"] else "rotation"
    motion = (translation if part == "translation" else rotation) in ("motion", "compliant")  # compliant: motion in
    is_load = field in ("f", "t")
    return "output" if motion == is_load else "input"


MODAL = {  # the modal coordinates of every superelement as outputs (runtime/outputs.py MODAL_FIELDS): field -> what
    # a value is (one text for every element, so that FMI 3.0's array modal.eta[E, nm] has it too)
    "eta": "modal coordinate eta[e,i]: the amplitude of free-free mode i of superelement e (1-based indices) in the "
           "reduction basis (eq. 76; the mode shapes are mass-normalized, so eta is in sqrt(kg) m)",
    "eta_rate": "rate d(eta[e,i])/dt of the modal coordinate of free-free mode i of superelement e (sqrt(kg) m/s)",
}


def modal_shape(data) -> tuple[int, int]:
    """(superelements, free-free modes per superelement) of a runtime.data.BodyData: the shape of the
    modal outputs modal.eta[e,i], modal.eta_rate[e,i]."""
    se = data.superelements[0]
    return len(data.superelements), se.n - 6 * len(se.nodes)


def body_variables(ports, node_positions, parameters: dict, damping=None,
                   modes: tuple[int, int] = (0, 0)) -> list[Variable]:
    """Every variable of a body FMU, in value-reference order.

    ports: objects with name, node, translation, rotation (runtime.data.PortData);
    node_positions: reference node positions (start values of motion-driven r inputs);
    parameters: defaults with keys step, rho_inf, gravity (3), terms (name), max_newton_iterations (optional,
    default 0), initial_velocity (3),
    initial_angular_velocity (3), port_displacements {port: (3,)} (force-driven translations);
    damping: the body's runtime.damping.Damping (the damping parameters' defaults), None: undamped;
    modes: `modal_shape` of the body, the modal outputs (none for (0, 0)).
    """
    out: list[Variable] = []
    for p in ports:
        r_ref = [float(x) for x in node_positions[p.node]]
        for field in OUTPUT_FIELDS:
            shape, unit, meaning = FIELDS[field]
            causality = port_field_causality(p.translation, p.rotation, field)
            part = "translation" if field in PART_FIELDS["translation"] else "rotation"
            how = f"{part} {getattr(p, part)}-driven"
            if causality == "input":
                rule = INPUT_RULE[field].format(p=p.name)
                if getattr(p, part) == "compliant":
                    rule = f"{COMPLIANT_INPUT}; {rule}"
                desc = f"{meaning} [input, {how}; {rule}]"
            elif field in ("a", "dw"):
                desc = f"{meaning} [output, {how}; {ACCELERATION_OUTPUT}]"
            else:
                desc = f"{meaning} [output at the communication point, {how}]"
            for idx in _indices(shape):
                if causality == "input":
                    if field == "r":
                        start = r_ref[idx[0]]
                    elif field == "R":
                        start = 1.0 if idx[0] == idx[1] else 0.0
                    else:
                        start = 0.0
                else:
                    start = None
                out.append(
                    Variable(port_variable(p.name, field, idx), "Real", causality, "continuous", unit, desc, start,
                             "port", p.name, field, idx)
                )
        out.extend(_compliant_variables(p))
    for name in parameters.get("probes", ()):
        seen, _, frame = name.partition("_from_")
        for i in range(3):
            out.append(Variable(component_name(f"probe.{name}", (i,)), "Real", "output", "continuous", "m",
                                f"elastic displacement of port {seen} seen from the frame of port {frame} (geradin eq. 92): "
                                f"R_{frame}^T (r_{seen} - r_{frame}) - (X_{seen} - X_{frame}), axis {i + 1} of the {frame} frame "
                                "[output at the communication point]", None, "probe", field=name, index=(i,)))
    for field, text in MODAL.items():  # superelement e, mode i: 1-based in the name, 0-based in `index`
        for e in range(modes[0]):
            for i in range(modes[1]):
                out.append(Variable(component_name(f"modal.{field}", (e, i)), "Real", "output", "continuous", None,
                                    text + " [output at the communication point]", None,
                                    "modal", field=field, index=(e, i)))
    for key, meaning in ENERGIES.items():
        out.append(Variable(f"energy.{key}", "Real", "output", "continuous", "J", meaning, None, "energy", field=key))
    out.append(
        Variable("solver.newton_iterations", "Integer", "output", "discrete", None,
                 "largest number of Newton iterations of the internal steps of the last communication step",
                 None, "solver", field="newton_iterations")
    )
    par = parameters
    # solver.step declares no min: its bound (> 0) is exclusive, FMI's min is inclusive; it is
    # checked at initialization (positive, finite, not longer than the experiment)
    out.append(Variable("solver.step", "Real", "parameter", "fixed", "s",
                        "internal integrator step, > 0 and not longer than the experiment. " + INTERNAL_STEPS,
                        float(par["step"]), "parameter", field="step"))
    out.append(Variable("solver.rho_inf", "Real", "parameter", "fixed", None,
                        "spectral radius at infinite frequency of generalized-alpha, in [0, 1]",
                        float(par["rho_inf"]), "parameter", field="rho_inf", min=0.0, max=1.0))
    out.append(Variable("solver.terms", "Integer", "parameter", "fixed", None,
                        "term set of the body equations (Integer enumeration): 0 = linear, 1 = gyroscopic, 2 = full (needs the "
                        "inertia data, built when the scene's term set is full)",
                        TERM_SETS.index(par["terms"]), "parameter", field="terms", min=0, max=len(TERM_SETS) - 1))
    out.append(Variable("solver.max_newton_iterations", "Integer", "parameter", "fixed", None,
                        "hard real-time cap: at most this many Newton iterations in an internal step, retry included; a "
                        "step that needs more makes doStep return Error naming the cap (never an unconverged step "
                        "accepted). 0 = no cap (docs/fmu.md, Real-time datasheet)",
                        int(par.get("max_newton_iterations", 0)), "parameter", field="max_newton_iterations", min=0))
    for i in range(3):
        out.append(Variable(component_name("gravity", (i,)), "Real", "parameter", "fixed", "m/s2",
                            "uniform gravity acceleration, world axes", float(par["gravity"][i]), "parameter",
                            field="gravity", index=(i,)))
    for i in range(3):
        out.append(Variable(component_name("initial.v", (i,)), "Real", "parameter", "fixed", "m/s",
                            "initial rigid velocity field v + w x (X - origin) of a body with no motion-driven port: v",
                            float(par["initial_velocity"][i]), "parameter", field="initial_velocity", index=(i,)))
    for i in range(3):
        out.append(Variable(component_name("initial.w", (i,)), "Real", "parameter", "fixed", "rad/s",
                            "initial rigid velocity field v + w x (X - origin) of a body with no motion-driven port: w",
                            float(par["initial_angular_velocity"][i]), "parameter",
                            field="initial_angular_velocity", index=(i,)))
    disp = par.get("port_displacements", {})
    for p in ports:
        if p.translation != "force":
            continue
        d = disp.get(p.name, (0.0, 0.0, 0.0))
        for i in range(3):
            out.append(Variable(component_name(f"initial.{p.name}.d", (i,)), "Real", "parameter", "fixed", "m",
                                f"initial elastic displacement of port {p.name} from its reference position",
                                float(d[i]), "parameter", port=p.name, field="port_displacement", index=(i,)))
    out.extend(damping_variables(damping))
    return out


def damping_variables(damping) -> list[Variable]:
    """The structural damping's parameters (runtime/damping.py; defaults from the model file's
    [body.damping], zero without it): damping.ratio, one for every mode (or damping.ratio[i], one per
    mode, when the model file lists them), damping.alpha, damping.beta. Both kinds may be set: their
    per-mode coefficients add, c_i = 2 zeta_i omega_i + alpha + beta omega_i^2."""
    ratios = list(damping.ratios if damping is not None else ()) or [0.0]
    alpha, beta = (damping.alpha, damping.beta) if damping is not None else (0.0, 0.0)
    out = []
    rule = ("structural damping on the co-rotated elastic rates, never on the rigid motion (docs/equations.md); "
            "set before initialization, >= 0")
    for i, z in enumerate(ratios):
        which = "every mode of each superelement's reduced model" if len(ratios) == 1 else \
            f"mode {i + 1} (by rising frequency) of each superelement's reduced model"
        out.append(Variable(component_name("damping.ratio", (i,)) if len(ratios) > 1 else "damping.ratio", "Real",
                            "parameter", "fixed", None, f"modal damping ratio of {which}; {rule}", float(z),
                            "parameter", field="damping_ratio", index=(i,) if len(ratios) > 1 else (), min=0.0))
    out.append(Variable("damping.alpha", "Real", "parameter", "fixed", "1/s",
                        f"Rayleigh damping coefficient on the mass; {rule}", float(alpha), "parameter",
                        field="damping_alpha", min=0.0))
    out.append(Variable("damping.beta", "Real", "parameter", "fixed", "s",
                        f"Rayleigh damping coefficient on the stiffness; {rule}", float(beta), "parameter",
                        field="damping_beta", min=0.0))
    return out


COMPLIANT_INPUT = ("the far end of the port's coupling spring-damper (compliant part, docs/cosim.md): "
                   "the motion of the partner, extrapolated like a motion input")
# compliant part -> (node frame outputs, coupling parameters: (suffix, unit, meaning, index in PortData.compliance))
COMPLIANT = {
    "translation": (("r", "v", "a"), (("k", "N/m", "stiffness, world axes", 0), ("c", "N.s/m", "damping, world axes", 1))),
    "rotation": (("R", "w", "dw"), (("k_rot", "N.m/rad", "rotational stiffness, nodal axes", 2),
                              ("c_rot", "N.m.s/rad", "rotational damping, nodal axes", 3))),
}


def _compliant_variables(p) -> list[Variable]:
    """A compliant part (runtime/coupling.py) has motion inputs (the spring's far end) and the spring
    load as output; the body's own nodal frame is then an output under P.node.*, and the spring-damper
    coefficients are parameters P.coupling.* (defaults from the model file's coupling table)."""
    out = []
    comp = list(getattr(p, "compliance", ()) or [0.0] * 12)
    for part, (fields, params) in COMPLIANT.items():
        if getattr(p, part) != "compliant":
            continue
        for field in fields:
            shape, unit, meaning = FIELDS[field]
            for idx in _indices(shape):
                out.append(Variable(port_variable(p.name, "node." + field, idx), "Real", "output", "continuous", unit,
                                    f"{meaning} of the body's own node at compliant port {p.name} "
                                    + (f"[output; {ACCELERATION_OUTPUT}]" if field in ("a", "dw") else
                                       "[output at the communication point]"), None, "port", p.name, "node." + field, idx))
        for suffix, unit, meaning, row in params:
            for i in range(3):
                out.append(Variable(component_name(f"{p.name}.coupling.{suffix}", (i,)), "Real", "parameter", "fixed", unit,
                                    f"coupling spring-damper of compliant port {p.name}: {meaning}",
                                    float(comp[3 * row + i]), "parameter", p.name, "coupling." + suffix, (i,)))
    return out


def patch_model_description(root: Element, variables: list[Variable], derivatives: bool = False) -> Element:
    """Complete pythonfmu's modelDescription: units, UnitDefinitions and a ModelStructure with
    Outputs and InitialUnknowns (every output; depends on all inputs and parameters), so that fmpy's
    validate_fmu finds nothing to report.

    derivatives: the FMU provides directional derivatives (DIRECTIONAL_DERIVATIVES; needs the native
    loader): providesDirectionalDerivative="true". Every output has dependencies="": no direct
    feedthrough (setting an input changes no output before the next doStep; outputs are the values
    at the end of the last step, tests/test_model_structure.py perturbs every input to show it), so a
    master that detects algebraic loops from the ModelStructure finds none. (The derivatives this
    FMU provides are those of its last step's map, docs/fmu.md, not direct feedthrough.)"""
    by_name = {v.name: v for v in variables}
    used_units = set()
    mv = root.find("ModelVariables")
    for sv in mv.findall("ScalarVariable"):
        var = by_name[sv.get("name")]
        typ = sv.find(var.type)
        if var.unit:
            typ.set("unit", var.unit)
            used_units.add(var.unit)
        for key in ("min", "max"):
            bound = getattr(var, key)
            if bound is not None:
                typ.set(key, repr(float(bound)) if var.type == "Real" else str(int(bound)))
    # UnitDefinitions come right after CoSimulation (FMI 2.0 schema order)
    units = Element("UnitDefinitions")
    for name in sorted(used_units):
        u = SubElement(units, "Unit", {"name": name})
        SubElement(u, "BaseUnit", {k: str(e) for k, e in UNITS[name].items()})
    pos = list(root).index(root.find("CoSimulation")) + 1
    root.insert(pos, units)
    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    structure = SubElement(root, "ModelStructure")
    outputs = [i + 1 for i, v in enumerate(variables) if v.causality == "output"]
    if derivatives:
        root.find("CoSimulation").set("providesDirectionalDerivative", "true")
    if outputs:
        o = SubElement(structure, "Outputs")
        for i in outputs:
            SubElement(o, "Unknown", {"index": str(i), "dependencies": ""})
        iu = SubElement(structure, "InitialUnknowns")
        for i in outputs:
            SubElement(iu, "Unknown", {"index": str(i)})
    return root
