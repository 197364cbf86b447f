"""The reduced body's port records (runtime/data.py PortData) from the model's ports: their boundary
node, causality and, for compliant ports, stiffness and damping. Shared by the beam's reduction
and the solid's (reduction.py: reduce_body, reduce_solid_body), below both."""
from __future__ import annotations

import dataclasses

import numpy as np

from .model import PART_CAUSALITIES, Body, ModelError
from .runtime.data import BodyData, PortData


def port_data(body: Body, n_nodes: int) -> tuple[PortData, ...]:
    ports = []
    for p in body.ports:
        node = p.node + n_nodes if p.node < 0 else p.node
        if not 0 <= node < n_nodes:
            raise ModelError(f"{body.source}: port {p.name!r} node {p.node} outside 0..{n_nodes - 1}")
        t, r = p.translation, p.rotation
        if t not in PART_CAUSALITIES or r not in PART_CAUSALITIES:
            raise ModelError(f"{body.source}: port {p.name!r} causality must be one of {PART_CAUSALITIES}")
        ports.append(PortData(p.name, node, t, r))
    return tuple(ports)


def compliance(data: BodyData, body: Body, p: PortData) -> PortData:
    """Stiffness and damping of a compliant port (runtime/coupling.py): the rule of
    `coupling.compliance_rule` for the port's `coupling.step`, explicit values where given."""
    from .runtime.coupling import compliance_rule

    if "compliant" not in (p.translation, p.rotation):
        return p
    c = dict(next(q for q in body.ports if q.name == p.name).coupling)
    if "step" in c:
        KC = compliance_rule(data, p.node, c["step"])
    elif (p.translation == "compliant" and "stiffness" not in c) or (p.rotation == "compliant" and "rotational_stiffness" not in c):
        raise ModelError(f"{body.source}: compliant port {p.name!r} needs coupling.step or explicit stiffness values")
    else:
        KC = np.zeros((4, 3))
    for i, key in enumerate(("stiffness", "damping", "rotational_stiffness", "rotational_damping")):
        if key in c:
            KC[i] = c[key]
    if p.translation != "compliant":
        KC[0:2] = 0.0
    if p.rotation != "compliant":
        KC[2:4] = 0.0
    return dataclasses.replace(p, compliance=tuple(float(x) for x in KC.ravel()))
