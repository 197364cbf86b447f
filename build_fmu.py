#!/usr/bin/env python3
"""Build the FMU of a model's body: the same as `ffrf-fmu build`.

    python build_fmu.py MODEL [--scene NAME] [--set KEY=VALUE ...] -o Body.fmu

The FMU takes the scene's port causality and its solver values (step, rho_inf, terms, gravity,
initial velocities) as parameter defaults; see docs/fmu.md.
"""
import sys

from ffrf_fmu.cli import command_parser


def main(argv=None) -> int:
    args = command_parser("build", prog="build_fmu.py").parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
