"""The conrod in a crank drive (docs/inertia-terms.md, "The conrod in a crank drive"): the drive's modes,
the SSP package under our master, libcosim and ecos against the monolithic run at H = 1e-5 s (and our master
at 2e-5 and 5e-6 s: the coupling error's order), the plot docs/crank_drive.png, and with --convergence the
hand-made advice at 1 % (modes, term set, step) against a converged reference (40 modes, h = 1.25e-6 s).

    python benchmarks/crank_drive.py [--convergence] [--out DIR]
"""
from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

from ffrf_fmu.examples import crank_drive as cd
from ffrf_fmu.examples.crank_monolithic import monolithic
from ffrf_fmu.master.ssp import write_ssp

DOCS = Path(__file__).resolve().parents[1] / "docs"
DURATION = 7.5e-3  # the run-up (one revolution in 2.5 ms) and four revolutions at 5000 rad/s


def plot(runs: dict, mono: cd.CrankRun, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    styles = {"master": ("C0", "-", 2.5), "libcosim": ("C1", "--", 1.6), "ecos": ("C2", ":", 1.6)}
    for ax, name, label in zip(axes, ("bending", "axial"), ("bending", "axial")):
        ax.plot(np.degrees(mono.angle), 1e3 * getattr(mono, name), "k-", lw=1.0, label="monolithic")
        for e, r in runs.items():
            c, ls, lw = styles[e]
            ax.plot(np.degrees(r.angle), 1e3 * getattr(r, name), color=c, ls=ls, lw=lw, alpha=0.8, label=f"{e} (SSP, H = 10 us)")
        ax.set_ylabel(f"mid-shank {label} [mm]")
        ax.grid(alpha=0.3)
    for k in range(1, 5):  # the firings: top dead centre of each revolution after the run-up
        for ax in axes:
            ax.axvline(360 * k, color="0.6", lw=0.6)
    axes[0].legend(loc="upper left", fontsize=8)
    axes[1].set_xlabel("crank angle [deg] (run-up to 5000 rad/s over the first 360 deg; gas force 0-60 deg after each later TDC)")
    fig.suptitle("Conrod in a crank drive: mid-shank deformation, three engines and the monolithic run")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--convergence", action="store_true")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    out = Path(args.out or tempfile.mkdtemp(prefix="crank_drive_"))
    drive = cd.CrankDrive()
    body = cd.reduced_body()
    print(f"crank {drive.omega:g} rad/s = {drive.omega / 2 / math.pi:.1f} Hz; free-free f1 "
          f"{body.superelements[0].frequencies_hz[0]:.1f} Hz")
    for m in cd.drive_modes(body, drive):
        print(f"  drive mode {m.frequency_hz:8.1f} Hz  mid-shank {np.round(m.mid_shank, 3)}  piston {m.piston:.3f}")
    fmus = cd.build(out / "fmus", body=body)
    for H in (1e-5, 2e-5, 5e-6):
        pkg = write_ssp(out / f"crank_{H:g}.ssp", cd.system(fmus, drive, H, DURATION))
        mono = monolithic(drive, H, DURATION, body=body)
        print(f"H = {H:g} s: monolithic peaks axial {np.abs(mono.axial).max():.4e} m, bending "
              f"{np.abs(mono.bending).max():.4e} m ({mono.wall:.1f} s)")
        runs = {}
        for e in (("master", "libcosim", "ecos") if H == 1e-5 else ("master",)):
            r = runs[e] = cd.run_package(pkg, e)
            d = cd.deviation(r, mono)
            print(f"  {e:9s} axial {d.axial:.3e}  bending {d.bending:.3e}  ({r.wall:.1f} s){'  ' + r.stopped if r.stopped else ''}")
        if H == 1e-5:
            ref = runs["master"]
            for e in ("libcosim", "ecos"):
                dd = max(np.abs(getattr(runs[e], n) - getattr(ref, n)).max() / np.abs(getattr(ref, n)).max()
                         for n in ("axial", "bending"))
                print(f"  {e} vs master: {dd:.2e} of the peaks")
            plot(runs, mono, DOCS / "crank_drive.png")
            print(f"  wrote {DOCS / 'crank_drive.png'}")
    if not args.convergence:
        return
    print("convergence (monolithic, 7.5 ms): max difference over the peak, axial / bending")
    ref_key = (40, 1.25e-6, "full")
    cache: dict = {}

    def run(modes, h, terms="full"):
        key = (modes, h, terms)
        if key not in cache:
            ov = [f"body.modes={modes}", f'scenes.crank.terms="{terms}"']
            b = cd.reduced_body(overrides=ov)
            cache[key] = monolithic(drive, h, DURATION, overrides=ov, body=b)
        return cache[key]

    ref = run(*ref_key)
    rows = [(40, 2.5e-6, "full"), (6, 2.5e-6, "full"), (15, 2.5e-6, "full"), (6, 5e-6, "full"), (6, 1e-5, "full"),
            (6, 5e-6, "linear"), (6, 5e-6, "gyroscopic")]
    for key in rows:
        d = cd.deviation(run(*key), ref)
        print(f"  modes {key[0]:3d}  h {key[1]:.3g}  {key[2]:10s}  {d.axial:.2e} / {d.bending:.2e}")


if __name__ == "__main__":
    main()
