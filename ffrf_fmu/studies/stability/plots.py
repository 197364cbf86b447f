"""The stability maps' figures (docs/stability_*.png) from their tables (map.csv)."""
from __future__ import annotations

import numpy as np

from .common import is_true
from .case import COSIM_SCHEMES, DRIVE
from .tasks import COMPLIANT, IMPLICIT, INTERFACE_JACOBIAN, REFERENCE


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_spin(rows: list[dict], path) -> None:
    plt = _plt()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2))
    ref = sorted((r for r in rows if r["model"] == "reference"), key=lambda r: r["omega"])
    names = sorted({r["model"] for r in rows if r["model"] != "reference"},
                   key=lambda s: (s.split("-")[1], int(s.split("SE")[0])))
    ax2.plot([r["omega"] for r in ref], [r["max_deflection"] for r in ref], "k-o", lw=2, label="nonlinear reference")
    colors = {1: "tab:red", 2: "tab:orange", 4: "tab:green"}
    for name in names:
        rs = sorted((r for r in rows if r["model"] == name), key=lambda r: r["omega"])
        n, terms = int(name.split("SE")[0]), name.split("-")[1]
        style = "-" if terms == "linear" else "--"
        marginal = [r for r in rs if r.get("verdict") == "marginal"]  # the verdict changed under round-off (margin.py)
        ok = [r for r in rs if not is_true(r["unstable"]) and r not in marginal]
        bad = [r for r in rs if is_true(r["unstable"]) and r not in marginal]
        kw = dict(color=colors.get(n, "tab:blue"), ls=style, marker="o" if terms == "linear" else "s", ms=4)
        ax1.plot([r["omega"] for r in ok], [max(abs(100 * r["rel_error"]), 1e-3) for r in ok],
                 label=f"{n} SE, {terms}", **kw)
        ax2.plot([r["omega"] for r in ok], [r["max_deflection"] for r in ok], label=f"{n} SE, {terms}", **kw)
        y_bad = 1000.0 if terms == "linear" else 2000.0
        for r in bad:
            ax1.plot(r["omega"], y_bad, "x" if terms == "linear" else "+", color=kw["color"], ms=11, mew=3)
        for r in marginal:
            ax1.plot(r["omega"], y_bad, "o", mfc="none", color=kw["color"], ms=11, mew=2)
    f1 = ref[0].get("first_frequency_rad_s") if ref else None  # of the model at rest (spin_map)
    if f1:
        ax1.axvline(f1, color="gray", ls=":", lw=1)
        ax1.text(f1 * 1.03, 0.05, f"first cantilever\nfrequency {f1:.3g} rad/s", fontsize=7, color="gray")
    ax1.text(1.0, 3000.0, "unstable (deflection > L or Newton failure): x linear, + gyroscopic\n"
             "o marginal (verdict changed under a 1e-9 perturbation or at the neighbour spin)", fontsize=7)
    ax1.set_yscale("log")
    ax1.set_ylim(0.03, 6000.0)
    ax1.set_xlabel("final spin rate [rad/s]")
    ax1.set_ylabel("|error| of the max transverse tip deflection [%]")
    ax1.set_title("model error vs the nonlinear beam (x: unstable)")
    ax1.grid(True, alpha=0.3)
    ax1.legend(fontsize=8)
    ax2.set_xlabel("final spin rate [rad/s]")
    ax2.set_ylabel("max transverse tip deflection [m]")
    ax2.set_yscale("log")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=8)
    T = ref[0].get("T") if ref else None
    fig.suptitle(f"spin-up beyond the first bending frequency (T = {T:g} s, run {ref[0]['duration']:g} s)"
                 if ref else "spin map")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_integrator(rows: list[dict], path) -> None:
    plt = _plt()
    benches = sorted({(r["benchmark"], r["scene"]) for r in rows})
    fig, axes = plt.subplots(1, max(1, len(benches)), figsize=(6.5 * max(1, len(benches)), 5.2), squeeze=False)
    colors = {0.0: "tab:blue", 0.5: "tab:green", 0.8: "tab:orange", 1.0: "tab:red"}
    for ax, (b, sc) in zip(axes[0], benches):
        rs = [r for r in rows if r["benchmark"] == b and r["scene"] == sc and not is_true(r["converged"])]
        conv = [r for r in rows if r["benchmark"] == b and r["scene"] == sc and is_true(r["converged"])]
        for irho, rho in enumerate(sorted({r["rho_inf"] for r in rs})):
            rr = sorted((r for r in rs if r["rho_inf"] == rho), key=lambda r: r["step"])
            ok = [r for r in rr if not is_true(r["unstable"])]
            c = colors.get(rho, None)
            ax.plot([r["step"] for r in ok], [max(abs(r["peak_rel_error"]), 1e-7) for r in ok], "-o", color=c,
                    label=f"rho_inf = {rho:g}: max deflection")
            ax.plot([r["step"] for r in ok], [max(r["rel_error"], 1e-7) for r in ok], ":", color=c, lw=1,
                    label=f"rho_inf = {rho:g}: history")
            for r in rr:
                if r.get("verdict") == "marginal":  # the verdict changed under round-off (margin.py)
                    ax.plot(r["step"], 2.0 * 1.6**irho, "o", mfc="none", color=c, ms=11, mew=2)
                elif is_true(r["unstable"]):
                    ax.plot(r["step"], 2.0 * 1.6**irho, "x", color=c, ms=10, mew=3)
        ax.axhline(1.0, color="k", lw=0.5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time step h [s]")
        ax.set_ylabel("relative error of the tip deflection\nmaximum (solid), history (dotted)")
        hc = conv[0]["step"] if conv else float("nan")
        ax.set_title(f"{b} / {sc} (converged: h = {hc:g} s)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle("Integrator: generalized-alpha step size against rho_inf "
                 "(x = unstable: Newton failure or energy growth, o = marginal: the verdict changed under a 1e-9 "
                 "perturbation or at the neighbour step; one row per rho_inf)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def cosim_verdict(row: dict) -> str:
    """A map row's verdict; rows written before the verdict column: from `unstable` and the errors
    against cosim.ACCURACY_BOUND."""
    from .cosim import ACCURACY_BOUND

    v = row.get("verdict")
    if isinstance(v, str) and v:
        return v
    if is_true(row["unstable"]):
        return "unstable"
    errs = [row.get(k) for k in ("rel_error", "speed_rel_error")]
    errs = [float(e) for e in errs if e is not None and e == e]
    return "inaccurate" if errs and max(errs) > ACCURACY_BOUND else "stable"


def plot_cosim(rows: list[dict], path) -> None:
    """Per case a grid scheme x H: stable cells coloured by their error, inaccurate ones (completed,
    error above cosim.ACCURACY_BOUND) hatched orange with the error, unstable ones red."""
    plt = _plt()
    from matplotlib.colors import LogNorm
    from .cosim import ACCURACY_BOUND

    cases = [c for c in ("motor", "split") if any(r["case"] == c for r in rows)]
    fig, axes = plt.subplots(len(cases), 1, figsize=(10, 3.9 * len(cases)), squeeze=False)
    titles = {"motor": "B5 beam FMU + hub drive FMU (shaft k = {k:g} N m/rad, hub J = {J:g} kg m^2): error against the monolithic run",
              "split": "B1 beam split in two body FMUs at its middle node: error against the one-body run"}
    for ax, case in zip(axes[:, 0], cases):
        rs = [r for r in rows if r["case"] == case and r["scheme"] != REFERENCE]
        schemes = [s[0] for s in COSIM_SCHEMES + (IMPLICIT, INTERFACE_JACOBIAN, COMPLIANT) if any(r["scheme"] == s[0] for r in rs)]
        steps = sorted({r["H"] for r in rs})
        grid = np.full((len(schemes), len(steps)), np.nan)
        verdict, label = {}, {}
        for r in rs:
            i, j = schemes.index(r["scheme"]), steps.index(r["H"])
            verdict[i, j] = v = cosim_verdict(r)
            errs = [float(r[k]) for k in ("rel_error", "speed_rel_error") if r.get(k) is not None and r[k] == r[k]]
            grid[i, j] = max(max(errs) if errs else np.nan, 1e-9)
            if v == "unstable" and "did not converge" in str(r["failure"]):
                label[i, j] = "not converged"
        shown = np.array([[grid[i, j] if verdict.get((i, j)) == "stable" else np.nan for j in range(len(steps))]
                          for i in range(len(schemes))]).reshape(len(schemes), len(steps))
        im = ax.imshow(shown, aspect="auto", cmap="viridis", norm=LogNorm(vmin=1e-6, vmax=ACCURACY_BOUND))
        for i in range(len(schemes)):
            for j in range(len(steps)):
                v, e = verdict.get((i, j)), grid[i, j]
                if v is None:
                    ax.text(j, i, "-", ha="center", va="center", color="gray", fontsize=8)
                elif v == "unstable":
                    ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, color="tab:red"))
                    ax.text(j, i, label.get((i, j), "unstable"), ha="center", va="center", color="white", fontsize=8,
                            weight="bold")
                elif v == "marginal":  # the verdict changed under round-off (margin.py)
                    ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, facecolor="white", edgecolor="tab:red",
                                               lw=2))
                    ax.text(j, i, "marginal", ha="center", va="center", color="tab:red", fontsize=8, weight="bold")
                elif v == "inaccurate":
                    ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, facecolor="moccasin", edgecolor="tab:orange",
                                               hatch="//", lw=0))
                    ax.text(j, i, f"inaccurate\n{e:.1e}", ha="center", va="center", color="black", fontsize=7)
                else:
                    ax.text(j, i, f"{e:.1e}", ha="center", va="center", color="white" if e < 1e-3 else "black", fontsize=8)
        ax.set_xticks(range(len(steps)), [f"{1000 * h:g} ms" for h in steps])
        ax.set_yticks(range(len(schemes)), schemes, fontsize=8)
        ax.set_xlabel("communication step H")
        ax.set_title(titles[case].format(k=DRIVE["drive.k"], J=DRIVE["drive.J"]), fontsize=9)
        fig.colorbar(im, ax=ax, label=f"error (stable: completed and <= {ACCURACY_BOUND:g})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


PLOTS = {"spin": plot_spin, "integrator": plot_integrator, "cosim": plot_cosim}
