"""Modal coordinates as FMU outputs (docs/fmu.md, "Variables"): every superelement's modal amplitudes
modal.eta[e,i] and their rates modal.eta_rate[e,i], in the native FMI 2.0 and 3.0 FMUs and the pythonfmu
FMU, against the standalone run's eta (BodySystem.eta, and the eta slots of its rates).

The small B1-like beam (tests/conftest.py: 2 superelements x 2 modes) in its scene `spin`: hub rates
constant and the tip load constant, so the FMU's input rule reproduces the scene's signals exactly and
the FMU must equal the standalone run to the Newton tolerance (as validate checks there, 1e-7 of each
group's peak); the tip load excites the modes. Measured: 3.4e-12 of the peak (C FMUs), 3.8e-12 (pythonfmu)."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description

from ffrf_fmu import simulate as sim
from ffrf_fmu.fmu.builder import build_fmu
from ffrf_fmu.fmu.run import run_fmu
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_scene_body


@pytest.fixture(scope="module")
def standalone(small):
    """(times, eta (nt, E, nm), eta rates (nt, E, nm), scene) of the standalone run, one step at a time."""
    model = load_model(small)
    sc = model.scene("spin")
    body = reduce_scene_body(model.body, sc).data
    s, inputs = sim.build_system(body, sc, model.body.origin, "native")
    slots = s.layout.cfg_map[:, 6 : 6 + s.layout.nm]
    t, eta, rate = [s.t], [s.eta.copy()], [s.yd[slots].copy()]
    for _ in range(int(round(sc.duration / sc.step))):
        s.step(sc.step, inputs)
        t.append(s.t)
        eta.append(s.eta.copy())
        rate.append(s.yd[slots].copy())
    return np.array(t), np.array(eta), np.array(rate), sc


@pytest.mark.parametrize("kind", ["native2", "native3", "python"])
def test_modal_outputs_are_the_standalone_runs_eta(small, standalone, kind, tmp_path):
    t, eta, rate, sc = standalone
    E, nm = eta.shape[1:]
    fmu = build_fmu(small, tmp_path / f"{kind}.fmu", scene="spin", runtime="python" if kind == "python" else "native",
                    fmi=3 if kind == "native3" else 2)
    md = read_model_description(str(fmu))
    described = {v.name: v for v in md.modelVariables}
    if kind == "native3":  # one array of shape (E, nm) each
        v = described["modal.eta"]
        assert v.causality == "output" and [int(d.start) for d in v.dimensions] == [E, nm]
    else:
        assert {f"modal.eta[{e},{i}]" for e in range(1, E + 1) for i in range(1, nm + 1)} <= set(described)
        v = described[f"modal.eta[{E},{nm}]"]
        assert v.causality == "output" and "free-free mode" in v.description and "sqrt(kg) m" in v.description
    run = run_fmu(fmu, sc)
    assert run.reached, run.log[-3:]
    idx = np.searchsorted(t, run.t - 1e-9)
    assert np.allclose(t[idx], run.t)
    for field, ref in (("eta", eta), ("eta_rate", rate)):
        got = np.stack([np.stack([run.columns[f"modal.{field}[{e + 1},{i + 1}]"] for i in range(nm)], -1)
                        for e in range(E)], 1)
        peak = np.abs(ref).max()
        err = np.abs(got - ref[idx]).max() / peak
        assert peak > {"eta": 1e-3, "eta_rate": 0.1}[field], (field, peak)  # the modes move (1.6e-3, 0.65)
        assert err < 1e-9, (field, err, peak)  # measured 3.4e-12 (C), 3.8e-12 (pythonfmu): the Newton tolerance
