"""Two flexible bodies at a compliant cut under an explicit engine: the split beam (split.py) with
A's cut `compliant` and B's cut force-driven, run with plain Jacobi (held inputs), the discrete map
libcosim and ecos run (docs/cosim.md: they reproduce our Jacobi to round-off), against the one-body
run (monolithic.split_monolithic). Measures the cut's stable range: stiffness against H.

The cut's spring-damper follows the rule of docs/cosim.md for a coupling step H_c
(runtime/coupling.compliance_rule: omega_c = 0.5 / H_c, k = omega_c^2 m_P, c = omega_c m_P per
axis, m_P the half's rigid mass and inertia diagonal about the cut): H_c = H is the rule itself,
H_c > H a softer cut (omega_c H = 0.5 H / H_c).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .case import CosimRun, CosimSettings, _rotz, _vec, hub_profile, tip_deflection


@dataclass(frozen=True)
class CompliantCut:
    """The two half-beam FMUs with a compliant cut, the half A model (for the rule's masses)."""

    fmus: dict
    half_a: Path
    length: float
    profile: dict  # the hub spin-up of A (haug_spinup: omega, T = settings.split_T)


def build(model_path, fmu_dir, settings: CosimSettings) -> CompliantCut:
    from ...fmu.builder import build_fmu
    from ...model import load_model
    from .split import split_models

    fmu_dir = Path(fmu_dir)
    fmu_dir.mkdir(parents=True, exist_ok=True)
    b = settings.beam
    a, bb = split_models(model_path, fmu_dir, list(settings.overrides), coupling={"step": 0.01}, scene=b.driven_scene,
                         ports=(b.hub, b.tip))
    model = load_model(model_path, list(settings.overrides))
    return CompliantCut({"A": build_fmu(a, fmu_dir / "cut_a.fmu"), "B": build_fmu(bb, fmu_dir / "cut_b.fmu")},
                        a, model.body.length, {**hub_profile(model, b), "T": settings.split_T})


def coefficients(cut: CompliantCut, H_c: float) -> dict[str, float]:
    """FMU parameters A.cut.coupling.* of the rule for the coupling step H_c."""
    from ...model import load_model
    from ...reduction import reduce_scene_body
    from ...runtime.coupling import compliance_rule

    model = load_model(cut.half_a)
    data = reduce_scene_body(model.body, model.scene("run")).data
    node = next(p.node for p in data.ports if p.name == "cut")
    KC = compliance_rule(data, node, H_c)
    out = {}
    for row, name in enumerate(("k", "c", "k_rot", "c_rot")):
        out.update({f"A.cut.coupling.{name}[{i + 1}]": float(KC[row, i]) for i in range(3)})
    return out


def run(cut: CompliantCut, settings: CosimSettings, H: float, H_c: float, duration: float | None = None,
        accelerations: bool = False) -> CosimRun:
    """Plain Jacobi at H with the cut of the rule for H_c; the hub of A driven by the fast spin-up
    (settings.split_T) with its acceleration; the FMUs' internal step = H. accelerations: the
    spring's far end (A's cut inputs) also gets B's cut accelerations (connect_ports, docs/cosim.md)."""
    from ...master import CoSimulation
    from .case import CosimCase

    duration = settings.split_duration if duration is None else duration
    helper = CosimCase.__new__(CosimCase)  # the split case's hub source and angle law, without its FMUs
    helper.beam, helper.profile = settings.beam, cut.profile
    sv = {"A.solver.step": H, "B.solver.step": H, **coefficients(cut, H_c)}
    t0 = time.perf_counter()
    rec = _vec("B", settings.beam.tip, "r") + ["A.cut.t[3]"]
    with CoSimulation(cut.fmus, step=H, scheme="jacobi", start_values=sv) as sim:
        sim.connect_ports("A", "cut", "B", "cut", accelerations=accelerations)
        res = sim.run(duration, sources=helper._hub_sources("A"), record=rec)
    c = res.columns
    r_tip = np.stack([c[n] for n in _vec("B", settings.beam.tip, "r")], -1)
    d = tip_deflection(_rotz(helper._phi(res.t)), np.zeros_like(r_tip), r_tip, np.array([cut.length, 0.0, 0.0]))
    return CosimRun(res.t, d, np.full(len(res.t), np.nan), c["A.cut.t[3]"], res.stopped_early, time.perf_counter() - t0)

