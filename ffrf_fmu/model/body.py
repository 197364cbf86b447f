"""[body] of a beam (kind = "beam"): its section, ports on boundary nodes, point masses and
structural damping, read and checked (docs/model-format.md)."""
from __future__ import annotations

import math
from typing import Any

from ..checked_toml import ModelError, Reader, join, nonnegative, positive
from ..runtime.damping import Damping, per_mode_ratios
from ..section import Section
from .keys import BODY_KEYS, COUPLING_KEYS, DAMPING_KEYS, MASS_KEYS, PORT_KEYS, SECTION_KEYS, _NAME
from .schema import Body, PART_CAUSALITIES, PointMass, Port


def _parse_beam(r: Reader, t: Any, default_name: str, file: str) -> Body:
    """[body] kind = "beam" (the default): superelements of beam elements, ports on boundary nodes."""
    b = "body"
    r.table(t, b, BODY_KEYS, required=("length", "superelements", "elements_per_superelement", "modes", "section"))
    name = r.string(t, b, "name", BODY_KEYS["name"], default_name)
    if not _NAME.match(name):  # becomes part of FMU and variable names
        r.expected(join(b, "name"), BODY_KEYS["name"], name)
    n_se = r.integer(t, b, "superelements", BODY_KEYS["superelements"], low=1)
    n_el = r.integer(t, b, "elements_per_superelement", BODY_KEYS["elements_per_superelement"], low=2)
    modes = r.integer(t, b, "modes", BODY_KEYS["modes"], low=0)
    if modes > 6 * (n_el - 1):  # the modal columns of Y live on the interior dofs (eq. 76)
        r.fail(join(b, "modes"), f"expected at most 6 * (elements_per_superelement - 1) = {6 * (n_el - 1)} "
               f"(interior dofs of a superelement), got {modes}")

    s, st = "body.section", t["section"]
    r.table(st, s, SECTION_KEYS, required=("EA", "GJ", "EI2", "EI3", "m", "m22", "m33"))
    vals = {k: r.real(st, s, k, SECTION_KEYS[k], None, ok=nonnegative if k in ("m22", "m33") else positive)
            for k in SECTION_KEYS}
    if (vals["GA2"] is None) != (vals["GA3"] is None):
        missing = "GA3" if vals["GA3"] is None else "GA2"
        r.fail(join(s, missing), "missing; expected GA2 and GA3 together (Timoshenko) or neither (Euler-Bernoulli)")
    if vals["m11"] is None and vals["m22"] + vals["m33"] == 0.0:
        r.fail(join(s, "m11"), "missing; expected a positive torsional inertia when m22 = m33 = 0")

    ports = []
    pt = r.table(t.get("ports", {}), "body.ports", None)
    for pname, p in pt.items():
        pp = join("body.ports", pname)
        if not _NAME.match(pname):  # becomes an FMU variable prefix (docs/fmu.md)
            r.fail(pp, "expected a port name of letters, digits and _ (it prefixes FMU variable names)")
        r.table(p, pp, PORT_KEYS, required=("node",))
        node = r.integer(p, pp, "node", PORT_KEYS["node"], low=-math.inf)
        if not -n_se - 1 <= node <= n_se:
            r.fail(join(pp, "node"), f"expected a boundary node in 0..{n_se} (or -{n_se + 1}..-1 from the end) "
                   f"for {n_se} superelements, got {node}")
        node = node % (n_se + 1)
        for other in ports:
            if other.node == node:
                r.fail(join(pp, "node"), f"expected a node without a port, but port {other.name!r} is on node {node}")
        tr = r.string(p, pp, "translation", PORT_KEYS["translation"], "force", PART_CAUSALITIES)
        rot = r.string(p, pp, "rotation", PORT_KEYS["rotation"], "force", PART_CAUSALITIES)
        ports.append(Port(pname, node, tr, rot, _port_coupling(r, p, pp, tr, rot)))

    length = r.real(t, b, "length", BODY_KEYS["length"], ok=positive)
    masses = []
    mt = t.get("masses", [])
    if not isinstance(mt, list):
        r.expected(join(b, "masses"), BODY_KEYS["masses"], mt)
    h = length / (n_se * n_el)  # FE element length
    for i, pm in enumerate(mt):
        mp = join(join(b, "masses"), str(i))
        r.table(pm, mp, MASS_KEYS, required=("at", "mass"))
        at = r.real(pm, mp, "at", MASS_KEYS["at"], ok=lambda x: 0.0 <= x <= length)
        if abs(at / h - round(at / h)) > 1e-9 * max(1.0, at / h):
            r.fail(join(mp, "at"), f"expected a node of the FE mesh (a multiple of length / (superelements * "
                   f"elements_per_superelement) = {h:g} m), got {at!r}")
        inertia = r.vec3(pm, mp, "inertia", MASS_KEYS["inertia"], (0.0, 0.0, 0.0))
        if min(inertia) < 0.0:
            r.expected(join(mp, "inertia"), MASS_KEYS["inertia"], list(inertia))
        masses.append(PointMass(round(at / h) * h, r.real(pm, mp, "mass", MASS_KEYS["mass"], ok=positive), inertia))

    return Body(
        name=name,
        length=length,
        origin=r.vec3(t, b, "origin", BODY_KEYS["origin"], (0.0, 0.0, 0.0)),
        direction=r.vec3(t, b, "direction", BODY_KEYS["direction"], (1.0, 0.0, 0.0), unit=True),
        section=Section(**vals),
        superelements=n_se,
        elements_per_superelement=n_el,
        modes=modes,
        ports=tuple(ports),
        source=file,
        masses=tuple(masses),
        damping=_parse_damping(r, t),
    )


def _parse_damping(r: Reader, t: dict) -> Damping | None:
    """[body.damping]: modal ratios (one for all modes or one per mode) or Rayleigh's alpha, beta, not
    both. The length of a list is checked against the reduced model by `body_damping`."""
    if "damping" not in t:
        return None
    dp = "body.damping"
    dt = r.table(t["damping"], dp, DAMPING_KEYS)
    if not dt:
        r.fail(dp, "expected ratio = ZETA (modal damping) or alpha, beta (Rayleigh damping)")
    if "ratio" in dt and ("alpha" in dt or "beta" in dt):
        r.fail(dp, "expected either ratio (modal damping) or alpha and beta (Rayleigh damping), not both")
    if "ratio" not in dt:
        return Damping((), r.real(dt, dp, "alpha", DAMPING_KEYS["alpha"], 0.0, ok=nonnegative),
                       r.real(dt, dp, "beta", DAMPING_KEYS["beta"], 0.0, ok=nonnegative))
    z = dt["ratio"]
    ratios = z if isinstance(z, list) else [z]
    if not ratios or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x >= 0
                             for x in ratios):
        r.expected(join(dp, "ratio"), DAMPING_KEYS["ratio"], z)
    return Damping(tuple(float(x) for x in ratios))


def body_damping(body: Body, n: int) -> Damping | None:
    """The body's damping for superelements of n reduced dofs: a list of ratios must have n of them
    (ModelError naming the file and key otherwise)."""
    if body.damping is not None:
        try:
            per_mode_ratios(body.damping, n)
        except ValueError as e:
            raise ModelError(f"{body.source}: body.damping.ratio: {e}") from None
    return body.damping



def _port_coupling(r: Reader, p: dict, pp: str, tr: str, rot: str) -> tuple:
    coupling = ()
    if "coupling" in p:
        cp = join(pp, "coupling")
        c = r.table(p["coupling"], cp, COUPLING_KEYS)
        cvals = {}
        if "step" in c:
            cvals["step"] = r.real(c, cp, "step", COUPLING_KEYS["step"], ok=positive)
        for key in ("stiffness", "damping", "rotational_stiffness", "rotational_damping"):
            if key in c:
                v = r.vec3(c, cp, key, COUPLING_KEYS[key])
                if min(v) < 0.0:
                    r.fail(join(cp, key), f"expected {COUPLING_KEYS[key]}, got {list(v)}")
                cvals[key] = v
        coupling = tuple(cvals.items())
    if "compliant" in (tr, rot) and not coupling:
        r.fail(pp, "a compliant part needs a coupling table: {step = H} (the rule of docs/cosim.md) or explicit "
               "stiffness/damping values")
    return coupling
