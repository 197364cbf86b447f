"""What the `ffrf-fmu` subcommands share: the @command registry, the argument tables several of them
take (model, backend, sweep), and the small helpers they call (load a model, reduce its body).

Start-up: a command imports what it uses, inside its function (`ffrf-fmu --help` imports no numpy;
benchmarks/cli_startup.py). Only the error type every command catches is imported at the top.
"""
from __future__ import annotations

import argparse

# BLAS threads: pinned to one when the package is imported (ffrf_fmu/__init__.py)
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from ..model import Model, Scene

PROG = "ffrf-fmu"
_COMMANDS: list[tuple[Callable, tuple]] = []


def arg(*names, **kwargs):
    """One argparse argument, as given to `command`."""
    return names, kwargs


# The model arguments most subcommands share.
MODEL_ARGS = (
    arg("model", help="model file (TOML, see docs/model-format.md)"),
    arg("--scene", help="scene name (default: the first scene in the file)"),
    arg("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a model value, e.g. --set superelements=2 --set step=1e-3 (repeatable)"),
)


def _backend(value: str) -> str:
    """--backend: a backend of runtime/body.py BACKENDS; a retired one is refused naming its replacement."""
    from ..runtime.body import check_backend

    try:
        check_backend(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return value


BACKEND_ARG = arg(
    "--backend", type=_backend, default="native", metavar="{native,numpy}",
    help="native: the C runtime (default; compiled on first use in seconds, then cached in ~/.cache/ffrf-fmu), "
         "numpy: the plain reference implementation")


# Where a sweep's runs go (ffrf_fmu/studies/sweep.py, docs/scale.md); chart and study share them.
SWEEP_ARGS = (
    arg("--workers", type=int, metavar="K", help="local worker processes (default: cpu count; 1 runs in this "
        "process; wall times of concurrent runs are measured per process and grow when K exceeds the free cores)"),
    arg("--scheduler", metavar="ADDRESS", help="run on dask.distributed instead of the local pool: local:N starts a "
        "LocalCluster of N workers, anything else is the address of a running scheduler, e.g. tcp://host:8786 "
        "(optional extra `cluster`; docs/scale.md)"),
    arg("--start-method", choices=("spawn", "forkserver"), default="spawn", help="how the local pool starts its "
        "workers (default spawn; both import ffrf_fmu afresh)"),
    arg("--fresh", action="store_true", help="discard the results stored in the output directory and run every "
        "run again (needed after the code changed: a sweep does not mix code versions)"),
)


def _scheduler(args):
    from ..studies.sweep import parse_scheduler

    return parse_scheduler(args.scheduler, args.workers, args.start_method)


def command(*arguments):
    """Register the decorated function as a subcommand named after it."""

    def register(fn):
        _COMMANDS.append((fn, arguments))
        return fn

    return register


def _load(args) -> tuple[Model, Scene]:
    from ..model import load_model

    model = load_model(args.model, args.overrides)
    return model, model.scene(args.scene)


def _body_for_scene(model: Model, scene: Scene):
    """The body with the scene's causality, built and reduced: a reduction.ReducedBody."""
    from ..reduction import reduce_scene_body  # heavy (scipy); only the commands that need it pay

    return reduce_scene_body(model.body, scene)


def _hz(values, n: int = 6) -> str:
    shown = ", ".join(f"{f:.4f}" for f in values[:n])
    return shown + (f", ... ({len(values)} in all)" if len(values) > n else "")


def _damping_report(data):
    """The body's structural damping as each mode of superelement 0's reduced model feels it (its ratio
    c_i / (2 omega_i), runtime/damping.py), or None when undamped."""
    if data.damping is None or data.damping.kind == "none":
        return None
    import numpy as np

    from ..runtime.damping import modal_basis, modal_coefficients

    se = data.superelements[0]
    basis = modal_basis(se.K[None], se.M[None])
    w = basis.omega[0]
    return {"kind": data.damping.kind, **data.damping.as_meta(), "mode_frequencies_hz": (w / (2 * np.pi)).tolist(),
            "mode_ratios": (modal_coefficients(data.damping, basis)[0] / (2 * w)).tolist()}
