"""The ModelStructure states the real dependencies: no output depends directly on an input
(dependencies=""), checked against the FMU's behaviour: every input perturbed, every output read
before the next doStep, none moves; after a doStep they do (so the probe can see a dependency).
Three port layouts of models/haug_beam.toml: B1 (hub motion-driven, tip force-driven), B5 (hub
rotation force-driven) and B5 with the compliant hub (motion in, force out)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from ffrf_fmu.fmu.builder import build_fmu
from ffrf_fmu.master import FmuInstance

HAUG = Path(__file__).resolve().parent.parent / "models" / "haug_beam.toml"
COMPLIANT = ['scenes.hub_free.causality.hub.rotation="compliant"',
             "body.ports.hub.coupling={ rotational_stiffness = [0.0, 0.0, 300.0], rotational_damping = [0.0, 0.0, 0.0] }"]
CASES = {"b1": dict(scene="spinup"), "b5": dict(scene="hub_free"), "b5_compliant": dict(scene="hub_free", overrides=COMPLIANT)}
H = 0.01


def _rotated(R: np.ndarray, angle: float) -> np.ndarray:
    """R turned about world Z by angle (stays a rotation: a single entry of R perturbed would not)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R


@pytest.mark.parametrize("case", sorted(CASES))
def test_no_output_moves_when_an_input_is_set_before_a_step(case, tmp_path):
    fmu = build_fmu(HAUG, tmp_path / f"{case}.fmu", **CASES[case])
    md = read_model_description(str(fmu))
    assert md.outputs and all(u.dependencies == [] for u in md.outputs)
    inst = FmuInstance(case, fmu)
    try:
        f = inst.fmu
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        for k in range(3):
            f.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
        outs = inst.names("output")
        ins = [n for n in inst.names("input") if inst.variable(n).type == "Real"]
        assert ins
        base, x0 = inst.get(outs), inst.get(ins)
        frames = sorted({n.split(".R[")[0] for n in ins if ".R[" in n})
        for j, n in enumerate(ins):
            if ".R[" in n:
                continue
            inst.set([n], [x0[j] + 1e-3 * (abs(x0[j]) + 1.0)])
            assert np.array_equal(inst.get(outs), base), n
            inst.set([n], [x0[j]])
        for port in frames:  # a rotation input as a rotation
            names = [f"{port}.R[{i},{k}]" for i in (1, 2, 3) for k in (1, 2, 3)]
            R0 = inst.get(names).reshape(3, 3)
            inst.set(names, _rotated(R0, 1e-3).ravel())
            assert np.array_equal(inst.get(outs), base), port
            inst.set(names, R0.ravel())
        # the probe sees a dependency where there is one: over a step the outputs follow the inputs
        state = f.getFMUstate()
        f.doStep(currentCommunicationPoint=3 * H, communicationStepSize=H)
        plain = inst.get(outs)
        f.setFMUstate(state)
        loads = [n for n in ins if ".f[" in n or ".t[" in n] or ins
        inst.set([loads[0]], [inst.get([loads[0]])[0] + 1.0])
        f.doStep(currentCommunicationPoint=3 * H, communicationStepSize=H)
        assert not np.array_equal(inst.get(outs), plain)
        f.freeFMUstate(state)
    finally:
        inst.close()
