"""The package as a newcomer meets it: its public API (the docstring example runs) and its import
graph (no module imports another that imports it back)."""
from __future__ import annotations

import ast
import doctest
import os
import subprocess
import sys
from pathlib import Path

import pytest

import ffrf_fmu

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "ffrf_fmu"


def _modules() -> dict[str, tuple[Path, bool]]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        out[".".join(parts[:-1] if is_package else parts)] = (path, is_package)
    return out


def _imports(name: str, path: Path, is_package: bool, modules, top_level_only: bool) -> set[str]:
    """The package modules `name` imports (statically; `from . import x` counts x when x is a module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    nodes = tree.body if top_level_only else ast.walk(tree)
    found = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for a in node.names:
                found.add(f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target)
    return {m for m in found if m in modules and m != name}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


# Circles through imports inside functions (deferred, so Python tolerates them): none left; a new one
# is a seam to cut, not an entry to add here.
KNOWN_DEFERRED_CIRCLES: list[list[str]] = []


def test_no_import_circle():
    """No circle among module-level imports (the kind that fails at import time, depending on which
    module is imported first), and none through deferred imports beyond the known ones."""
    modules = _modules()
    top = {m: _imports(m, p, pkg, modules, True) for m, (p, pkg) in modules.items()}
    assert _cycles(top) == []
    every = {m: _imports(m, p, pkg, modules, False) for m, (p, pkg) in modules.items()}
    new = [c for c in _cycles(every) if not any(set(c) <= set(k) for k in KNOWN_DEFERRED_CIRCLES)]
    assert new == [], f"new import circle(s) through deferred imports: {new}"


# README's layout: the stages, each importing only its own and lower ones (runtime/ at the bottom: its data,
# equations and step import nothing else of the package). The most specific prefix decides a module's stage.
STAGES = {
    "ffrf_fmu": 0,  # the package's __init__: the version, and the public API imported on first use
    "ffrf_fmu.runtime": 0,
    "ffrf_fmu.checked_toml": 1, "ffrf_fmu.model": 1, "ffrf_fmu.section": 1, "ffrf_fmu.directions": 1, "ffrf_fmu.spin": 1,
    "ffrf_fmu.solid": 1,  # the solid's FE data (SolidFE) and its sources (mesh, exports), read with the model file
    "ffrf_fmu.fe": 1, "ffrf_fmu.solid.frames": 2, "ffrf_fmu.solid.ordering": 2, "ffrf_fmu.solid.stiffening": 2,
    "ffrf_fmu.solid.constraints": 2,  # frames as constraints of the FE model (uses frames)
    # the FE elements (fe/, the beam) and the Nastran reader that uses them are sources a model file names
    "ffrf_fmu.solid.nastran": 1,  # Nastran decks to K and M with the beam element of fe/beam.py
    "ffrf_fmu.solid.nastran_mass": 1, "ffrf_fmu.solid.nastran_body": 1,  # the deck's mass split, its body
    "ffrf_fmu.solid.nastran_rigid": 1,  # RBE2/RBE3 eliminated
    "ffrf_fmu.port_data": 3, "ffrf_fmu.reduction": 3, "ffrf_fmu.reduction_sparse": 3,
    "ffrf_fmu.reduction_quality": 3, "ffrf_fmu.linear": 3, "ffrf_fmu.invariants": 3, "ffrf_fmu.initial_state": 3,
    "ffrf_fmu.term_rule": 3, "ffrf_fmu.spin_supports": 3, "ffrf_fmu.body_cache": 3,
    "ffrf_fmu.reference": 4,
    "ffrf_fmu.simulate": 5,
    "ffrf_fmu.fmu": 6, "ffrf_fmu.peers": 6,
    "ffrf_fmu.validate": 7, "ffrf_fmu.master": 7, "ffrf_fmu.engines": 7, "ffrf_fmu.examples": 7,
    "ffrf_fmu.studies": 8, "ffrf_fmu.cli": 8, "ffrf_fmu.__main__": 8,
}


def _stage(module: str) -> int:
    prefix = max((p for p in STAGES if module == p or module.startswith(p + ".")), key=len)
    return STAGES[prefix]


def test_imports_go_one_way():
    """No module imports one of a later stage (README, Layout), at the top or inside a function: a new
    import upwards fails here (move the code down, or the fact into a lower module)."""
    modules = _modules()
    up = sorted(f"{m} -> {t}" for m, (p, pkg) in modules.items() for t in _imports(m, p, pkg, modules, False)
                if _stage(t) > _stage(m))
    assert up == [], up


def test_every_module_imports_first():
    """Each module imported first in a fresh interpreter: an import-order dependence (a circle the
    static check cannot see, e.g. through `importlib`) fails here. Optional extras (exudyn, dask) are
    imported inside functions, so every module imports with the core dependencies."""
    names = [m for m in _modules() if not m.endswith("__main__")]
    script = ("import importlib, sys\nbad = []\nfor n in sys.argv[1:]:\n"
              "    for k in [k for k in sys.modules if k.startswith('ffrf_fmu')]:\n        del sys.modules[k]\n"
              "    try:\n        importlib.import_module(n)\n"
              "    except Exception as e:\n        bad.append(f'{n}: {type(e).__name__}: {e}')\n"
              "print('\\n'.join(bad))\nsys.exit(1 if bad else 0)\n")
    out = subprocess.run([sys.executable, "-c", script, *names], capture_output=True, text=True, timeout=600,
                         cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr


def test_public_api_docstring_example(monkeypatch):
    """The example in ffrf_fmu's docstring runs (from the repository root) and gives what it shows."""
    monkeypatch.chdir(ROOT)
    result = doctest.testmod(ffrf_fmu, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 4 and result.failed == 0


def test_public_api_names():
    assert set(ffrf_fmu.__all__) >= {"load_model", "build_body", "run_scene", "build_fmu", "validate_fmu"}
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.validate import validate

    assert ffrf_fmu.build_fmu is build_fmu and ffrf_fmu.validate_fmu is validate


def test_public_names_mean_one_thing_and_old_spellings_are_refused():
    """build_body takes a model and returns a BodyData (reduce_body a Body, returning a ReducedBody);
    build_fmu takes a model file (build_python_fmu a BodyData); the old names are refused naming the new."""
    import dataclasses

    import ffrf_fmu.fmu
    import ffrf_fmu.master
    from ffrf_fmu.reduction import ReducedBody, build_body, reduce_body
    from ffrf_fmu.runtime.data import BodyData

    model = ffrf_fmu.load_model(ROOT / "models" / "haug_beam.toml", ["superelements=1", "modes=2"])
    assert ffrf_fmu.build_body is build_body and isinstance(build_body(model), BodyData)
    reduced = reduce_body(model.body)
    assert isinstance(reduced, ReducedBody) and dataclasses.is_dataclass(reduced)
    assert isinstance(reduced.data, BodyData) and len(reduced.reductions) == 1
    with pytest.raises(TypeError, match="reduce_body"):
        build_body(model.body)
    with pytest.raises(TypeError, match="build_python_fmu"):
        ffrf_fmu.build_fmu(reduced.data, ROOT / "never_written.fmu")
    with pytest.raises(ImportError, match="build_from_model is now ffrf_fmu.fmu.build_fmu"):
        from ffrf_fmu.fmu import build_from_model  # noqa: F401
    with pytest.raises(ImportError, match="Held is now ffrf_fmu.master.Signal"):
        from ffrf_fmu.master import Held  # noqa: F401
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        ffrf_fmu.nope  # noqa: B018


def test_readme_from_python_matches_the_api():
    """Each call of the README's "From Python" table names the function's own parameters after the first
    (which the table may name for what it takes, e.g. fmu_or_model), in the function's order: a keyword
    the README shows is one the function takes."""
    import inspect
    import re

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("### From Python", 1)[1].split("\n#", 1)[0]
    calls = dict(re.findall(r"^\| `(\w+)\((.*?)\)` \|", section, flags=re.M))
    assert set(calls) == set(ffrf_fmu.__all__) - {"__version__"}, calls
    for name, args in calls.items():
        shown = [a.split("=")[0].strip() for a in args.split(",")][1:]
        params = list(inspect.signature(getattr(ffrf_fmu, name)).parameters)[1:]
        assert shown == [p for p in params if p in shown], (name, shown, params)


def test_run_scene_refuses_overrides_it_would_ignore():
    model = ffrf_fmu.load_model(ROOT / "models" / "haug_beam.toml", ["superelements=1", "modes=2"])
    with pytest.raises(ValueError, match="load_model"):
        ffrf_fmu.run_scene(model, scene="spinup", overrides=["duration=0.1"])


def test_long_modules_say_why():
    """Every module over 400 lines says in its docstring why it is not split: a paragraph "Over 400
    lines: <reason>" of at least a sentence (60 characters), not the phrase alone."""
    long = []
    for name, (path, _) in _modules().items():
        text = path.read_text(encoding="utf-8")
        doc = ast.get_docstring(ast.parse(text)) or ""
        reason = doc.partition("Over 400 lines:")[2].split("\n\n")[0].strip()
        if len(text.splitlines()) > 400 and len(reason) < 60:
            long.append(f"{name} ({len(text.splitlines())} lines)")
    assert long == [], f"split by idea or give the reason in the module docstring: {long}"


def test_one_blas_thread_for_blas_loaded_after_import():
    """`import ffrf_fmu` after numpy, then scipy.linalg (which loads scipy's own OpenBLAS): every BLAS
    runs one thread. With threadpoolctl's limit alone, scipy's OpenBLAS started one thread per core
    and a spinning worker doubled a short run's CPU time (ffrf_fmu/__init__.py)."""
    code = ("import numpy, ffrf_fmu, scipy.linalg\n"
            "from threadpoolctl import threadpool_info\n"
            "print(sorted({i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'}))")
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                         cwd=ROOT)
    assert out.stdout.strip() == "[1]", out.stdout


def test_readme_layout_names_every_module():
    """README's layout names every module there is, by its file name in backquotes in the entry of its
    package (`ffrf_fmu/<package>/`; a top-level module anywhere in the layout): a module added without a
    line there fails here."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    layout = readme[readme.index("## Layout"):]
    entries = layout.split("\n- ")
    missing = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        rel = path.relative_to(PACKAGE)
        if not rel.parent.parts:  # ffrf_fmu/x.py
            named = path.name == "__init__.py" or f"`{path.name}`" in layout or f"/{path.name}`" in layout
        else:
            mine = [e for e in entries if f"ffrf_fmu/{rel.parts[0]}/" in e]
            named = path.name == "__init__.py" and bool(mine) or any(f"`{path.name}`" in e for e in mine)
        if not named:
            missing.append(str(rel))
    assert missing == [], f"README's layout does not name: {missing}"


def test_help_imports_no_numpy():
    """`ffrf-fmu --help` builds every subcommand's parser and imports nothing a command does not use
    (no numpy, scipy, matplotlib, dask, fmpy): its start-up is the interpreter's plus the argument
    tables (benchmarks/cli_startup.py)."""
    code = ("import sys, runpy\nsys.argv = ['ffrf-fmu', '--help']\n"
            "try:\n    runpy.run_module('ffrf_fmu', run_name='__main__')\nexcept SystemExit:\n    pass\n"
            "heavy = ('numpy', 'scipy', 'matplotlib', 'dask', 'fmpy', 'pythonfmu', 'numba')\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy), file=sys.stderr)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert "usage: ffrf-fmu" in out.stdout
    assert out.stderr.strip() == "[]", out.stderr


def test_only_the_optional_peer_is_skipped_when_missing():
    """README: no test skips for a missing declared dependency; the optional extra `peers` (exudyn) is
    the one package a test may skip without, and the only other skips are for the system tools README
    names (a C compiler on Linux for the C host, libasan for the sanitizer run)."""
    import re

    skipped, sites = set(), {}
    for path in (ROOT / "tests").glob("*.py"):
        text = path.read_text(encoding="utf-8")
        skipped |= set(re.findall(r"importorskip\(\s*[\"']([\w.]+)[\"']", text))
        n = len(re.findall(r"\bskipif\(|pytest\.skip\(", text))
        if n and path.name != "test_package.py":
            sites[path.name] = n
    assert skipped <= {"exudyn"}, skipped
    assert sites == {"test_native_host.py": 2, "test_native_runs.py": 2}, sites


def test_no_file_outside_the_repository_is_cited():
    """Code, tests, models and docs cite docs/ (docs/background.md carries what they need from the
    reference material outside the repository), never a file there (ports.md, formulation.md,
    stiffening.md, architecture.md, the reference benchmarks.md, ../shared)."""
    import re

    outside = re.compile(r"(?<![\w/])(ports|formulation|stiffening|architecture)\.md|shared/(spec|seeds)|\.\./shared"
                         r"|(?<![\w/])benchmarks\.md (B\d|note)")
    hits = []
    for path in [*PACKAGE.rglob("*.py"), *PACKAGE.rglob("*.c"), *PACKAGE.rglob("*.h"), *(ROOT / "tests").glob("*.py"),
                 *(ROOT / "models").glob("*.toml"), *(ROOT / "docs").glob("*.md"), ROOT / "README.md"]:
        if path.name == "test_package.py":
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if outside.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{n}")
    assert hits == [], hits
