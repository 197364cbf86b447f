"""Build a body FMU: reduced data + a private copy of the runtime + a pythonfmu script.

Layout of resources/ in the FMU (the FMU is a black box: no FE mesh, no model file):

    ffrf_slave_<body>_<hash>.py     pythonfmu script, one class FfrfBody_<body>_<hash>(Fmi2Slave)
    ffrf_rt_<body>_<hash>/          private package: runtime/ (copy of ffrf_fmu/runtime) and
                                    fmu/ (core.py, parameters.py, signals.py, state.py, derivatives.py,
                                    variables.py); imports numpy, scipy only
    body.npz                        BodyData.save: reduced matrices, node positions, ports
    ffrf_fmu.json                   parameter defaults, body origin, description, build info
    ffrf_python.json                the building Python: version, libpython, site-packages of numpy/scipy
    ffrf_libpython.txt              the building Python's libpython (read by the native loader)
    pythonfmu/                      embedded by pythonfmu

binaries/linux64/<id>.so is the native loader (native_loader.c, compiled here with the system C
compiler): it loads libpython when the host has none and forwards the fmi2 calls to pythonfmu's
binary, shipped next to it as <id>.pythonfmu.so. Without a C compiler the build is an error unless
native_loader=False asks for pythonfmu's binary alone (it then runs only in Python hosts). On backend
native (the default) the slave steps in the C runtime, compiled here and shipped in the private package
(runtime/native/prebuilt: runtime/native/build.py `ship`); where it does not load, the slave runs numpy
and logs why.

Over 400 lines: one module makes one kind of FMU from start to end (sources checked, loader, staging,
pythonfmu's build, the loader installed); its parts share the staging directory and the names.

<hash> is a digest of the reduced data, the configuration and the shipped sources, so two
different bodies (or two versions of the code) never share a module name in one process.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..runtime.data import BodyData
from .core import CONFIG_FILE, DATA_FILE
from .slave_template import TEMPLATE
from ..runtime.terms import FULL_TERMS, TERM_SETS
from .variables import (DERIVATIVE_CHANNEL, DESCRIPTION_BASE, DIRECTIONAL_DERIVATIVES, INPUTS_BETWEEN_COMMUNICATION_POINTS, INTERNAL_STEPS,
                        equations_text, identifier)

PACKAGE_ROOT = Path(__file__).resolve().parent.parent  # ffrf_fmu/
RUNTIME_DIR = PACKAGE_ROOT / "runtime"
SHIPPED_FMU_MODULES = ("core.py", "parameters.py", "signals.py", "state.py", "derivatives.py", "variables.py")
LOADER_SOURCE = Path(__file__).resolve().parent / "native_loader.c"
PYTHON_FILE = "ffrf_python.json"
LIBPYTHON_FILE = "ffrf_libpython.txt"
ALLOWED_IMPORTS = {"numpy", "scipy"}
OPTIONAL_IMPORTS = {"threadpoolctl", "ziglang"}  # allowed inside `try: ... except ImportError:` only

DESCRIPTION = DESCRIPTION_BASE + "."


class BuildError(RuntimeError):
    """The FMU cannot be built (the message says why)."""


class BuildWarning(UserWarning):
    """The FMU was built but lacks something (e.g. the native loader: no C compiler)."""


def python_facts() -> dict:
    """The building Python, as the FMU's native loader and slave script need it where no Python
    host is: its version, its shared libpython (None for a statically linked Python) and the
    site-packages directories that hold numpy and scipy."""
    import numpy
    import scipy

    libdir, soname = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME")
    libpython = os.path.join(libdir, soname) if libdir and soname and ".so" in soname else None
    if libpython and not os.path.exists(libpython):
        libpython = None
    import site

    dirs = [str(Path(m.__file__).resolve().parent.parent) for m in (numpy, scipy)]
    dirs += [d for d in site.getsitepackages() if d not in dirs]
    return {"version": list(sys.version_info[:2]), "executable": sys.executable, "libpython": libpython,
            "home": sys.base_prefix, "site_dirs": list(dict.fromkeys(dirs))}


def c_compiler() -> str | None:
    """The C compiler an FMU's native code is built with: $CC, else cc, gcc or clang on the PATH; None if none."""
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def compile_loader(out: Path) -> str:
    """Compile native_loader.c into `out`; '' on success, else why not (no compiler, error)."""
    cc = c_compiler()
    if not cc:
        return "no C compiler found (set CC or install gcc)"
    channel = [f"-DFFRF_DERIVATIVE_{key}={value}u" for key, value in DERIVATIVE_CHANNEL.items()]
    cmd = [cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wl,-z,nodelete", *channel,
           f"-I{LOADER_SOURCE.parent / 'native'}", "-o", str(out), str(LOADER_SOURCE), "-ldl", "-lpthread"]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"{cc} failed: {e}"
    return "" if done.returncode == 0 else f"{' '.join(cmd)} failed: {done.stderr.strip()[:2000]}"


def native_loader_problem(out: Path) -> str:
    """Compile the native loader into `out` for this platform; '' or why not."""
    if not sys.platform.startswith("linux"):
        return f"the native loader is built on Linux only (this is {sys.platform})"
    return compile_loader(out)


def install_loader(fmu: Path, model_identifier: str, loader: Path) -> str:
    """Put the compiled native loader in front of pythonfmu's linux64 binary inside `fmu`; '' or why not."""
    name = f"binaries/linux64/{model_identifier}.so"
    rewritten = fmu.with_suffix(".tmp")
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(rewritten, "w", zipfile.ZIP_DEFLATED) as dst:
        if name not in src.namelist():
            rewritten.unlink()
            return f"{name} is not in the FMU"
        for item in src.infolist():
            data = src.read(item)
            if item.filename == name:
                dst.writestr(f"binaries/linux64/{model_identifier}.pythonfmu.so", data)
                dst.write(loader, name)
            else:
                dst.writestr(item, data)
    os.replace(rewritten, fmu)
    return ""


@dataclasses.dataclass(frozen=True)
class SceneParameters:
    """The scene values an FMU takes as parameter defaults (all can be changed at instantiation)."""

    step: float
    rho_inf: float = 0.8
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    terms: str = "linear"
    max_newton_iterations: int = 0  # a step's Newton iterations at most (0: no cap; docs/fmu.md, real time)
    initial_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    initial_angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    port_displacements: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    duration: float | None = None  # DefaultExperiment stopTime when given
    probes: tuple[str, ...] = ()  # "<port>_from_<port>" outputs (eq. 92)
    full_terms: tuple[str, ...] = FULL_TERMS  # Witteveen's terms on in `full` (fixed at build)

    @classmethod
    def of_scene(cls, scene) -> "SceneParameters":
        return cls(
            step=scene.step,
            rho_inf=scene.rho_inf,
            gravity=tuple(scene.gravity),
            terms=scene.terms,
            max_newton_iterations=scene.max_newton_iterations,
            initial_velocity=tuple(scene.initial.velocity),
            initial_angular_velocity=tuple(scene.initial.angular_velocity),
            port_displacements=tuple(scene.initial.port_displacements),
            duration=scene.duration,
            probes=tuple(scene.outputs),
            full_terms=tuple(scene.full_terms),
        )

    def as_config(self) -> dict:
        if self.terms not in TERM_SETS:
            raise BuildError(f"terms must be one of {TERM_SETS}, got {self.terms!r}")
        if not set(self.full_terms) <= set(FULL_TERMS):
            raise BuildError(f"full_terms must be among {FULL_TERMS}, got {self.full_terms!r}")
        return {
            "step": float(self.step),
            "rho_inf": float(self.rho_inf),
            "gravity": [float(g) for g in self.gravity],
            "terms": self.terms,
            "max_newton_iterations": int(self.max_newton_iterations),
            "initial_velocity": [float(x) for x in self.initial_velocity],
            "initial_angular_velocity": [float(x) for x in self.initial_angular_velocity],
            "port_displacements": {k: [float(x) for x in v] for k, v in self.port_displacements},
            "probes": list(self.probes),
            "full_terms": list(self.full_terms),
        }


def start_states(data: BodyData, scene, origin=None) -> dict | None:
    """The scene's start state ([scenes.NAME.initial] state static or steady_spin: initial_state.settle) of
    `data` for each term set an FMU offers, made here at build time for the FMU to start from
    (runtime/start.py): {"state": name, "gravity": [3], "terms": {term set: {field: array}}}; None for "rest".
    The same state as the standalone run's (simulate.build_system)."""
    if scene.initial.state == "rest":
        return None
    from ..runtime.start import capture
    from ..simulate.loop import InitializationFailure, build_system

    out = {}
    for terms in TERM_SETS:
        if terms == "full" and any(se.W2 is None for se in data.superelements):
            continue
        try:
            system, _ = build_system(data, dataclasses.replace(scene, terms=terms),
                                     origin if origin is not None else data.node_positions[0], backend="numpy")
        except InitializationFailure as e:
            raise BuildError(str(e)) from None
        out[terms] = capture(system)
    return {"state": scene.initial.state, "gravity": [float(g) for g in scene.gravity], "terms": out}


def _sources(directory: Path, names=None) -> dict[str, str]:
    files = sorted(directory.glob("*.py")) if names is None else [directory / n for n in names]
    return {f.name: f.read_text(encoding="utf-8") for f in files}


_STDLIB = set(getattr(sys, "stdlib_module_names", ())) | {"__future__"}


def check_shipped_imports(sources: dict[str, str]) -> None:
    """The shipped modules may import only the standard library, numpy, scipy and each other
    (relative imports): anything else would be missing where the FMU runs."""
    import ast

    for name, text in sources.items():
        tree = ast.parse(text, filename=name)
        guarded = set()  # imports inside a try whose handlers catch ImportError
        for node in ast.walk(tree):
            if isinstance(node, ast.Try) and any(
                isinstance(h.type, ast.Name) and h.type.id in ("ImportError", "ModuleNotFoundError") for h in node.handlers
            ):
                guarded.update(id(n) for stmt in node.body for n in ast.walk(stmt))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                mods = [] if node.level else [node.module or ""]
            elif isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            else:
                continue
            for mod in mods:
                top = mod.split(".")[0]
                if top in ALLOWED_IMPORTS or top in _STDLIB or (top in OPTIONAL_IMPORTS and id(node) in guarded):
                    continue
                raise BuildError(
                    f"{name} imports {mod!r}: modules shipped in an FMU may import only numpy, scipy, the "
                    "standard library and each other (relative imports)"
                )


def body_digest(data: BodyData, config: dict, sources: dict[str, str]) -> str:
    h = hashlib.sha256()
    for se in data.superelements:
        for key in ("J0", "x_cm", "X_B", "nodes", "K", "M", "G", "frequencies_hz"):
            a = np.ascontiguousarray(getattr(se, key))
            h.update(key.encode() + str(a.dtype).encode() + str(a.shape).encode() + a.tobytes())
        h.update(repr(float(se.mass)).encode())
    h.update(np.ascontiguousarray(data.node_positions, dtype=float).tobytes())
    h.update(json.dumps([dataclasses.astuple(p) for p in data.ports]).encode())
    h.update(json.dumps(config, sort_keys=True).encode())
    for name in sorted(sources):
        h.update(name.encode() + sources[name].encode())
    return h.hexdigest()[:10]


def build_python_fmu(
    data: BodyData,
    dest,
    params: SceneParameters,
    *,
    origin=None,
    build_info: dict | None = None,
    native_loader: bool = True,
    backend: str = "native",
    start: dict | None = None,
) -> Path:
    """Write the FMU of `data` to `dest` (a .fmu file name, or a directory) and return its path.

    origin: body origin for the initial rigid velocity field (default: node 0 position).
    build_info: free JSON-able facts stored in the resources (model file, scene, overrides).
    native_loader: put the native loader in front of pythonfmu's binary (Linux, needs a C
    compiler at build time; without one a BuildError says so); False makes an FMU that only Python
    hosts can load (no directional derivatives).
    backend: "native" (the slave steps in the C runtime, compiled here and shipped) or "numpy" (the
    reference implementation, shipped as Python modules).
    start: the start state of `start_states` (the FMU initializes there), None: from rest.
    """
    if backend not in ("native", "numpy"):
        raise BuildError(f"the pythonfmu FMU's slave steps on backend native or numpy, got {backend!r}")
    from pythonfmu import FmuBuilder  # build-time only

    runtime_src = _sources(RUNTIME_DIR)
    if "body.py" not in runtime_src:
        raise BuildError(f"{RUNTIME_DIR}/body.py is missing: the body dynamics are not there")
    if backend == "native":  # the binding's modules ship too (runtime/native/build.py `ship`), checked here
        runtime_src.update({f"native/{k}": v for k, v in _sources(RUNTIME_DIR / "native").items()})
    fmu_src = _sources(Path(__file__).resolve().parent, SHIPPED_FMU_MODULES)
    check_shipped_imports({**{f"runtime/{k}": v for k, v in runtime_src.items()},
                           **{f"fmu/{k}": v for k, v in fmu_src.items()}})
    config = {
        "parameters": params.as_config(),
        "origin": [float(x) for x in (origin if origin is not None else data.node_positions[0])],
        "body": data.name,
        "ffrf_fmu_version": __version__,
        "build": build_info or {},
        "backend": backend,
    }
    if start is not None:  # floats as JSON numbers (repr: exact), read by core.BodyCoSim._start
        config["start"] = {"state": start["state"], "gravity": start["gravity"],
                           "terms": {t: {k: np.asarray(a).tolist() for k, a in arrays.items()}
                                     for t, arrays in start["terms"].items()}}
    stage_dir = tempfile.TemporaryDirectory(prefix="ffrf_fmu_build_")
    stage = Path(stage_dir.name)
    # the loader first: it is what provides fmi2GetDirectionalDerivative, which the modelDescription
    # then declares (the slave reads config["directional_derivatives"])
    loader_why = native_loader_problem(stage / "loader.so") if native_loader else "not asked for"
    if native_loader and loader_why:  # an FMU only Python hosts can load is made when asked for, never silently
        stage_dir.cleanup()
        raise BuildError(f"the pythonfmu FMU's native loader cannot be built ({loader_why}): without it only Python "
                         "hosts load the FMU; native_loader=False accepts that, or build the native FMU")
    config["directional_derivatives"] = not loader_why
    ports_text = ", ".join(f"{p.name} (translation {p.translation}, rotation {p.rotation})" for p in data.ports)
    stiff = all(se.stiffening for se in data.superelements)
    config["description"] = (DESCRIPTION.format(body=data.name, n_se=len(data.superelements), ports=ports_text) + " "
                             + equations_text(params.terms, params.full_terms, stiff)
                             + (" " + DIRECTIONAL_DERIVATIVES if config["directional_derivatives"] else ""))
    config["stiffening"] = stiff
    if params.duration is not None:
        config["experiment"] = {"stop_time": float(params.duration), "step_size": float(params.step)}
    digest = body_digest(data, {k: v for k, v in config.items() if k != "build"}, {**runtime_src, **fmu_src})
    name = identifier(data.name)
    package = f"ffrf_rt_{name}_{digest}"
    module = f"ffrf_slave_{name}_{digest}"
    cls = f"FfrfBody_{name}_{digest}"
    config["names"] = {"package": package, "module": module, "class": cls, "digest": digest}

    dest = Path(dest)
    if dest.suffix != ".fmu":
        if dest.suffix and not dest.is_dir():
            raise BuildError(f"{dest}: an FMU file name must end in .fmu (or name a directory)")
        dest = dest / f"{data.name}.fmu"
    dest.parent.mkdir(parents=True, exist_ok=True)
    with stage_dir:
        pkg = stage / package
        (pkg / "runtime").mkdir(parents=True)
        (pkg / "fmu").mkdir()
        (pkg / "__init__.py").write_text(f'"""Private runtime of FMU {cls} (ffrf-fmu {__version__})."""\n')
        for fname, text in runtime_src.items():
            if "/" not in fname:  # runtime/native/ comes with its library below
                (pkg / "runtime" / fname).write_text(text, encoding="utf-8")
        if backend == "native":  # the C runtime compiled for this platform, beside its binding
            from ..runtime.native import build as runtime_build

            try:
                runtime_build.ship(pkg / "runtime" / "native")
            except runtime_build.BuildError as e:
                raise BuildError(f"the C runtime cannot be compiled for the FMU ({e}); backend numpy needs none") from None
        (pkg / "fmu" / "__init__.py").write_text("")
        for fname, text in fmu_src.items():
            (pkg / "fmu" / fname).write_text(text, encoding="utf-8")
        data.save(stage / DATA_FILE)
        (stage / CONFIG_FILE).write_text(json.dumps(config, indent=1), encoding="utf-8")
        py = python_facts()
        (stage / PYTHON_FILE).write_text(json.dumps(py, indent=1), encoding="utf-8")
        # line 1: the libpython the loader loads; line 2: that Python's home, the loader's PYTHONHOME
        (stage / LIBPYTHON_FILE).write_text((py["libpython"] or "") + "\n" + py["home"] + "\n", encoding="utf-8")
        script = stage / f"{module}.py"
        script.write_text(TEMPLATE.format(body=data.name, version=__version__, package=package, cls=cls),
                          encoding="utf-8")
        saved_path = list(sys.path)
        try:
            out = FmuBuilder.build_FMU(
                script,
                dest=dest,
                project_files=[pkg, stage / DATA_FILE, stage / CONFIG_FILE, stage / PYTHON_FILE,
                               stage / LIBPYTHON_FILE],
                canHandleVariableCommunicationStepSize=True,
                canGetAndSetFMUstate=True,
                canSerializeFMUstate=True,
                canBeInstantiatedOnlyOncePerProcess=False,
            )
        finally:
            # the build imported the script and the package from the staging directory: forget
            # them, so that loading the FMU later in this process imports its own resources
            sys.path[:] = saved_path
            for key in [k for k in sys.modules if k == module or k == package or k.startswith(package + ".")]:
                del sys.modules[key]
        out = Path(out)
        if native_loader:
            why = install_loader(out, cls, stage / "loader.so")
            if why:
                warnings.warn(f"{out.name}: no native loader ({why}); the FMU runs only in a host that has "
                              "Python loaded (fmpy), or with libpython in LD_PRELOAD", BuildWarning, stacklevel=2)
            elif py["libpython"] is None:
                warnings.warn(f"{out.name}: this Python has no shared libpython; a host without Python needs "
                              "FFRF_FMU_LIBPYTHON set to one", BuildWarning, stacklevel=2)
    return out


# ---------------------------------------------------------------------------------------------
# from a model file

RUNTIMES = ("native", "python")


def build_fmu(model_path, dest, *, scene: str | None = None, overrides=(), backend: str = "native",
              runtime: str = "native", platforms=("linux64",), compiler: str = "zig",
              log=None, native_loader: bool = True, fmi: int = 2) -> Path:
    """Model file -> reduced body with the scene's causality -> FMU with the scene's parameters; returns the
    FMU's path (the public ffrf_fmu.build_fmu). runtime: "native" (fmu/native: binaries for `platforms` by
    `compiler`, zig or system; FMI version `fmi`, 2 or 3) or "python" (`build_python_fmu` of the BodyData,
    with `backend`; FMI 2.0 only)."""
    if isinstance(model_path, BodyData):
        raise TypeError("build_fmu(model_path, dest, scene=...) builds from a model file; the FMU of a BodyData is "
                        "ffrf_fmu.fmu.build_python_fmu(data, dest, SceneParameters(...))")
    if runtime not in RUNTIMES:
        raise BuildError(f"runtime must be one of {RUNTIMES}, got {runtime!r}")
    if fmi != 2 and (fmi != 3 or runtime != "native"):
        raise BuildError(f"FMI version {fmi!r}: 2, or 3 with the native runtime only (pythonfmu makes FMI 2.0 FMUs)")
    from ..model import load_model
    from ..reduction import reduce_scene_body

    model = load_model(model_path, overrides)
    sc = model.scene(scene)
    data = reduce_scene_body(model.body, sc).data
    start = start_states(data, sc, model.body.origin)
    info = {"model_file": str(Path(model_path).name), "model_sha256": hashlib.sha256(Path(model_path).read_bytes()).hexdigest(),
            "scene": sc.name, "overrides": list(overrides), "scenes": [s.name for s in model.scenes]}
    if runtime == "native":
        from .native import build_native_fmu
        from .native.build import NativeBuildError

        try:
            path = build_native_fmu(data, dest, SceneParameters.of_scene(sc), origin=model.body.origin,
                                    build_info=info, platforms=platforms, compiler=compiler, log=log, fmi=fmi,
                                    start=start)
        except NativeBuildError as e:
            raise BuildError(str(e)) from None
    else:
        path = build_python_fmu(data, dest, SceneParameters.of_scene(sc), origin=model.body.origin, build_info=info,
                                backend=backend, native_loader=native_loader, start=start)
    if sc.max_newton_iterations:  # the real-time cap, checked on the scene (fmu/realtime.py)
        from .realtime import IterationCapRefused, check_iteration_cap

        try:
            check = check_iteration_cap(path, sc)
        except IterationCapRefused as e:
            Path(path).unlink()
            raise BuildError(f"{Path(model_path).name}: {e}") from None
        if log:
            log(f"max_newton_iterations = {check['cap']} holds on scene {sc.name!r}: at most {check['max_iterations']} "
                f"Newton iterations per step, port outputs within {check['deviation']:.3g} of their peaks")
    return path


def read_fmu_config(fmu_path) -> dict:
    """The ffrf_fmu.json of a built FMU (names, parameters, build info)."""
    import zipfile

    with zipfile.ZipFile(fmu_path) as z:
        return json.loads(z.read(f"resources/{CONFIG_FILE}").decode("utf-8"))


def __getattr__(name: str):
    """`build_from_model` was the name of `build_fmu` (which then named the BodyData build, now
    `build_python_fmu`): refused, naming the new one; an ImportError, so that `from ... import` shows it."""
    if name == "build_from_model":
        raise ImportError("ffrf_fmu.fmu.build_from_model is now ffrf_fmu.fmu.build_fmu (model file -> FMU, as "
                          "ffrf_fmu.build_fmu); the FMU of a BodyData is ffrf_fmu.fmu.build_python_fmu")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
