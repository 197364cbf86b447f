"""A run of a sweep as data: what defines it, the key that names it, and the one function a worker
executes on it.

A task is (model file bytes, overrides, scene, runner, backend, options): plain bytes, texts and
numbers, never pickled code. A worker (a local process, or a dask.distributed worker on another
machine) imports this module by name and calls `execute(task)`; it writes the model bytes into a
private temporary directory under the model's own file name (the body's default name is the file
stem) and runs the named runner of the installed ffrf_fmu. So the worker runs *its* code: every
result carries that code's version (`code_version`) and the sweep refuses results of another
version than its own (sweep.py).

Runners (RUNNERS): `standalone` (simulate.run) and `fmu` (the body's FMU under fmpy) through
runners.run_configuration; `reference` (the full-order beam, runners.run_reference; options
elements, step); `beam` (runners.run_beam, the stability maps' standalone run; option
record_every); `cosim` (a coupled run of the co-simulation map, stability/tasks.py; options case,
H, scheme, settings); `peer:NAME` (ffrf_fmu.peers; options elements, step).

The one import that runs up within studies/: `_run` imports the `cosim` runner from
stability/tasks.py, on first use. A worker resolves a task's runner by its name here, the one place
that knows them all, while the coupled runs live beside the stability map that defines their
options (stability/ builds its tasks with this module's make_task).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import multiprocessing
import os
import sys
import tempfile
import traceback
from functools import lru_cache
from pathlib import Path
from typing import Any

PACKAGE = Path(__file__).resolve().parent.parent  # ffrf_fmu/
RUNNERS = ("standalone", "fmu", "reference", "beam", "cosim")  # and "peer:<name>"


@dataclasses.dataclass(frozen=True)
class Task:
    """One run. `model_name` is the model file's name (its stem is the body's default name);
    `options` holds runner options as sorted (key, value) pairs of texts and numbers."""

    model_name: str
    model_bytes: bytes
    overrides: tuple[str, ...] = ()
    scene: str | None = None
    runner: str = "standalone"
    backend: str = "numpy"  # the runtime's (runtime/body.py BACKENDS); the standalone and FMU runners use it
    options: tuple[tuple[str, Any], ...] = ()

    @property
    def key(self) -> str:
        """The content that defines the run, hashed: model bytes, overrides (in order: a later one
        wins), scene, runner, backend, options. The model file's name is part of it (the body's
        default name comes from it); where the file lies is not."""
        h = hashlib.sha256(self.model_bytes)
        h.update(json.dumps([self.model_name, list(self.overrides), self.scene, self.runner, self.backend,
                             [list(o) for o in self.options]]).encode())
        return h.hexdigest()[:20]

    def describe(self) -> dict:
        """The task without its bytes (for the store's JSON lines)."""
        return {"model": self.model_name, "model_sha256": hashlib.sha256(self.model_bytes).hexdigest()[:16],
                "overrides": list(self.overrides), "scene": self.scene, "runner": self.runner,
                "backend": self.backend, "options": dict(self.options)}


def make_task(model_path, overrides=(), scene: str | None = None, runner: str = "standalone",
              backend: str = "numpy", **options) -> Task:
    """A Task from a model file on this machine (its bytes are read now)."""
    p = Path(model_path)
    return Task(p.name, p.read_bytes(), tuple(str(o) for o in overrides), scene, runner, backend,
                tuple(sorted((k, v) for k, v in options.items() if v is not None)))


@lru_cache(maxsize=1)
def code_version() -> str:
    """`<package version>+<sha256 of every .py file of the installed ffrf_fmu, by relative path>`,
    12 hex digits. Independent of git (a cluster's workers have installs, not checkouts); any edit
    of the package, a comment included, is another version. Cached per process: a worker process
    reports the code it imported."""
    from .. import __version__

    h = hashlib.sha256()
    for f in sorted(PACKAGE.rglob("*.py")):
        h.update(str(f.relative_to(PACKAGE)).encode() + b"\0" + f.read_bytes() + b"\0")
    return f"{__version__}+{h.hexdigest()[:12]}"


def execute(task: Task) -> dict:
    """Run one task in this process. Never raises for a run that fails: the result says why
    (`completed` False, `failure`, `traceback`). Always carries `key` and `code_version`."""
    if multiprocessing.parent_process() is not None:  # a worker process (pool or dask)
        forget_fmu_resources()
    out: dict[str, Any] = {"completed": False, "failure": None}
    try:
        with tempfile.TemporaryDirectory(prefix="ffrf_task_") as tmp:
            path = Path(tmp) / task.model_name
            path.write_bytes(task.model_bytes)
            out = _run(task, str(path))
    except Exception as e:  # noqa: BLE001 - a run that cannot start is a row with its cause
        out = {"completed": False, "failure": f"{type(e).__name__}: {e}", "error_type": type(e).__name__,
               "traceback": traceback.format_exc(limit=4)}
    out["key"] = task.key
    out["code_version"] = code_version()
    out["pid"] = os.getpid()
    return out


def forget_fmu_resources() -> None:
    """Drop from sys.path the resources directories of FMUs (they hold pythonfmu's slavemodule.txt).

    A worker started by multiprocessing inherits its parent's sys.path, and pythonfmu's loader puts
    the resources directory of every FMU the parent ran in-process there. Such a directory carries
    its own copy of pythonfmu, without the FMU binaries: imported first, it builds FMUs without
    them (fmpy then fails: "Cannot find shared library"). A worker runs no FMU of its parent's."""
    sys.path[:] = [p for p in sys.path if not os.path.isfile(os.path.join(p or ".", "slavemodule.txt"))]


def _run(task: Task, model_path: str) -> dict:
    opts = dict(task.options)
    if task.runner in ("standalone", "fmu"):
        from .runners import run_configuration

        return run_configuration(model_path, task.scene, list(task.overrides), {}, task.runner, task.backend)
    if task.runner == "reference":
        from .runners import run_reference

        ref = run_reference(model_path, task.scene, list(task.overrides), opts.get("elements"), opts.get("step"))
        return {**ref, "completed": True, "failure": None}
    if task.runner == "beam":
        from ..model import load_model
        from .runners import run_beam

        model = load_model(model_path, list(task.overrides))
        return run_beam(model, model.scene(task.scene), **opts).as_result()
    if task.runner == "cosim":
        from .stability.tasks import run_task

        return run_task(model_path, list(task.overrides), opts)
    if task.runner.startswith("peer:"):
        from ..peers import runner

        return runner(task.runner[5:])(model_path, task.scene, list(task.overrides),
                                       {k: opts[k] for k in ("elements", "step") if k in opts})
    raise ValueError(f"unknown runner {task.runner!r} (known: {', '.join(RUNNERS)}, peer:NAME)")
