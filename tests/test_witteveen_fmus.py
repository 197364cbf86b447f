"""Witteveen's seven bodies (docs/inertia-terms.md) each build an FMU that validates under fmpy against its
standalone run. Four are checked here; the other three where their bodies are tested: the plate
(tests/test_shell_body.py), the car body (tests/test_car_body.py, second order in the communication step) and
GenStruct1 (tests/test_genstruct.py). Each scene is cut to its first 200 steps or so (`duration`), the spin-up
under way: what is validated is the FMU's equality with the standalone run, not the scene's end.

Tolerances: validate's own (rtol 1e-3 per output group, docs/fmu.md), but GenStruct2's hub reaction force: the
body is balanced, so that force is a residue (2.6e-4 N at 200 rad/s) of the internal centrifugal load
(m / 2) w^2 (b / 4) of each half; its difference is held to 1e-3 of that load, as GenStruct1's
(tests/test_genstruct.py: the FMU extrapolates the motion inputs within a communication step)."""
from pathlib import Path

import pytest

MODELS = Path(__file__).resolve().parents[1] / "models"

CASES = {  # model: (duration [s] of the validated run, the output group held to 1e-3 of a load instead, that load)
    "conrod": (0.02, None, None),
    "jeffcott_rotor": (0.2, None, None),
    "witteveen_beam": (0.2, None, None),
    "genstruct2": (0.05, "hub.f", 0.4 / 2 * 200.0**2 * 0.2 / 4),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_fmu_validates_under_fmpy(tmp_path, name):
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.model import load_model
    from ffrf_fmu.validate import validate

    duration, group, load = CASES[name]
    model, o = MODELS / f"{name}.toml", [f"duration={duration!r}"]
    fmu = build_fmu(model, tmp_path / f"{name}.fmu", overrides=o)
    rep = validate(fmu, model=model, overrides=o, plots=False)
    assert rep["fmu_reached_stop_time"] and rep["fmu_matches_model"]
    groups = rep["groups"]
    assert len(groups) >= 2 * len(load_model(model, o).body.ports), sorted(groups)  # r, f, ... of every port compared
    assert all(g["passed"] for k, g in groups.items() if k != group), {k: g["max_rel_diff"] for k, g in groups.items()}
    if group:
        assert groups[group]["max_abs_diff"] < 1e-3 * load
