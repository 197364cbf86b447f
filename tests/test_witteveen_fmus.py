"""Witteveen's seven bodies (docs/inertia-terms.md) each build an FMU that validates under fmpy against its
standalone run. Four are checked here; the other three where their bodies are tested: the plate
(tests/test_shell_body.py), the car body (tests/test_car_body.py, second order in the communication step) and
GenStruct1 (tests/test_genstruct.py). Each scene is cut to its first 200 steps or so (`duration`), the spin-up
under way: what is validated is the FMU's equality with the standalone run, not the scene's end.

Tolerances: validate's own (rtol 1e-3 per output group, docs/fmu.md), every group, against the standalone run
under the FMU's input rule; the cost of that rule against exact inputs at every step's end is reported apart
(`input_sampling`), not judged here."""
from pathlib import Path

import pytest

MODELS = Path(__file__).resolve().parents[1] / "models"

CASES = {"conrod": 0.02, "jeffcott_rotor": 0.2, "witteveen_beam": 0.2, "genstruct2": 0.05}  # duration [s] validated


@pytest.mark.parametrize("name", sorted(CASES))
def test_fmu_validates_under_fmpy(tmp_path, name):
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.model import load_model
    from ffrf_fmu.validate import validate

    duration = CASES[name]
    model, o = MODELS / f"{name}.toml", [f"duration={duration!r}"]
    fmu = build_fmu(model, tmp_path / f"{name}.fmu", overrides=o)
    rep = validate(fmu, model=model, overrides=o, plots=False)
    assert rep["fmu_reached_stop_time"] and rep["fmu_matches_model"]
    groups = rep["groups"]
    assert len(groups) >= 2 * len(load_model(model, o).body.ports), sorted(groups)  # r, f, ... of every port compared
    assert rep["passed"] and all(g["passed"] for g in groups.values()), {k: g["max_rel_diff"] for k, g in groups.items()}
