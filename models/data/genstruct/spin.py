"""GenStruct1 and GenStruct2 spun up (scene `spin` of models/genstruct1.toml, genstruct2.toml;
docs/inertia-terms.md, "GenStruct1 and GenStruct2"): the corner's displacement seen from the spinning
hub, averaged over the 0.1 s at speed, with the advised terms against a converged reference of the same scene
(terms full, more free modes, half the step), and what each term set gives.

Run: PYTHONPATH=$PWD python models/data/genstruct/spin.py [docs [1] [2]]   (writes docs/genstruct{1,2}_spin.png)
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ffrf_fmu.simulate.loop import run_scene

MODELS = Path(__file__).resolve().parents[2]
REFERENCE_MODES = (20, 40, 80)  # the reference's convergence in the number of free modes (terms full, h / 2)
REFERENCE = f"full, {REFERENCE_MODES[-1]} modes, h/2"


HOLD = 0.2  # the spin-up ends here; the metric is the mean over the 0.1 s at speed (the ringing averages out)


def widening(result) -> tuple[np.ndarray, np.ndarray]:
    """(t, |u| [m]): the corner frame's displacement seen from the hub frame (the spinning frame), the
    quantity the term rule measures on the steady spin (term_rule.steady_term_effects)."""
    c = result.columns
    d = np.stack([c[f"corner.r[{i}]"] - c[f"hub.r[{i}]"] for i in (1, 2, 3)], axis=1)
    R = np.stack([np.stack([c[f"hub.R[{i},{j}]"] for j in (1, 2, 3)], axis=1) for i in (1, 2, 3)], axis=1)
    local = np.einsum("tji,tj->ti", R, d)  # R^T d
    return result.t, np.linalg.norm(local - local[0], axis=1)


def metric(t: np.ndarray, u: np.ndarray) -> float:
    """The scene's metric: the mean corner displacement over the time at speed (t >= HOLD)."""
    return float(u[t >= HOLD - 1e-12].mean())


def run(n: int, overrides=()) -> tuple[np.ndarray, np.ndarray]:
    return widening(run_scene(MODELS / f"genstruct{n}.toml", "spin", list(overrides)))


def study(n: int) -> dict:
    """The metric of each configuration, and the curves."""
    from ffrf_fmu.model import load_model

    h = load_model(MODELS / f"genstruct{n}.toml").scene("spin").step  # the scene's step
    runs = {"advised": run(n)}
    for k in REFERENCE_MODES:
        runs[f"full, {k} modes, h/2"] = run(n, ["terms=full", f"modes={k}", f"step={h / 2:g}"])
    runs[f"full, {REFERENCE_MODES[-1]} modes, h/4"] = run(n, ["terms=full", f"modes={REFERENCE_MODES[-1]}", f"step={h / 4:g}"])
    runs["full, 20 modes"] = run(n, ["terms=full"])
    runs["W1 only"] = run(n, ["terms=full", "full_terms=[\"inertia_W1\"]"])
    runs["W1 and W2"] = run(n, ["terms=full", "full_terms=[\"inertia_W1\", \"inertia_W2\"]"])
    runs["full without W2"] = run(n, ["terms=full", "full_terms=[\"inertia_W1\", \"inertia_coupling\", \"coriolis\"]"])
    runs["linear"] = run(n, ["terms=linear"])
    return {k: (t, u, metric(t, u)) for k, (t, u) in runs.items()}


def plot(n: int, res: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = res[REFERENCE]
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for k, style in (("advised", "-"), (REFERENCE, "--"), ("W1 only" if n == 1 else "W1 and W2", ":"),
                     ("linear", "-.")):
        t, u, _ = res[k]
        ax.plot(t, u * 1e3, style, label=f"{k}: mean {res[k][2] * 1e3:.4g} mm over t >= {HOLD:g} s")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("corner displacement in the hub frame [mm]")
    ax.set_title(f"GenStruct{n} spun up to 200 rad/s in 0.2 s (reference {ref[2] * 1e3:.4g} mm)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    docs = Path(sys.argv[1]) if len(sys.argv) > 1 else None
    for n in [int(a) for a in sys.argv[2:]] or (1, 2):
        res = study(n)
        ref = res[REFERENCE][2]
        print(f"GenStruct{n}: mean corner displacement at speed [m] and error against the reference (full, "
              f"{REFERENCE_MODES[-1]} modes, h/2)")
        for k, (_, _, u) in res.items():
            print(f"  {k:24s} {u:.6e}  {abs(u - ref) / abs(ref):.3%}")
        if docs is not None:
            plot(n, res, docs / f"genstruct{n}_spin.png")
