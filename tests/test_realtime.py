"""The hard real-time cap of the Newton iterations per step (a scene's `max_newton_iterations`, the FMU
parameter `solver.max_newton_iterations`; fmu/realtime.py, docs/fmu.md "Real-time datasheet") and the C host's
STEP_LOG mode of benchmarks/fmu_host_bench.c that measures the datasheet. No time is asserted.

B1 (models/haug_beam.toml, spinup: 4 superelements x 6 modes, h = 2 ms) shortened to 0.1 s: under the FMU at
H = h its steps take 1 or 2 Newton iterations (the first 2 at t = 0.02 s, benchmarks/realtime.py), so a cap
of 1 changes the result and a cap of 2 never binds.
"""
from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from ffrf_fmu.fmu.builder import BuildError, build_fmu
from ffrf_fmu.fmu.realtime import CAP_TOLERANCE
from ffrf_fmu.fmu.run import fmu_body, fmu_input_table, run_fmu, scene_start_values
from ffrf_fmu.model import ModelError, load_model
from ffrf_fmu.reduction import reduce_scene_body
from ffrf_fmu.simulate import run, scene_inputs

ROOT = Path(__file__).resolve().parent.parent
B1 = ROOT / "models" / "haug_beam.toml"
SHORT = ["duration=0.1"]


@pytest.fixture(scope="module")
def capped(tmp_path_factory):
    """B1's FMI 2.0 and FMI 3.0 FMUs built with max_newton_iterations = 2 (accepted: the check ran), 0.1 s."""
    d = tmp_path_factory.mktemp("realtime")
    over = [*SHORT, "max_newton_iterations=2"]
    return {fmi: build_fmu(B1, d / f"B1_cap2_fmi{fmi}.fmu", scene="spinup", overrides=over, fmi=fmi) for fmi in (2, 3)}


def test_a_cap_that_changes_the_result_is_refused_at_build_naming_cap_scene_and_step(tmp_path):
    with pytest.raises(BuildError) as e:
        build_fmu(B1, tmp_path / "B1.fmu", scene="spinup", overrides=[*SHORT, "max_newton_iterations=1"])
    msg = str(e.value)
    assert "max_newton_iterations = 1 changes the result of scene 'spinup'" in msg
    assert "takes 2 Newton iterations without the cap" in msg and "raise the cap to 2" in msg, msg
    assert not (tmp_path / "B1.fmu").exists()  # no FMU left behind


def test_a_cap_never_reached_leaves_the_fmu_bit_identical(capped):
    """The FMU built with cap 2 run with its cap and with the cap off (solver.max_newton_iterations = 0):
    every output equal bit for bit (the check at build measured this; here it is asserted directly)."""
    scene = load_model(B1, SHORT).scene("spinup")
    with_cap = run_fmu(capped[2], scene, start_values={"solver.max_newton_iterations": 2})
    without = run_fmu(capped[2], scene, start_values={"solver.max_newton_iterations": 0})
    assert with_cap.reached and without.reached
    it = without.columns["solver.newton_iterations"][1:]  # (the first sample is t = 0, before any step)
    assert it.min() == 1 and it.max() == 2  # the cap is reached exactly, never exceeded: the test means something
    for name, col in without.columns.items():
        assert np.array_equal(with_cap.columns[name], col), name
    assert CAP_TOLERANCE == 1e-8  # the stated tolerance (docs/fmu.md): 10 x the Newton tolerance 1e-9


@pytest.mark.parametrize("backend", ["native", "numpy"])
def test_the_standalone_run_honours_the_cap_on_both_backends(backend):
    """A cap that binds stops the run at the first step that needs more (the same step on both backends, the
    numpy path's verdict after the fact being step.c's bounded loop's); a cap that never binds changes nothing."""
    model = load_model(B1, ["duration=0.6"])
    scene = model.scene("spinup")
    body = reduce_scene_body(model.body, scene).data
    results = {}
    for cap in (0, 1, 2):
        results[cap] = run(body, dataclasses.replace(scene, max_newton_iterations=cap), origin=model.body.origin, progress=False, backend=backend)
    assert results[0].summary["completed"] and results[2].summary["completed"]
    for name, col in results[0].columns.items():
        assert np.array_equal(results[2].columns[name], col), name
    stopped = results[1]
    assert not stopped.summary["completed"]
    assert stopped.t[-1] == pytest.approx(0.544, abs=1e-9)  # measured: the step to 0.546 s needs 2 (both backends)


def _fmpy_run(fmu, scene, start_values) -> tuple[int | None, list[str]]:
    """fmpy.simulate_fmu of the FMI 2.0 FMU through the scene at H = h: (the status it raised on or None, the
    FMU's log)."""
    log: list[str] = []
    table = fmu_input_table(fmu, scene_inputs(fmu_body(fmu), scene),
                            scene.step * np.arange(round(scene.duration / scene.step) + 1))
    try:
        fmpy.simulate_fmu(str(fmu), stop_time=scene.duration, output_interval=scene.step, input=table,
                          start_values={**scene_start_values(scene, fmu), **start_values},
                          logger=lambda c, i, status, cat, msg: log.append(msg.decode()))
    except FMICallException as e:
        return e.status, log
    return None, log


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_step_over_the_cap_at_run_time_is_an_error_naming_the_cap(capped, fmi):
    """The FMU built with cap 2, instantiated with solver.max_newton_iterations = 1: the first step that needs
    2 iterations returns fmi2Error / fmi3Error (not a discard: a smaller step is no real-time answer), logged
    with the cap; the FMU is left at the step's start."""
    scene = load_model(B1, SHORT).scene("spinup")
    if fmi == 3:  # fmu/run.py's FMI 3.0 loop stops on the error and keeps the log
        out = run_fmu(capped[3], scene, start_values={"solver.max_newton_iterations": 1})
        assert not out.reached
        log = out.log
    else:
        status, log = _fmpy_run(capped[2], scene, {"solver.max_newton_iterations": 1})
        assert status == 3  # fmi2Error
    text = "\n".join(log)
    assert "Newton did not converge within max_newton_iterations = 1 iterations" in text, text[-2000:]
    assert "t = 0.02 s" in text  # the first step that needs 2 (test_a_cap_that_changes...: 'the step to t = 0.02 s')


def test_a_bad_cap_is_refused_in_the_model_and_at_initialization(capped):
    with pytest.raises(ModelError) as e:
        load_model(B1, ["max_newton_iterations=-1"])
    assert "max_newton_iterations" in str(e.value)
    scene = load_model(B1, SHORT).scene("spinup")
    status, log = _fmpy_run(capped[2], scene, {"solver.max_newton_iterations": -1})
    assert status == 3  # fmi2Error at initialization
    want = "parameter solver.max_newton_iterations must be an integer in 0 .. 2^31 - 1 (0: no cap), got -1"
    assert any(want in m for m in log), log


def test_the_c_hosts_step_log_reads_the_fmus_iterations_per_doStep(capped, tmp_path):
    """benchmarks/fmu_host_bench.c in its STEP_LOG mode (benchmarks/realtime.py): one row per doStep, the wall
    and CPU times finite and positive, and the iterations it read (fmi2GetInteger of solver.newton_iterations)
    those fmpy records for the same FMU and inputs, step by step."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from fmu_overhead import host_command, host_table

    model = load_model(B1, SHORT)
    scene = model.scene("spinup")
    body = reduce_scene_body(model.body, scene).data
    host, md = host_command(capped[2], scene, tmp_path)
    n = host_table(capped[2], body, scene, scene_inputs(body, scene), scene.step, tmp_path / "table.bin")
    vr = next(v.valueReference for v in md.modelVariables if v.name == "solver.newton_iterations")
    done = subprocess.run([*host, str(tmp_path / "table.bin"), str(n), repr(scene.step), "1", "1",
                           str(tmp_path / "steps.bin"), str(vr)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    rows = np.fromfile(tmp_path / "steps.bin", dtype="<f8").reshape(-1, 3)
    assert rows.shape == (n, 3) and n == 50
    assert np.all(np.isfinite(rows[:, :2])) and np.all(rows[:, :2] > 0.0)
    ref = run_fmu(capped[2], scene, record=["solver.newton_iterations"])
    assert np.array_equal(rows[:, 2], ref.columns["solver.newton_iterations"][1:])  # fmpy's first sample is t = 0
    assert set(rows[:, 2]) == {1.0, 2.0}
