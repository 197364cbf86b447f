"""The chart's figure: error against cost on log axes, the Pareto fronts, every point labelled
where it overlaps the fewest others, failed runs in a strip above each panel."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..peers import NAMES as PEER_NAMES

COSTS = {"wall": "wall_time_s", "cpu": "cpu_time_s"}  # cost measure -> row column
ERROR_FLOOR = 1e-6  # errors below this are drawn at the floor of the log axis


def _place_labels(ax, xs, ys, texts, fontsize=7):
    """Put each label near its point where it overlaps the fewest labels and points placed so far
    (greedy over 12 directions at 3 distances, display coordinates); labels set off by more than a
    few pixels get a thin leader line to their point."""
    fig = ax.figure
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    pts = ax.transData.transform(np.column_stack([xs, ys])) if len(xs) else np.zeros((0, 2))
    axbb = ax.get_window_extent(renderer)
    placed = []
    cands = [(0.0, 5.0)]
    for r, n in ((7.0, 12), (20.0, 12), (35.0, 16), (55.0, 16), (80.0, 16), (110.0, 16)):
        for k in range(n):
            a = 2 * math.pi * (k + 0.5 * (r > 30)) / n
            cands.append((r * math.cos(a), r * math.sin(a)))
    # crowded points first: they have the fewest good places
    crowd = [sum(np.hypot(*(pts[j] - pts[i])) < 30 for j in range(len(pts))) for i in range(len(pts))]
    for i in sorted(range(len(pts)), key=lambda i: -crowd[i]):
        x, y, text = xs[i], ys[i], texts[i]
        best = None
        for dx, dy in cands:
            ha = "left" if dx > 2 else "right" if dx < -2 else "center"
            va = "bottom" if dy > 2 else "top" if dy < -2 else "center"
            a = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset pixels", fontsize=fontsize, ha=ha,
                            va=va, color="0.15", zorder=5)
            bb = a.get_window_extent(renderer)
            score = sum(_overlap(bb, o) for o in placed)
            # never hide a point, and sit closer to the own point than to any other
            own = _distance(bb, pts[i])
            score += sum(5000.0 if _distance(bb, q) < 3 or _distance(bb, q) < own + 8 else 0.0
                         for j, q in enumerate(pts) if j != i)
            if bb.x0 < axbb.x0 or bb.x1 > axbb.x1 or bb.y0 < axbb.y0 or bb.y1 > axbb.y1:
                score += 1e5
            score += 2.0 * math.hypot(dx, dy)  # near its point, unless crowded
            if best is None or score < best[0]:
                if best is not None:
                    best[1].remove()
                best = (score, a, bb, dx, dy)
            else:
                a.remove()
        _, a, bb, dx, dy = best
        if math.hypot(dx, dy) > 10:
            a.remove()
            ha, va = a.get_ha(), a.get_va()
            a = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset pixels", fontsize=fontsize, ha=ha,
                            va=va, color="0.15", zorder=5,
                            arrowprops=dict(arrowstyle="-", lw=0.5, color="0.55", shrinkA=0, shrinkB=3))
        placed.append(bb)


def _distance(bb, p) -> float:
    """Distance from a point to a box (0 inside)."""
    dx = max(bb.x0 - p[0], 0.0, p[0] - bb.x1)
    dy = max(bb.y0 - p[1], 0.0, p[1] - bb.y1)
    return math.hypot(dx, dy)


def _overlap(a, b) -> float:
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w * h if w > 0 and h > 0 else 0.0


def plot_chart(rows: list[dict], path, title: str = "", metric_name: str | None = None,
               tolerances: Sequence[float] = (0.01, 0.05), cost: str = "wall") -> None:
    """Error (log) against wall (or CPU) time (log): one panel per error measure; colour = number of
    superelements, marker = term set, hollow = through the FMU; the Pareto front (of the primary
    error) connected by a black line and ringed; every point labelled; failed runs in a strip above
    each panel at the time they took until they failed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter

    panels = ([("metric_error_rel", f"relative error of {metric_name}")] if metric_name else []) + [
        ("rms_error_rel", "RMS error of the elastic tip trajectory (eq. 92) / max |d_ref|")]
    # panels stacked: the full page width for the (log) time axis, where the cheap runs crowd
    fig = plt.figure(figsize=(17.0, 8.0 * len(panels)))
    gs = fig.add_gridspec(2 * len(panels), 1, height_ratios=[1, 12] * len(panels), hspace=0.06, top=0.95,
                          bottom=0.05)
    ck = COSTS[cost]
    ok = [r for r in rows if r["completed"] and r[ck]]
    bad = [r for r in rows if not r["completed"]]
    times = [r[ck] for r in rows if r[ck]]
    xlim = (min(times) / 1.8, max(times) * 1.8) if times else (0.1, 10)
    front_key = "metric_error_rel" if metric_name else "rms_error_rel"
    counts = sorted({int(r["superelements"]) for r in rows if r["runner"] not in PEER_NAMES})
    peer_style = dict(marker="D", color="C3")  # a peer's runs: red diamonds, its front dash-dotted
    cmap = plt.get_cmap("viridis")
    colour = {n: cmap(0.9 * k / max(len(counts) - 1, 1)) for k, n in enumerate(counts)}
    shape = {"linear": "o", "gyroscopic": "^"}
    for p, (key, name) in enumerate(panels):
        ax = fig.add_subplot(gs[2 * p + 1, 0])
        top = fig.add_subplot(gs[2 * p, 0], sharex=ax)
        pts = [r for r in ok if r[key] is not None]
        x = np.array([r[ck] for r in pts])
        y = np.maximum([r[key] for r in pts], ERROR_FLOOR) if pts else np.zeros(0)
        for r, xi, yi in zip(pts, x, y):
            if r["runner"] in PEER_NAMES:
                ax.scatter([xi], [yi], s=30, marker=peer_style["marker"], facecolors=peer_style["color"], zorder=3)
                continue
            c = colour[int(r["superelements"])]
            hollow = r["runner"] == "fmu"
            ax.scatter([xi], [yi], s=34, marker=shape.get(r["terms"], "s"), facecolors="none" if hollow else [c],
                       edgecolors=[c], lw=1.4 if hollow else 0.5, zorder=3)
        for runner, ls in (("standalone", "-"), ("fmu", "--"), *((p, "-.") for p in PEER_NAMES)):
            on = [(r[ck], max(r[key], ERROR_FLOOR)) for r in pts if r["runner"] == runner and r.get("pareto")]
            if on:
                fx, fy = zip(*sorted(on))
                fc = peer_style["color"] if runner in PEER_NAMES else "k"
                ax.plot(fx, fy, ls, color=fc, lw=1.2, alpha=0.8, zorder=2)
                ax.scatter(fx, fy, s=120, facecolors="none", edgecolors=fc, lw=1.0, zorder=4)
        for tol in tolerances:
            ax.axhline(tol, color="0.5", lw=0.8, ls=":", zorder=1)
            ax.text(xlim[1] / 1.05, tol * 1.06, f"{tol:.0%}", color="0.4", fontsize=8, va="bottom", ha="right")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(*xlim)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if f"{v:g}"[0] in "25" else ""))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{100 * v:g}%"))
        if len(y):
            lo, hi = min(y.min(), min(tolerances)), max(y.max(), max(tolerances))
            ax.set_ylim(lo / 2.5, hi * 2.5)
        ax.set_xlabel(("wall" if cost == "wall" else "CPU") + " time of the run [s] (time stepping only)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.25)
        handles = [Line2D([], [], ls="", marker="o", color=colour[n], label=f"{n} SE") for n in counts]
        handles += [Line2D([], [], ls="", marker=m, color="0.4", label=t) for t, m in shape.items()
                    if any(r["terms"] == t for r in rows)]
        if any(r["runner"] == "fmu" for r in rows):
            handles.append(Line2D([], [], ls="", marker="o", mfc="none", color="0.4", label="through the FMU"))
        handles.append(Line2D([], [], color="k", marker="o", mfc="none", ms=10,
                              label="Pareto front" + (" (of the upper panel)" if key != front_key else "")))
        handles += [Line2D([], [], ls="-.", color=peer_style["color"], marker=peer_style["marker"],
                           label=f"{PEER_NAMES[p]} (full-order 3D beam) and its front")
                    for p in PEER_NAMES if any(r["runner"] == p for r in rows)]
        ax.legend(handles=handles, loc="lower left", fontsize=8, ncol=2)
        _place_labels(ax, list(x), list(y), [r["label"] + (" FMU" if r["runner"] == "fmu" else "") for r in pts])
        # failed runs: a strip above the panel, at the time they took until they failed
        top.set_yticks([])
        top.set_ylim(0, 1)
        top.tick_params(axis="x", which="both", labelbottom=False)
        top.set_ylabel("failed", rotation=0, ha="right", va="center", fontsize=8, color="C3")
        for k, r in enumerate(bad):
            xb = r[ck] or xlim[0] * 1.2
            top.plot([xb], [0.5], "x", color="C3", ms=7, mew=2)
            where = f" (stopped at t = {r['t_end_s']:.3g} s)" if r.get("t_end_s") is not None else ""
            top.annotate(r["label"] + (" FMU" if r["runner"] == "fmu" else "") + where, (xb, 0.5),
                         xytext=(6, 3 if k % 2 == 0 else -9), textcoords="offset points", fontsize=7, color="C3")
        if not bad:
            top.text(0.5, 0.5, "no failed runs", transform=top.transAxes, ha="center", va="center", fontsize=8,
                     color="0.5")
    fig.suptitle(title, fontsize=11, y=0.97)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
