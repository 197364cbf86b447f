"""validate.py: what makes a validation pass, and comparisons only where both runs have values."""
from __future__ import annotations

import numpy as np
import pytest

from ffrf_fmu.fmu.builder import build_fmu
from ffrf_fmu.validate import compare, validate



def test_comparison_stops_where_the_reference_stopped():
    """A reference that stopped at t = 2 s against an FMU run to 4 s with the same signal y = t:
    interpolating past t = 2 would hold y = 2 and report a difference of 2 that no run computed.
    The comparison covers [0, 2] only (difference 0) and says so."""
    t_ref, t_fmu = np.linspace(0.0, 2.0, 21), np.linspace(0.0, 4.0, 41)
    g = compare(t_fmu, {"tip.r[1]": t_fmu}, t_ref, {"tip.r[1]": t_ref}, ["tip.r[1]"], rtol=1e-3, atol=1e-9)["tip.r"]
    assert g["max_abs_diff"] == pytest.approx(0.0, abs=1e-12) and g["passed"]
    assert g["compared_until"] == pytest.approx(2.0)


def test_fmu_of_another_model_fails(tmp_path, small_toml):
    """An FMU built with another torsional stiffness (GJ = 435.5 instead of 435.38, +0.03 %): its
    reduced stiffness differs from the model's (fmu_matches_model is False) while its outputs in the
    scene `spin` (constant rates: the same FMU equals the standalone run to 1e-7) move by at most
    5.3e-4 (measured, tip.w), inside the default rtol 1e-3. Such a validation must fail, not pass
    with a warning."""
    model = tmp_path / "small.toml"
    model.write_text(small_toml())  # the small B1-like beam; its scene `spin` has constant rates and loads
    other = tmp_path / "other.toml"
    other.write_text(small_toml().replace("GJ = 435.38", "GJ = 435.5"))
    fmu = build_fmu(other, tmp_path / "other.fmu", scene="spin")
    rep = validate(fmu, model=model, scene="spin", plots=False)
    assert rep["fmu_reached_stop_time"] and all(g["passed"] for g in rep["groups"].values())
    assert not rep["fmu_matches_model"] and not rep["passed"]
    # and the FMU of the model itself passes
    same = build_fmu(model, tmp_path / "same.fmu", scene="spin")
    rep = validate(same, model=model, scene="spin", plots=False)
    assert rep["fmu_matches_model"] and rep["passed"]


def test_the_standalone_run_steps_on_the_fmus_backend(tmp_path, small_toml):
    """The standalone reference of a validation runs on the backend the FMU steps on (its config), so
    that FMU and standalone compare the same equations' code."""
    model = tmp_path / "small.toml"
    model.write_text(small_toml())
    fmu = build_fmu(model, tmp_path / "small.fmu", scene="spin", backend="numpy", runtime="python")
    rep = validate(fmu, model=model, scene="spin", plots=False)
    assert rep["passed"]
    assert rep["backend"] == {"fmu": "numpy", "standalone": "numpy"}
