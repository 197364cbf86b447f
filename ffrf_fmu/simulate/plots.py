"""The figure of a run: the benchmark's quantity of interest (tip deflection or the hub's angular
velocity) and the energies. matplotlib is imported only when a figure is drawn."""
from __future__ import annotations

from ..model import Scene
from .quantities import elastic_tip, end_ports
from .results import SimulationResult


def plot(result: SimulationResult, scene: Scene, path) -> None:
    """Energies, and the benchmark's quantity of interest (tip deflection or port angular velocity)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    t = result.t
    hub, tip = end_ports(result.body)
    if scene.metrics.kind == "hub_rates":
        w = result.port(hub, "w")
        for i, c in enumerate("xyz"):
            ax1.plot(t, w[:, i], label=f"{hub} omega_{c}")
        ax1.set_ylabel("angular velocity [rad/s]")
    else:
        d = elastic_tip(result, hub, tip)
        for i, c in enumerate("xyz"):
            ax1.plot(t, d[:, i], label=f"{tip} elastic d_{c} (eq. 92)")
        ax1.set_ylabel("elastic tip displacement [m]")
    ax1.legend(loc="best")
    ax1.grid(True, alpha=0.3)
    c = result.columns
    energies = [k.removeprefix("energy.") for k in c if k.startswith("energy.")]
    total = sum(c[f"energy.{k}"] for k in energies if k != "work_external")
    for k in energies:
        ax2.plot(t, c[f"energy.{k}"], label=k.replace("_", " "))
    ax2.plot(t, total, "k--", lw=1, label="total")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("energy [J]")
    ax2.legend(loc="best")
    ax2.grid(True, alpha=0.3)
    model = (f"reference beam, {result.summary['elements']} elements" if result.summary.get("solver") == "reference"
             else f"{len(result.body.superelements)} SE, terms {scene.terms}")
    fig.suptitle(f"{result.body.name} / {scene.name}: {model}, h = {result.summary['step']:g} s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
