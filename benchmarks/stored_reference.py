"""A bundled scene's converged reference, stored beside its model (models/NAME.reference.json): the
scene's [reference] refined in mesh and step by the rule `advise --check` and `chart --resolve` use
(studies/resolve.py: until the primary metric moves by less than a tenth of the tolerance), with the
refinement table and the value judged against. The advisor's out-of-sample tests read these files
instead of rerunning full-order solves.

    python benchmarks/stored_reference.py models/sagging_rotor.toml --scene lag_kick --tolerance 0.5% -o /tmp/ref
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--scene", default=None)
    ap.add_argument("--tolerance", default="0.5%", help="the smallest tolerance the stored value must judge")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("-o", "--out", default="chart", help="the result store of the refinement runs")
    args = ap.parse_args()
    from ffrf_fmu.model import load_model
    from ffrf_fmu.studies.errors import primary_metric
    from ffrf_fmu.studies.resolve import format_resolution, resolve_reference

    tol = float(args.tolerance.rstrip("%")) / 100 if args.tolerance.endswith("%") else float(args.tolerance)
    model = load_model(args.model)
    scene = model.scene(args.scene)
    res, ref = resolve_reference(args.model, scene.name, tol, out_dir=args.out, max_rounds=args.rounds)
    print(format_resolution(res))
    if not res.resolved:
        raise SystemExit("not resolved: nothing stored")
    metric = primary_metric(scene)
    out = {"model": Path(args.model).name, "scene": scene.name, "metric": metric,
           "solver": "the full-order geometrically exact beam (ffrf_fmu/reference), ffrf_fmu.simulate.run_reference("
                     "model, scene, n_elements, step)",
           "value": ref["metrics"][metric], "metrics": ref["metrics"],
           "judged_against": {"n_elements": res.n_elements, "step": res.step},
           "resolved_to": max(abs(r.move) for r in res.rows[-2:]), "tolerance": tol, "reason": res.reason,
           "measured": f"{datetime.date.today().isoformat()}, load {os.getloadavg()[0]:.1f}, "
                       f"`python benchmarks/stored_reference.py {args.model} --scene {scene.name} --tolerance {args.tolerance}`",
           "rows": [r.__dict__ for r in res.rows]}
    path = Path(args.model).with_suffix(".reference.json")
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"stored in {path}")


if __name__ == "__main__":
    main()
