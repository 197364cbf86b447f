"""Shared set-ups: the benchmark beam sections of docs/background.md (B1, B2) as model.Section, the
model file of a small B1-like beam, and a body state far from its reference with the finite-
difference iteration matrix at it."""
import os

# as the CLI does (ffrf_fmu/cli/): one BLAS thread for the small body matrices, before numpy loads
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# no test reads what a previous run left in the user cache (~/.cache/ffrf-fmu: compiled runtime, FMU
# binaries, reduced bodies): the session gets a fresh one, as a fresh machine or CI has, unless the caller
# chose one ($FFRF_FMU_CACHE_DIR: .ci/run's round-off check builds its runtime in its own)
if not os.environ.get("FFRF_FMU_CACHE_DIR"):
    import atexit
    import shutil
    import tempfile

    _cache = tempfile.mkdtemp(prefix="ffrf-fmu-test-cache-")
    os.environ["FFRF_FMU_CACHE_DIR"] = _cache
    atexit.register(shutil.rmtree, _cache, True)

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ffrf_fmu.checked_toml import toml_key, toml_value
from ffrf_fmu.model import Section

_E, _NU, _A, _I, _RHO = 2.1e6, 0.3, 9.0, 6.75, 7.8e-3
BEAMS = {
    # B1 (geradin 9.2), L = 8: m22 = m33 = 22.7e-6 (docs/background.md, B1 note 2)
    "B1": (Section(EA=5.03e6, GJ=435.0, EI2=566.0, EI3=566.0, m=0.201, m22=22.7e-6, m33=22.7e-6, GA2=1.94e6, GA3=1.94e6), 8.0),
    # B2 (geradin 9.1), L = 141.42: E = 2.1e6, nu = 0.3, A = 9, I = 6.75 both axes, rho = 7.8e-3, Euler-Bernoulli
    "B2": (Section(EA=_E * _A, GJ=_E / (2 * (1 + _NU)) * 2 * _I, EI2=_E * _I, EI3=_E * _I, m=_RHO * _A, m22=_RHO * _I, m33=_RHO * _I), 141.42),
}


@pytest.fixture
def b1():
    """(Section, length) of benchmark B1."""
    return BEAMS["B1"]


@pytest.fixture
def b2():
    """(Section, length) of benchmark B2."""
    return BEAMS["B2"]


@pytest.fixture(params=sorted(BEAMS))
def beam(request):
    """(Section, length) of each benchmark beam in turn."""
    return BEAMS[request.param]


def b1_beam_toml(scenes: str, *, name: str | None = "small_beam", length: float = 8.0,
                 superelements: int = 2, elements: int = 4, modes: int = 2, shear: bool = True,
                 ports: str = "") -> str:
    """A model file of a beam with B1's section (L = 8 unless given) followed by `scenes` (TOML text).
    Ports: the hub (node 0) motion-driven and a free tip (node -1, default causality), unless
    `ports` gives the [body.ports.*] tables. name None: no name (the file's stem is taken);
    shear False: no GA2, GA3 (Euler-Bernoulli)."""
    lines = ["[body]", *([f'name = "{name}"'] if name else []), f"length = {length!r}",
             f"superelements = {superelements}", f"elements_per_superelement = {elements}", f"modes = {modes}",
             "[body.section]", "EA = 5.03e6", *(["GA2 = 1.94e6", "GA3 = 1.94e6"] if shear else []), "GJ = 435.38",
             "EI2 = 566.0", "EI3 = 566.0", "m = 0.201", "m22 = 22.7e-6", "m33 = 22.7e-6"]
    ports = ports or '[body.ports.hub]\nnode = 0\ntranslation = "motion"\nrotation = "motion"\n[body.ports.tip]\nnode = -1\n'
    return "\n".join(lines) + "\n" + ports + scenes


@pytest.fixture(scope="session")
def beam_toml():
    """b1_beam_toml: the model file text of a B1-like beam with the given scenes."""
    return b1_beam_toml


def _far_from_reference(s, seed: int = 1) -> dict:
    """Move BodySystem `s` far from its reference state (frames, modes, rates: a random state in
    which every term of the equations is visible) and return port inputs for a hub whose
    translation is motion-driven and rotation force-driven, with a free tip."""
    rng = np.random.default_rng(seed)
    from ffrf_fmu.runtime.ports import PortValues
    from ffrf_fmu.runtime.rotation import expm

    s.xN += rng.normal(size=s.xN.shape) * 0.05
    s.x0 += rng.normal(size=s.x0.shape) * 0.05
    s.RN = expm(rng.normal(size=s.RN.shape[:1] + (3,)) * 0.7)
    s.R0 = expm(rng.normal(size=s.R0.shape[:1] + (3,)) * 0.7)
    s.eta += rng.normal(size=s.eta.shape) * 0.01
    s.v += rng.normal(size=s.v.shape)
    s.yd = rng.normal(size=s.yd.shape)
    s.a = rng.normal(size=s.a.shape)
    return {
        "hub": PortValues(r=np.array([0.1, 0.2, 0.3]), v=np.array([1.0, 2.0, 3.0]), t=rng.normal(size=3)),
        "tip": PortValues(f=rng.normal(size=3), t=rng.normal(size=3)),
    }


@pytest.fixture(scope="session")
def far_from_reference():
    """far_from_reference(system, seed=1) -> port inputs: the system moved to a random state."""
    return _far_from_reference


def _iteration_matrix_check(s, values, h: float = 0.01, eps: float = 1e-6) -> float:
    """max |J - J_fd| / max |J| of the Newton iteration matrix at s.yd + 0.3 against central
    differences of the residual (eps = 1e-6 gives ~1e-8)."""
    yd = s.yd + 0.3
    _, J = s.newton_system(yd, h, values)
    J_fd = np.zeros_like(J)
    for j, g in enumerate(s._free_idx):
        yp, ym = yd.copy(), yd.copy()
        yp[g] += eps
        ym[g] -= eps
        J_fd[:, j] = (s.newton_system(yp, h, values, jacobian=False) - s.newton_system(ym, h, values, jacobian=False)) / (2 * eps)
    return float(np.max(np.abs(J - J_fd)) / np.max(np.abs(J)))


@pytest.fixture(scope="session")
def iteration_matrix_error():
    """iteration_matrix_error(system, values) -> relative difference of the iteration matrix to
    central differences."""
    return _iteration_matrix_check


# A small B1-like beam (2 superelements, 2 modes each: fast) with three scenes:
#  spin: hub driven at a constant rate in rotation and translation (ramps started before t = 0,
#        so that the rates are constant over the run: the FMU's extrapolation of motion inputs
#        is then exact) and a constant tip load (held inputs are then exact too);
#  spinup: a Wu-Haug spin-up (rates change: extrapolation is first order);
#  free: hub rotation force-driven (a torque input), for the failure tests.
SMALL_SCENES = """
[scenes.spin]
duration = 0.2
step = 0.01
[scenes.spin.drives.hub.rotation]
axis = [0.0, 0.0, 1.0]
angle = { kind = "ramp", rate = 0.5, t_start = -1.0 }
[scenes.spin.drives.hub.translation]
direction = [0.0, 1.0, 0.0]
displacement = { kind = "ramp", rate = 0.3, t_start = -1.0 }
[[scenes.spin.loads]]
port = "tip"
force = [0.0, 0.0, 2.0]
moment = [0.1, 0.0, 0.0]

[scenes.spinup]
duration = 0.3
step = 0.01
[scenes.spinup.drives.hub.rotation]
axis = [0.0, 0.0, 1.0]
angle = { kind = "haug_spinup", omega = 4.0, T = 1.0 }

[scenes.free]
duration = 0.2
step = 0.01
[scenes.free.causality.hub]
rotation = "force"
"""


@pytest.fixture(scope="session")
def small_toml():
    """small_toml(**body options of b1_beam_toml) -> the model file text of the small beam (SMALL_SCENES)."""
    return lambda **options: b1_beam_toml(SMALL_SCENES, **options)


@pytest.fixture(scope="module")
def small(tmp_path_factory, small_toml):
    """The small beam's model file (a fresh directory per test module)."""
    path = tmp_path_factory.mktemp("small") / "small.toml"
    path.write_text(small_toml())
    return path


@pytest.fixture(scope="module")
def small_fmu(small):
    """The small beam's pythonfmu FMU for its scene `spin` (the package's original route, `--runtime python`;
    the native FMU has its own tests: tests/test_native_fmu.py, and runs the fault table and the host tests)."""
    from ffrf_fmu.fmu.builder import build_fmu

    return build_fmu(small, small.parent / "small_spin.fmu", scene="spin", runtime="python")


def toml_table(name: str, **keys) -> str:
    """The model file's table [NAME] (a dotted path) with its keys, written by checked_toml's writer."""
    return "\n".join([f"[{'.'.join(toml_key(p) for p in name.split('.'))}]"]
                     + [f"{toml_key(k)} = {toml_value(v)}" for k, v in keys.items()])


def end_face_port(name: str, x: float, **keys) -> str:
    """A solid bar's port [body.ports.NAME] on its end face, the nodes of the plane x = const normal to X
    (docs/model-format.md, solids), with its further keys (toml_table)."""
    plane = {"point": [float(x), 0.0, 0.0], "normal": [1.0, 0.0, 0.0]}
    return toml_table(f"body.ports.{name}", select={"plane": plane}, **keys)


# A small solid bar (steel, 1 x 0.1 x 0.1 m, 4 quadratic serendipity hexahedra) on two end-face frames:
# the hub rigidly linked, translation motion-driven and rotation force-driven (far_from_reference's
# inputs), the tip averaging and force-driven.
SOLID_BAR = f"""
[body]
name = "solid_bar"
kind = "solid"
modes = 3
[body.mesh]
box = {{ size = [1.0, 0.1, 0.1], divisions = [4, 1, 1], origin = [0.0, -0.05, -0.05] }}
element = "hex20"
{toml_table("body.material", E=2.1e11, nu=0.3, rho=7850.0)}
{end_face_port("hub", 0.0, link="rigid", point=[0.0, 0.0, 0.0], translation="motion", rotation="force")}
{end_face_port("tip", 1.0, link="averaging", point=[1.0, 0.0, 0.0], translation="force", rotation="force")}
[scenes.s]
duration = 0.01
step = 0.001
"""


def solid_bar_body(stiffening: bool = True, inertia: bool = True):
    """(BodyData, SolidReduction) of SOLID_BAR, built once per process per option pair."""
    key = (stiffening, inertia)
    if key not in _SOLID_BARS:
        import tempfile

        from ffrf_fmu.model import load_model
        from ffrf_fmu.reduction import reduce_body

        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "solid_bar.toml")
            with open(path, "w") as f:
                f.write(SOLID_BAR)
            body = load_model(path).body
            reduced = reduce_body(body, stiffening=stiffening, inertia=inertia)
            data, (red,) = reduced.data, reduced.reductions
        _SOLID_BARS[key] = (data, red)
    return _SOLID_BARS[key]


_SOLID_BARS: dict = {}


@pytest.fixture(scope="session")
def solid_bar():
    """solid_bar(stiffening=True, inertia=True) -> (BodyData, SolidReduction) of a small solid bar."""
    return solid_bar_body


def stepping_on_is_an_error(slave, t: float, h: float, cause: str, retry_from: float) -> None:
    """After a step the FMU discarded (fmi2Discard, fmi3Discard), a master that steps on (doStep(t, h)) gets
    Error (3 in FMI 2.0 and 3.0), each time, with one log message naming the discard, its cause and the time
    to retry from. `slave` has .fmu (fmpy), .log [(status, category, message)] and .status(call, *args)."""
    for _ in range(2):
        slave.log.clear()
        assert slave.status(slave.fmu.doStep, t, h) == 3
        (st, _, msg), = slave.log
        assert st == 3 and "discarded" in msg and cause in msg and f"retry from t = {retry_from!r}" in msg, msg
