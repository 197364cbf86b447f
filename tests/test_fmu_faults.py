"""Body FMU fault paths per FMI 2.0, initial port displacements inside the FMU and its BLAS thread
limit, under fmpy in this process.

fmi2Discard is for numerical failures the master can recover from (the FMU stays at t_c);
fmi2Error for everything else, with the cause in the log; never fmi2Fatal, never a crash: each
bad call is made twice and the instance is freed afterwards.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException

from conftest import stepping_on_is_an_error
from ffrf_fmu.fmu.builder import build_fmu, read_fmu_config
from ffrf_fmu.master import FmuInstance
from ffrf_fmu.validate import validate

DISCARD, ERROR = 2, 3

SCENES = """
[scenes.still]
duration = 0.2
step = 0.01

[scenes.bent]
duration = 0.2
step = 0.01
[scenes.bent.initial]
port_displacements.tip = [0.0, 0.01, 0.0]
"""


@pytest.fixture(scope="module")
def model(tmp_path_factory, beam_toml):
    path = tmp_path_factory.mktemp("faults") / "fault_beam.toml"
    path.write_text(beam_toml(SCENES, name="fault_beam"))
    return path


@pytest.fixture(scope="module", params=["native", "python"])
def fmu(model, request):
    """The FMU of scene `still` of each runtime (native: C over the C runtime; python: pythonfmu): the fault
    table holds for both, status and message."""
    return build_fmu(model, model.parent / f"still_{request.param}.fmu", scene="still",
                            runtime=request.param, platforms=("linux64",))


@pytest.fixture(scope="module")
def python_fmu(model):
    """The pythonfmu FMU alone on backend numpy (tests that reach into its Python runtime's step)."""
    return build_fmu(model, model.parent / "still_python_numpy.fmu", scene="still", runtime="python",
                            backend="numpy")


class Slave:
    """An FmuInstance (master/instance.py: per-instance log) with value references by name."""

    def __init__(self, path):
        self.inst = FmuInstance("body", path)
        self.fmu = self.inst.fmu
        self.log = self.inst.messages
        self.vr = {n: v.valueReference for n, v in self.inst.vars.items()}

    def status(self, call, *args) -> int:
        """The fmi2Status of a call (0 when fmpy did not raise)."""
        try:
            call(*args)
        except FMICallException as e:
            return e.status
        return 0

    def start(self, values=None, stop=None):
        f = self.fmu
        f.setupExperiment(startTime=0.0, stopTime=stop)
        f.enterInitializationMode()
        for name, value in (values or {}).items():
            (f.setInteger if name == "solver.terms" else f.setReal)([self.vr[name]], [value])
        return self.status(f.exitInitializationMode)

    def close(self):
        self.inst.close()


@pytest.mark.parametrize("values, stop, cause", [
    ({"solver.rho_inf": 2.0}, None, "solver.rho_inf must be in [0, 1], got 2.0"),
    ({"solver.step": 0.0}, None, "solver.step must be positive and finite, got 0.0"),
    ({"solver.terms": 7}, None, "solver.terms must be 0 (linear), 1 (gyroscopic) or 2 (full), got 7"),
    ({"solver.step": 1e9}, 0.2, "solver.step = 1e+09 s is longer than the experiment"),
    ({"initial.v[1]": 0.5}, None, "initial.v = [0.5, 0.0, 0.0] is set, but the translation of port hub is motion-driven"),
    ({"initial.w[3]": 1.0}, None, "initial.w = [0.0, 0.0, 1.0] is set, but the rotation of port hub is motion-driven"),
    ({"initial.tip.d[2]": math.nan}, None, "initial.tip.d is not finite"),
])
def test_invalid_parameters_make_exit_initialization_an_error(fmu, values, stop, cause):
    s = Slave(fmu)
    try:
        assert s.start(values, stop) == ERROR
        assert any(st == ERROR and cause in msg for st, _, msg in s.log), s.log
        for _ in range(2):  # every doStep is then an error naming the cause, not a silent discard
            s.log.clear()
            assert s.status(s.fmu.doStep, 0.0, 0.01) == ERROR
            assert any(st == ERROR and cause in msg for st, _, msg in s.log), s.log
    finally:
        s.close()


def test_parameters_declare_min_and_max(fmu):
    md = read_model_description(str(fmu))
    by = {v.name: v for v in md.modelVariables}
    assert (float(by["solver.rho_inf"].min), float(by["solver.rho_inf"].max)) == (0.0, 1.0)
    assert (int(by["solver.terms"].min), int(by["solver.terms"].max)) == (0, 2)  # linear, gyroscopic, full


def test_bad_calls_are_errors_twice_and_the_instance_survives(fmu):
    """Unknown value references and calls of the wrong type: fmi2Error (pythonfmu alone gave
    fmi2Fatal with a NULL log category, and the second call crashed the host)."""
    s = Slave(fmu)
    try:
        real, integer = s.vr["tip.f[3]"], s.vr["solver.terms"]
        calls = [
            (s.fmu.getReal, [10**6], "unknown value reference(s) [1000000]"),
            (s.fmu.setReal, [10**6], [1.0], "unknown value reference(s) [1000000]"),
            (s.fmu.setInteger, [real], [1], "tip.f[3]: Real) are not Integer"),
            (s.fmu.getReal, [integer], "solver.terms: Integer) are not Real"),
            (s.fmu.getInteger, [real], "tip.f[3]: Real) are not Integer"),
            (s.fmu.setReal, [s.vr["tip.r[1]"]], [1.0], "tip.r[1] is an output: it cannot be set"),
        ]
        for call, *args, cause in calls:
            for _ in range(2):
                s.log.clear()
                assert s.status(call, *args) == ERROR
                assert [(st, cat) for st, cat, _ in s.log] == [(ERROR, "logStatusError")], s.log
                assert cause in s.log[0][2]
        assert s.start({"tip.f[3]": 1.0}) == 0, s.log  # the instance still works
        s.fmu.doStep(0.0, 0.01)
        assert s.fmu.getReal([s.vr["tip.r[3]"]])[0] > 0.0  # pushed up by the tip force
    finally:
        s.close()


def test_stepping_on_after_a_discard_is_an_error_naming_it(fmu):
    """A master that ignores fmi2Discard and steps on gets fmi2Error with the earlier failure in the
    log (ecos kept advancing, and the body stayed frozen without a further word)."""
    s = Slave(fmu)
    try:
        assert s.start() == 0
        s.fmu.doStep(0.0, 0.01)
        s.fmu.setReal([s.vr["tip.f[2]"]], [math.nan])
        assert s.status(s.fmu.doStep, 0.01, 0.01) == DISCARD
        stepping_on_is_an_error(s, 0.02, 0.01, "tip.f[2] not finite", 0.01)
        s.fmu.setReal([s.vr["tip.f[2]"]], [0.0])  # the recovery the discard allows still works
        s.fmu.doStep(0.01, 0.01)
    finally:
        s.close()


def test_programming_error_inside_the_step_is_an_error_with_its_traceback(python_fmu, monkeypatch):
    """Discard only for numerical failures: an exception that is not a StepFailure (here a
    TypeError planted in the FMU's own copy of the runtime) is fmi2Error with the traceback."""
    s = Slave(python_fmu)
    try:
        assert s.start() == 0
        pkg = read_fmu_config(python_fmu)["names"]["package"] + ".runtime.body"  # this FMU's own private runtime
        system_cls = sys.modules[pkg].BodySystem

        def broken(self, *args, **kwargs):
            raise TypeError("planted bug")

        monkeypatch.setattr(system_cls, "step", broken)
        s.log.clear()
        assert s.status(s.fmu.doStep, 0.0, 0.01) == ERROR
        monkeypatch.undo()
        (st, cat, msg), = s.log
        assert st == ERROR and "TypeError: planted bug" in msg and "Traceback (most recent call last)" in msg
    finally:
        s.close()


def test_initial_port_displacement_reaches_the_fmu(model, tmp_path):
    """initial.tip.d was dead inside the FMU (every group BAD, tip.r off by 0.01): the FMU built
    from a scene with a tip displacement now equals the standalone run. Hub at rest and no loads:
    the held inputs are exact, so the runs agree to the Newton tolerance (rtol 1e-7)."""
    rep = validate(model, scene="bent", report_dir=tmp_path / "rep", plots=False)
    assert rep["passed"] and rep["fmu_reached_stop_time"], rep["groups"]
    for g, d in rep["groups"].items():
        assert d["max_rel_diff"] < 1e-7, (g, d)
    # the displacement is there: the standalone run, which the FMU equals to 1e-7 of max |tip.r| (8 m,
    # so 8e-7 m), starts the tip 0.01 m off its reference y (to the static solve's tolerance)
    from ffrf_fmu.simulate import run_scene

    run = run_scene(str(model), "bent")
    y_ref = run.body.node_positions[run.body.port("tip").node][1]
    assert run.columns["tip.r[2]"][0] - y_ref == pytest.approx(0.01, abs=1e-9)


def test_fmu_limits_blas_to_one_thread_during_its_calls_only(python_fmu, monkeypatch):
    """BLAS threads: one thread while the FMU steps (threadpoolctl, scoped), the
    host's own setting (here 2 threads) before and after the call."""
    from threadpoolctl import threadpool_info, threadpool_limits

    blas_threads = lambda: {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}
    s = Slave(python_fmu)
    try:
        assert s.start() == 0
        pkg = read_fmu_config(python_fmu)["names"]["package"] + ".runtime.body"  # this FMU's own private runtime
        system_cls = sys.modules[pkg].BodySystem
        seen = []
        original = system_cls.step

        def recording(self, *args, **kwargs):
            seen.append(blas_threads())
            return original(self, *args, **kwargs)

        monkeypatch.setattr(system_cls, "step", recording)
        with threadpool_limits(limits=2, user_api="blas"):
            assert blas_threads() == {2}
            s.fmu.doStep(0.0, 0.02)
            assert blas_threads() == {2}
        assert seen == [{1}, {1}]  # two internal steps of solver.step = 0.01
    finally:
        s.close()


def test_shipped_modules_may_import_threadpoolctl_only_when_guarded():
    from ffrf_fmu.fmu.builder import BuildError, check_shipped_imports

    check_shipped_imports({"a.py": "try:\n    import threadpoolctl\nexcept ImportError:\n    threadpoolctl = None\n"})
    with pytest.raises(BuildError, match="threadpoolctl"):
        check_shipped_imports({"a.py": "import threadpoolctl\n"})


def test_reflection_input_is_refused_naming_the_reflection(fmu):
    """A reflection is orthonormal: the message says it is a reflection (it read
    'max |R^T R - I| = 0 > 1e-06 or det = -1 <= 0')."""
    s = Slave(fmu)
    try:
        assert s.start() == 0
        s.fmu.setReal([s.vr["hub.R[3,3]"]], [-1.0])  # diag(1, 1, -1)
        assert s.status(s.fmu.doStep, 0.0, 0.01) == DISCARD
        (st, _, msg), = [m for m in s.log if m[0] == DISCARD]
        assert "hub.R is not a rotation matrix (a reflection: det = -1, a rotation has det = +1)" in msg
    finally:
        s.close()


def test_build_output_must_be_an_fmu_or_a_directory(model, tmp_path):
    """`build -o x.txt` made a directory x.txt/ with the FMU inside: now a clear BuildError."""
    from ffrf_fmu.fmu.builder import BuildError

    with pytest.raises(BuildError, match=r"x\.txt: an FMU file name must end in \.fmu"):
        build_fmu(model, tmp_path / "x.txt", scene="still")
    assert not (tmp_path / "x.txt").exists()


def test_simulation_csv_header_has_one_field_per_column(model, tmp_path):
    """`simulate --out` wrote hub.R[1,1] unquoted: a CSV reader saw 72 header fields for 54 columns."""
    import csv

    from ffrf_fmu.model import load_model
    from ffrf_fmu.simulate import run_scene

    res = run_scene(load_model(model, ["scenes.still.duration=0.02"]), "still")
    res.write_csv(tmp_path / "r.csv")
    with open(tmp_path / "r.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert len(rows[0]) == len(rows[1]) == 1 + len(res.columns)
    assert "hub.R[1,1]" in rows[0] and rows[0][0] == "time"


def test_simulate_port_displacements_without_equilibrium_exit_2(capsys):
    """A free beam with its end pulled sideways by its own length (8 m) has no relaxed static shape the
    initialization finds: a clear error and exit status 2 (it was a raw ValueError traceback)."""
    from ffrf_fmu.cli import main

    root = Path(__file__).resolve().parent.parent
    status = main(["simulate", str(root / "models" / "free_beam.toml"), "--set", "scenes.tumble.duration=0.01",
                   "--set", "scenes.tumble.initial.port_displacements.b=[0,8,0]"])
    err = capsys.readouterr().err
    assert status == 2
    assert "scene 'tumble' cannot start: initial port displacements ['b']: no static equilibrium" in err


def test_initial_velocities_are_the_initial_field_under_an_initial_load(fmu):
    """A load set at initialization accelerates the body but does not move it yet: the tip starts
    at rest (it started at 1.76e-4 m/s per N on B1: the rates of a backward-Euler micro-step of
    1e-6 s were taken as the initial velocities)."""
    s = Slave(fmu)
    try:
        assert s.start({"tip.f[3]": 1.0}) == 0
        assert s.fmu.getReal([s.vr[f"tip.v[{i}]"] for i in (1, 2, 3)]) == [0.0, 0.0, 0.0]
        s.fmu.doStep(0.0, 0.01)
        assert s.fmu.getReal([s.vr["tip.v[3]"]])[0] > 0.0  # and then it moves along the load
    finally:
        s.close()


def test_tumbling_free_beam_starts_with_the_rigid_velocity_field_under_a_load():
    """Free beam (no motion-driven port), initial angular velocity w and a force on end b from t = 0:
    the initial velocity of every port is the rigid field w x (x - origin), to round-off (a guard
    for the exact initial rates with a displaced port, modal rates included, under rotation)."""
    from ffrf_fmu.model import load_model
    from ffrf_fmu.model import scene_body
    from ffrf_fmu.reduction import reduce_body
    from ffrf_fmu.runtime.body import BodySystem
    from ffrf_fmu.simulate import scene_inputs

    root = Path(__file__).resolve().parent.parent
    model = load_model(root / "models" / "free_beam.toml")
    sc = model.scene("tumble")
    data = reduce_body(scene_body(model.body, sc)).data
    base = scene_inputs(data, sc)

    def inputs(t):
        v = base(t)
        v["b"].f = np.array([0.0, 3.0, 5.0])
        return v

    w = np.array([0.3, 0.5, 2.0])
    system = BodySystem(data, terms=sc.terms, rho_inf=sc.rho_inf)
    system.initialize(0.0, inputs, angular_velocity=w, origin=model.body.origin)
    for name, pv in system.outputs().items():
        expected = np.cross(w, pv.r - np.asarray(model.body.origin))
        assert np.allclose(pv.v, expected, rtol=0.0, atol=1e-13 * max(1.0, np.abs(expected).max())), name
        assert np.allclose(pv.w, w, rtol=0.0, atol=1e-14), name


def _core(fmu, tmp_path):
    """The FMU's BodyCoSim in this process, from its unpacked resources."""
    import zipfile

    from ffrf_fmu.fmu.core import BodyCoSim

    zipfile.ZipFile(fmu).extractall(tmp_path)
    return BodyCoSim.from_resources(tmp_path / "resources")


def _hub_at_rest(core):
    """Every hub input of a body at rest at the reference (R = I), set in initialization mode."""
    names = [v.name for v in core.variables if v.causality == "input" and v.name.startswith("hub.")]
    core.set_many([core.by_name[n] for n in names], [1.0 if n in ("hub.R[1,1]", "hub.R[2,2]", "hub.R[3,3]") else 0.0
                                                     for n in names])


def test_set_many_refuses_per_mode_with_the_same_list_again_and_instances_apart(python_fmu, tmp_path):
    """set_many keeps each value-reference list's index array and causalities (a host sets the same list
    every step): a list with a parameter is accepted in initialization and refused in step mode, one
    with an output always, in order up to the first refused value; a second instance of the same FMU
    keeps its own values."""
    a, b = _core(python_fmu, tmp_path / "a"), _core(python_fmu, tmp_path / "b")
    rho, f1, r1 = a.by_name["solver.rho_inf"], a.by_name["tip.f[1]"], a.by_name["tip.r[1]"]
    for core in (a, b):
        core.setup_experiment(0.0)
        core.enter_initialization_mode()
        _hub_at_rest(core)
    assert a.set_many([rho, f1], [0.5, 1.0]) == ""
    assert b.set_many([rho, f1], [0.6, 3.0]) == ""
    assert (a.values[rho], a.values[f1], b.values[rho], b.values[f1]) == (0.5, 1.0, 0.6, 3.0)
    assert a.exit_initialization_mode() == "" and b.exit_initialization_mode() == ""
    assert a.set_many([rho, f1], [0.7, 2.0]) == "solver.rho_inf is a fixed parameter: it cannot change after initialization"
    assert (a.values[rho], a.values[f1]) == (0.5, 1.0)  # the parameter came first: nothing set
    assert a.set_many([f1, r1], [2.0, 9.0]) == "tip.r[1] is an output: it cannot be set"
    assert a.values[f1] == 2.0 and a.values[r1] != 9.0  # set in order up to the refused output
    for value in (4.0, 5.0):  # the same list again: a plain scatter
        assert a.set_many([f1], [value]) == "" and a.values[f1] == value
    assert (b.values[rho], b.values[f1]) == (0.6, 3.0)


@pytest.mark.filterwarnings("ignore:overflow encountered")
def test_finite_checks_refuse_nan_and_inf_but_not_a_sum_that_overflows(python_fmu, tmp_path):
    """The doStep's finite checks sum first (a NaN or inf makes the sum non-finite): an input or
    state of huge finite values whose sum overflows passes, one NaN or inf anywhere is refused."""
    from types import SimpleNamespace

    from ffrf_fmu.fmu.core import BodyCoSim
    from ffrf_fmu.runtime.ports import StepFailure

    huge = np.full(4, 1e308)
    BodyCoSim._check_finite(SimpleNamespace(t=0.1, yd=huge), huge)  # sums inf, entries finite: passes
    for outputs, yd in ((np.array([1.0, np.nan]), huge), (huge, np.array([0.0, -np.inf]))):
        with pytest.raises(StepFailure, match="the state is not finite"):
            BodyCoSim._check_finite(SimpleNamespace(t=0.1, yd=yd), outputs)
    core = _core(python_fmu, tmp_path)
    f1, f2 = core.by_name["tip.f[1]"], core.by_name["tip.f[2]"]
    core.values[[f1, f2]] = 1e308
    assert core._point_values(0.0)[1] == ""
    core.values[f2] = -math.inf
    assert core._point_values(0.0)[1] == "t = 0 s: input(s) tip.f[2] not finite (NaN or inf)"
