#!/usr/bin/env python3
"""Build the FMU of a model's body: the same as `ffrf-fmu build`.

    python build_fmu.py MODEL [--scene NAME] [--set KEY=VALUE ...] -o Body.fmu

The FMU takes the scene's port causality and its solver values (step, rho_inf, terms, gravity,
initial velocities) as parameter defaults; see docs/fmu.md.
"""
import argparse
import sys

from ffrf_fmu.fmu.builder import add_build_arguments, build_command


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="build_fmu.py", description=__doc__.strip().splitlines()[0])
    add_build_arguments(parser)
    return build_command(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
