"""The car body on its mounts, the Jeffcott run-up and GenStruct1/2 spun up as SSP systems under our master,
libcosim and ecos, against their monolithic runs (ffrf_fmu/examples/car_body_system.py, rotor_system.py,
genstruct_system.py; docs/cosim.md, docs/inertia-terms.md): errors, peaks, walls printed, and the plots
docs/car_body_system.png, docs/jeffcott_system.png, docs/genstruct_system.png.

    PYTHONPATH=$PWD python benchmarks/witteveen_systems.py [car|rotor|genstruct ...] [--out docs]
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ffrf_fmu.examples import car_body_system as cs  # noqa: E402
from ffrf_fmu.examples import genstruct_system as gs  # noqa: E402
from ffrf_fmu.examples import rotor_system as rs  # noqa: E402
from ffrf_fmu.master.ssp import ENGINES, write_ssp  # noqa: E402

STYLE = {"master": ("C0", "-", 2.5), "libcosim": ("C1", "--", 1.5), "ecos": ("C2", ":", 1.5)}


def car(work: Path, out: Path, H: float = 1e-3, duration: float = 2.0) -> None:
    fmus = cs.build(work / "car", step=H, duration=duration)
    pkg = write_ssp(work / "car" / "car_body_bump.ssp", cs.system(fmus, H, duration))
    ref = cs.run_monolithic(H, duration)
    runs = {e: cs.run_engine(pkg, e) for e in ENGINES}
    fig, axs = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for ax, f, scale, lab in zip(axs, ("twist", "probe", "force"), (1e6, 1e3, 1.0),
                                 ("twist angle [urad]", "rear_right from front_left, z [mm]", "front_left mount force z [N]")):
        ax.plot(ref.t, getattr(ref, f) * scale, color="k", lw=4, alpha=0.3, label="monolithic (scene bump)")
        for e, r in runs.items():
            c, ls, lw = STYLE[e]
            ax.plot(r.t, getattr(r, f) * scale, color=c, ls=ls, lw=lw, label=f"{e} ({cs.error(r, ref, f):.2e})")
        ax.set_ylabel(lab)
        ax.legend(fontsize=7, loc="upper right")
    axs[-1].set_xlabel("t [s]")
    axs[0].set_title(f"car body on four compliant mounts, road bump under front_left: H = {H * 1e3:g} ms "
                     "(max error over the peak in brackets)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "car_body_system.png", dpi=110)
    print(f"car body: monolithic {ref.wall:.1f} s wall; peak twist {np.abs(ref.twist).max():.4g} rad, "
          f"probe {np.abs(ref.probe).max():.4g} m")
    for e, r in runs.items():
        print(f"  {e}: {r.wall:.1f} s wall, " + ", ".join(f"{f} {cs.error(r, ref, f):.3g}" for f in ("twist", "probe", "force"))
              + (f"; stopped: {r.stopped}" if r.stopped else ""))


def rotor(work: Path, out: Path, H: float = 5e-4, duration: float = 10.0) -> None:
    fmus = rs.build(work / "rotor", step=H, duration=duration)
    pkg = write_ssp(work / "rotor" / "jeffcott_runup.ssp", rs.system(fmus, H, duration))
    ref = rs.run_monolithic(H, duration)
    runs = {e: rs.run_engine(pkg, e) for e in ENGINES}
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(ref.speed, ref.whirl * 1e3, color="k", lw=4, alpha=0.3,
            label=f"monolithic (scene runup): peak {ref.peak[0] * 1e3:.4g} mm at {ref.peak[1]:.4g} rad/s")
    for e, r in runs.items():
        c, ls, lw = STYLE[e]
        ax.plot(r.speed, r.whirl * 1e3, color=c, ls=ls, lw=lw,
                label=f"{e}: peak {r.peak[0] * 1e3:.4g} mm at {r.peak[1]:.4g} rad/s (history {rs.error(r, ref):.2e})")
    ax.axvline(169.57, color="r", lw=1, label="Campbell crossing 169.57 rad/s (first bending on the bearings)")
    ax.set_xlabel("drive speed [rad/s]"), ax.set_ylabel("disc whirl amplitude [mm]")
    ax.set_title(f"Jeffcott rotor run-up (Wu-Haug, 340 rad/s in 10 s), rotor FMU + spin drive FMU, H = {H * 1e3:g} ms",
                 fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "jeffcott_system.png", dpi=110)
    print(f"rotor: monolithic {ref.wall:.1f} s wall; peak {ref.peak[0] * 1e3:.5g} mm at {ref.peak[1]:.5g} rad/s")
    for e, r in runs.items():
        late = np.interp(r.t - H, ref.t, ref.whirl)
        print(f"  {e}: {r.wall:.1f} s wall, peak {r.peak[0] * 1e3:.5g} mm at {r.peak[1]:.5g} rad/s "
              f"({r.peak[0] / ref.peak[0] - 1:+.2e}), history {rs.error(r, ref):.3g}, against the reference one step "
              f"late {np.abs(r.whirl - late).max() / ref.whirl.max():.3g}" + (f"; stopped: {r.stopped}" if r.stopped else ""))


def genstruct(work: Path, out: Path, steps=((1, 5e-4), (2, 2.5e-4)), duration: float = 0.3, T: float = 0.2) -> None:
    """Each GenStruct at its scene's step (GenStruct2's 0.25 ms: docs/inertia-terms.md), H = that step."""
    fig, axs = plt.subplots(len(steps), 1, figsize=(8, 3.6 * len(steps)), sharex=True)
    for ax, (n, H) in zip(np.atleast_1d(axs), steps):
        fmus = gs.build(work / f"genstruct{n}", n, step=H)
        pkg = write_ssp(work / f"genstruct{n}" / f"genstruct{n}.ssp", gs.system(fmus, H, duration))
        ref = gs.run_monolithic(n, H)
        runs = {e: gs.run_engine(pkg, e) for e in ENGINES}
        scale = 1e3 if n == 1 else 1e6
        ax.plot(ref.t, ref.magnitude * scale, color="k", lw=4, alpha=0.3,
                label=f"monolithic (scene spin): mean at speed {ref.mean_at_speed(T) * scale:.5g}")
        for e, r in runs.items():
            c, ls, lw = STYLE[e]
            ax.plot(r.t, r.magnitude * scale, color=c, ls=ls, lw=lw,
                    label=f"{e}: mean at speed {r.mean_at_speed(T) * scale:.5g} (history {gs.error(r, ref):.2e})")
        ax.axvline(T, color="r", lw=1, label=f"spin-up ends: {ref.speed.max():.4g} rad/s")
        ax.set_ylabel(f"GenStruct{n}: |corner from hub| [{'mm' if n == 1 else 'um'}]")
        ax.legend(fontsize=7, loc="upper left")
        ax.set_title(f"GenStruct{n} FMU + spin drive FMU, H = {H * 1e3:g} ms", fontsize=9)
        print(f"genstruct{n}: monolithic {ref.wall:.1f} s wall; peak {ref.magnitude.max():.5g} m, mean at speed "
              f"{ref.mean_at_speed(T):.6g} m")
        for e, r in runs.items():
            print(f"  {e}: {r.wall:.1f} s wall, history {gs.error(r, ref):.3g} of the peak, mean at speed "
                  f"{r.mean_at_speed(T) / ref.mean_at_speed(T) - 1:+.2e}, against master "
                  f"{np.abs(r.u - runs['master'].u).max() / ref.magnitude.max():.2g}"
                  + (f"; stopped: {r.stopped}" if r.stopped else ""))
    np.atleast_1d(axs)[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "genstruct_system.png", dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=["car", "rotor", "genstruct"], choices=["car", "rotor", "genstruct"])
    ap.add_argument("--out", default="docs")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="witteveen_systems_") as tmp:
        for s in a.scenes:
            {"car": car, "rotor": rotor, "genstruct": genstruct}[s](Path(tmp), out)


if __name__ == "__main__":
    main()
