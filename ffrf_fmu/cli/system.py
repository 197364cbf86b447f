"""`ffrf-fmu system`: write or run a system of several FMUs."""
from __future__ import annotations

import sys

from .common import PROG, arg, command


@command(
    arg("action", choices=("write", "run"), help="write: an SSP 1.0 package from FMUs; run: a package under an engine"),
    arg("package", metavar="PACKAGE.ssp"),
    arg("--fmu", action="append", default=[], metavar="NAME=FILE", help="write: a component (repeat)"),
    arg("--ports", action="append", default=[], metavar="A.PORT:B.PORT", help="write: join two body ports rigidly (repeat)"),
    arg("--connect", action="append", default=[], metavar="SRC:DST[:GAIN]",
        help="write: a connection of variables or port fields, e.g. drive.hub_frame.R:beam.hub.R (repeat)"),
    arg("--set", dest="params", action="append", default=[], metavar="INSTANCE.VAR=VALUE", help="write: a parameter (repeat)"),
    arg("--step", type=float, help="communication step [s] (write: required; run: overrides the package's)"),
    arg("--stop", type=float, help="stop time [s] (write: required; run: overrides the package's)"),
    arg("--engine", choices=("master", "libcosim", "ecos"), default="master", help="run: the co-simulation engine"),
    arg("--record", default="", metavar="VAR,...", help="run: variables or port fields to record"),
    arg("-o", "--out", metavar="FILE.csv", help="run: write the recorded series"),
)
def system(args) -> int:
    """Write or run an SSP 1.0 system package (ffrf_fmu/master/ssp.py, docs/cosim.md)."""
    from pathlib import Path

    from ..master import ssp

    try:
        if args.action == "write":
            if args.step is None or args.stop is None:
                raise ssp.SspError("write needs --step and --stop")
            s = ssp.system_from_arguments(Path(args.package).stem, args.fmu, args.ports, args.connect, args.params,
                                          args.step, args.stop)
            ssp.write_ssp(args.package, s)
            print(f"wrote {args.package}: {len(s.components)} FMUs, {len(s.connections)} connections, "
                  f"{len(s.parameters)} parameters, H = {s.step:g} s, stop {s.stop:g} s")
            return 0
        pkg = ssp.read_ssp(args.package)
        names = [n for r in filter(None, args.record.split(",")) for n in ssp.expand(
            r, list(ssp._model_variables(pkg.components.get(r.split(".", 1)[0], "")) if r.split(".", 1)[0] in pkg.components else []))]
        run = ssp.run_ssp(args.package, args.engine, names, step=args.step, stop=args.stop)
    except ssp.SspError as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
    if args.out:
        ssp.write_csv(args.out, run)
    print(f"{args.engine}: {len(run.t)} steps to t = {run.t[-1] if len(run.t) else 0.0:g} s in {run.wall:.2f} s"
          + (f"; stopped: {run.stopped}" if run.stopped else ""))
    return 1 if run.stopped else 0
