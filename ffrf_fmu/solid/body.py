"""A solid body of a model file (model.SolidSpec) built and reduced: its FE model (mesh assembled with
scikit-fem, or a partner's export), its frames, and the reduced BodyData the runtime takes unchanged
(one superelement whose boundary nodes are the port frames, in the order of the ports)."""
from __future__ import annotations

import dataclasses
import json

import numpy as np

from . import SolidFE
from .frames import Frame, select_nodes
from .source import solid_fe


def solid_frames(spec, fe: SolidFE) -> tuple[Frame, ...]:
    """The port frames of a SolidSpec on its FE model: node selections (solid/frames.py), link, origin."""
    scale = float(np.linalg.norm(fe.coords.max(0) - fe.coords.min(0)))
    out = []
    for f in spec.frames:
        try:
            nodes = select_nodes(fe.coords, fe.node_sets, json.loads(f.select), scale)
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"port {f.port!r}: {e}") from None
        point = np.asarray(f.point, dtype=float) if f.point is not None else fe.coords[nodes].mean(0)
        out.append(Frame(f.port, nodes, f.link, point))
    return tuple(out)


def reduce_solid_body(body, stiffening: bool = False, inertia: bool = False):
    """The ReducedBody (BodyData, (SolidReduction,)) of a solid body: one superelement on its port frames."""
    from ..model import body_damping
    from ..port_data import compliance, port_data
    from ..reduction_sparse import reduce_solid
    from ..runtime.data import BodyData, ReducedBody

    from ..checked_toml import ModelError

    spec = body.solid
    try:  # a bad selection, a set that cannot hold a frame, a mechanism: the model's fault, said as such
        fe = solid_fe(spec)
        frames = solid_frames(spec, fe)
        red = reduce_solid(fe, frames, n_modes=body.modes if spec.cutoff_hz is None else None,
                           cutoff_hz=spec.cutoff_hz, inertia=inertia, stiffening=stiffening)
    except ValueError as e:
        raise ModelError(f"body {body.name!r} ({body.source}): {e}") from None
    data = BodyData(name=body.name, superelements=(red.data,),
                    node_positions=np.array([f.point for f in frames]),
                    ports=port_data(body, len(frames)), damping=body_damping(body, red.data.n))
    if any("compliant" in (p.translation, p.rotation) for p in data.ports):
        data = dataclasses.replace(data, ports=tuple(compliance(data, body, p) for p in data.ports))
    return ReducedBody(data, (red,))
