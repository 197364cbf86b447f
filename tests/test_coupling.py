"""Compliant coupling (runtime/coupling.py, docs/cosim.md): the spring-damper's derivatives in the
iteration matrix, its limit (a stiff coupling is the motion-driven port), and B5 with compliant
coupling in the engines people use (libcosim, ecos): the same numbers as our master's Jacobi
scheme, and a failing body step reported through the engine with the host alive."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import build_body
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.simulate import scene_inputs

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "models"


def _compliant(extra=(), duration=0.3, step=0.01):
    return load_model(MODELS / "haug_beam.toml", [
        'body.ports.hub.translation="compliant"', 'body.ports.hub.rotation="compliant"', *extra,
        f"duration={duration}", f"step={step}", "superelements=2"])


def test_spring_damper_iteration_matrix_against_finite_differences():
    """The Newton system's Jacobian (body + spring-damper on a compliant hub, both parts, unequal
    stiffness per axis, damping) against central differences of its residual at perturbed rates,
    mid spin-up (hub rotated, spring deflected): within 1e-6 relative to the largest entry (central
    differences with step 1e-6 leave ~1e-8 here; an error in a spring term is of order beta k ~ 1)."""
    model = _compliant(['body.ports.hub.coupling={ stiffness = [1e4, 2e4, 3e4], damping = [5.0, 6.0, 7.0], '
                        'rotational_stiffness = [30.0, 40.0, 300.0], rotational_damping = [0.1, 0.2, 0.3] }'])
    sc = model.scene("spinup")
    data, _ = build_body(model.body, sc.causality)
    inputs = scene_inputs(data, sc)
    body = BodySystem(data)
    body.initialize(0.0, inputs)
    for _ in range(30):
        body.step(0.01, inputs)
    assert np.linalg.norm(body.outputs()["hub"].t) > 1e-3  # the spring is loaded
    h, values = 0.01, inputs(body.t + 0.01)
    yd = body.yd + 1e-3 * np.random.default_rng(1).standard_normal(body.yd.size)
    F, J = body.newton_system(yd, h, values)
    fi, eps = body._free_idx, 1e-6
    Jfd = np.empty_like(J)
    for j, g in enumerate(fi):
        yp, ym = yd.copy(), yd.copy()
        yp[g] += eps
        ym[g] -= eps
        Jfd[:, j] = (body.newton_system(yp, h, values, jacobian=False)
                     - body.newton_system(ym, h, values, jacobian=False)) / (2 * eps)
    assert np.abs(J - Jfd).max() < 1e-6 * np.abs(Jfd).max()


def test_stiff_compliant_hub_tends_to_the_motion_driven_hub():
    """B1's spin-up (first 0.6 s, 2 SE) with the hub compliant instead of motion-driven: the tip
    follows the motion-driven run more closely as the coupling gets stiffer, the difference falling
    like 1/k (the spring's static deflection under the hub reaction; measured: 8.2e-7 m at
    k = 1e5 N/m, 8.4e-8 m at 1e6, of a 3.6e-5 m transverse tip excursion); damping at zeta ~ 0.5 of
    the coupling mode."""
    base = load_model(MODELS / "haug_beam.toml", ["duration=0.6", "step=0.005", "superelements=2"])
    sc = base.scene("spinup")
    data, _ = build_body(base.body, sc.causality)
    ref = BodySystem(data)
    inp = scene_inputs(data, sc)
    ref.initialize(0.0, inp)
    tip_ref = []
    for _ in range(120):
        ref.step(0.005, inp)
        tip_ref.append(ref.outputs()["tip"].r.copy())
    diffs = []
    for k in (1e5, 1e6):
        c = 2 * 0.5 * math.sqrt(k * 1.6)  # zeta 0.5 against the beam's mass 1.6 kg
        kr, cr = k * 0.1, c * 0.1
        m = _compliant([f'body.ports.hub.coupling={{ stiffness = [{k}, {k}, {k}], damping = [{c}, {c}, {c}], '
                        f'rotational_stiffness = [{kr}, {kr}, {kr}], rotational_damping = [{cr}, {cr}, {cr}] }}'],
                       duration=0.6, step=0.005)
        d, _ = build_body(m.body, m.scene("spinup").causality)
        b = BodySystem(d)
        bi = scene_inputs(d, m.scene("spinup"))
        b.initialize(0.0, bi)
        tip = []
        for _ in range(120):
            b.step(0.005, bi)
            tip.append(b.outputs()["tip"].r.copy())
        diffs.append(np.abs(np.array(tip) - np.array(tip_ref)).max())
    peak = np.abs(np.array(tip_ref)[:, 1]).max()
    assert diffs[1] < diffs[0] / 3, diffs
    assert diffs[1] < 1e-2 * peak, (diffs, peak)
