"""Connections between FMU variables: held signals and body-port motions (docs/fmu.md), and the
wiring of two body ports."""
from __future__ import annotations

from dataclasses import dataclass

from ..fmu.variables import port_variables
from .instance import CoSimulationError, FmuInstance


@dataclass(frozen=True)
class Signal:
    """dst <- gain * src, a signal held by the receiver over the step (or extrapolated by the master)."""

    src: str
    dst: str
    gain: float = 1.0


@dataclass(frozen=True)
class Motion:
    """A frame and its rate: positions (3 names, r or R flattened) and rates (3 names, v or w), and
    optionally the accelerations (3 names, a or dw; empty: the receiver's stay as they are, 0 by default)."""

    kind: str  # "translation" | "rotation"
    src_pos: tuple[str, ...]
    src_rate: tuple[str, ...]
    dst_pos: tuple[str, ...]
    dst_rate: tuple[str, ...]
    src_acc: tuple[str, ...] = ()
    dst_acc: tuple[str, ...] = ()

    @property
    def src(self) -> tuple[str, ...]:
        return self.src_pos + self.src_rate + self.src_acc

    @property
    def dst(self) -> tuple[str, ...]:
        return self.dst_pos + self.dst_rate + self.dst_acc


def _split(full: str) -> tuple[str, str]:
    inst, sep, var = full.partition(".")
    if not sep:
        raise CoSimulationError(f"{full!r}: expected '<instance>.<variable>'")
    return inst, var


def body_port_links(a: str, port_a: str, b: str, port_b: str, causality_a: dict, causality_b: dict,
                    accelerations: bool = False) -> list:
    """Connections joining port_a of body FMU a to port_b of body FMU b (rigid joint of the frames).

    causality_x: {"translation": "motion"|"force", "rotation": ...} of each port. Each part must be
    motion-driven on exactly one side. accelerations: the motion-driven side also receives the
    force-driven side's accelerations (its outputs P.a / P.dw into the inputs P.a / P.dw, docs/fmu.md
    "Accelerations out"), so that its motion is extrapolated to second order over the step."""
    links: list = []
    for part, (pos, rate, acc, load) in {"translation": ("r", "v", "a", "f"), "rotation": ("R", "w", "dw", "t")}.items():
        ca, cb = causality_a[part], causality_b[part]
        if ca == cb:
            raise CoSimulationError(
                f"{a}.{port_a} and {b}.{port_b}: the {part} is {ca}-driven on both sides; one side must be "
                "motion-driven and the other force-driven"
            )
        (m, pm), (s, ps) = ((a, port_a), (b, port_b)) if ca == "motion" else ((b, port_b), (a, port_a))
        # the motion-driven side m follows the frame of the force-driven side s ...
        links.append(Motion(part,
                            tuple(f"{s}.{n}" for n in port_variables(ps, pos)), tuple(f"{s}.{n}" for n in port_variables(ps, rate)),
                            tuple(f"{m}.{n}" for n in port_variables(pm, pos)), tuple(f"{m}.{n}" for n in port_variables(pm, rate)),
                            tuple(f"{s}.{n}" for n in port_variables(ps, acc)) if accelerations else (),
                            tuple(f"{m}.{n}" for n in port_variables(pm, acc)) if accelerations else ()))
        # ... and s receives minus the reaction on m
        for src, dst in zip(port_variables(pm, load), port_variables(ps, load)):
            links.append(Signal(f"{m}.{src}", f"{s}.{dst}", -1.0))
    return links


def port_causality(inst: FmuInstance, port: str) -> dict:
    """Part causalities of a body port, read from the FMU variables."""
    out = {}
    for part, pos in (("translation", "r"), ("rotation", "R")):
        v = inst.variable(port_variables(port, pos)[0])
        out[part] = "motion" if v.causality == "input" else "force"
    return out
