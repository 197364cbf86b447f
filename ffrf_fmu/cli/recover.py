"""`ffrf-fmu recover`: a solid's stresses recovered from a run."""
from __future__ import annotations

from ..checked_toml import ModelError
from .common import MODEL_ARGS, _load, arg, command


@command(
    *MODEL_ARGS,
    arg("--out", metavar="DIR", required=True, help="directory for modal.csv and the VTK series (BODY.pvd, BODY_*.vtu)"),
    arg("--every", type=int, default=10, metavar="N", help="record every N-th step (default 10)"),
    arg("--no-vtk", action="store_true", help="write the modal coordinates only"),
    arg("--png", metavar="FILE.png", help="also draw one recorded state's deformed surface (studies/render.py)"),
    arg("--at", type=float, metavar="T", help="--png: the recorded state nearest to time T [s] (default: largest deformation)"),
    arg("--scale", type=float, metavar="S", help="--png: deformation scale (default: largest |u| = 5%% of the extent)"),
)
def recover(args) -> int:
    """Run a solid's scene and write its modal coordinates (modal.csv) and deformed mesh (VTK for ParaView)."""
    model, scene = _load(args)
    if args.every < 1:
        raise ModelError(f"--every: expected a positive integer, got {args.every}")
    from pathlib import Path

    from ..simulate.recovery import run_recorded, write_modal_csv, write_vtk

    rec, red, data = run_recorded(model, scene.name, every=args.every)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_modal_csv(rec, red, out / "modal.csv")
    print(f"{out / 'modal.csv'}: {len(rec.t)} states, {rec.q.shape[1]} elastic coordinates")
    if not args.no_vtk:
        print(f"{write_vtk(rec, red, out, data.name)}: {len(rec.t)} meshes of {red.fe.n_nodes} nodes")
    if args.png:
        from ..studies.render import pick_state, render_state

        i = pick_state(rec, red, args.at)
        pic = render_state(red, rec.q[i], args.png, float(rec.t[i]), args.scale,
                           title=f"{data.name}, scene {scene.name}")
        print(f"{pic.path}: t = {pic.t:.6g} s (state {i}), deformation x {pic.scale:.4g}, max |u| = {pic.u_max:.4g} m")
    return 0
