"""`ffrf-fmu` command line: one function per subcommand, registered with @command (cli/common.py); all of
the package's argparse code is in this package (build_fmu.py uses `build` through `command_parser`).

A subcommand is `def name(args) -> int` whose docstring is its help; its arguments come from the
decorator. The subcommands live by family: run.py (info, simulate, build, validate), studies.py
(campbell, stability, chart, study, advise, convergence), system.py, recover.py; the work itself is in
the modules they call. Expected failures (a bad model file, a missing file) print
`ffrf-fmu: error: <message>` on stderr and exit 2, without a traceback.
"""
from __future__ import annotations

import argparse
import sys
from typing import Sequence

from ..checked_toml import ModelError
from . import recover, run, studies, system  # registers their subcommands

__all__ = ["main", "build_parser", "command_parser", "recover", "run", "studies", "system"]
from .common import _COMMANDS, PROG

# The order of `ffrf-fmu --help`.
ORDER = ("info", "recover", "campbell", "simulate", "stability", "chart", "study", "advise", "build", "validate",
         "system", "convergence")


def _commands():
    named = {fn.__name__: (fn, a) for fn, a in _COMMANDS}
    if set(named) != set(ORDER):
        raise RuntimeError(f"cli ORDER {ORDER} lists other commands than those registered: {sorted(named)}")
    return [named[n] for n in ORDER]


def _add_arguments(parser: argparse.ArgumentParser, arguments) -> None:
    for names, kwargs in arguments:
        parser.add_argument(*names, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description="Flexible bodies (beams and solids) as FFRF superelement FMUs.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for fn, arguments in _commands():
        doc = (fn.__doc__ or "").strip()
        p = sub.add_parser(fn.__name__, help=doc.splitlines()[0] if doc else None, description=doc)
        _add_arguments(p, arguments)
        p.set_defaults(run=fn)
    return parser


def command_parser(name: str, prog: str) -> argparse.ArgumentParser:
    """A stand-alone parser of one subcommand (build_fmu.py is `build` under another name)."""
    fn, arguments = next((fn, a) for fn, a in _COMMANDS if fn.__name__ == name)
    parser = argparse.ArgumentParser(prog=prog, description=(fn.__doc__ or "").strip().splitlines()[0])
    _add_arguments(parser, arguments)
    parser.set_defaults(run=fn)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except (ModelError, OSError) as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
