"""Shared by the cost benchmarks: CPU time per body step (stiffening_cost.py, term_cost.py) and B1's
spin-up system at a small configuration (jacobian_cost.py, refresh_cost.py)."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from ffrf_fmu import simulate as sim
from ffrf_fmu.body_cache import scene_body_data
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_scene_body


def cpu_per_step(model_path: str, scene_name: str, overrides, steps: int, repeat: int, backend: str = "numpy") -> float:
    """Best over `repeat` runs of the CPU time (this process) per step of the scene's first `steps`
    steps after one untimed step (the C runtime is loaded there)."""
    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    body = reduce_scene_body(model.body, scene).data
    best = float("inf")
    for _ in range(repeat):
        system, inputs = sim.build_system(body, scene, backend=backend)
        system.step(scene.step, inputs)
        t0 = time.process_time()
        for _ in range(steps):
            system.step(scene.step, inputs)
        best = min(best, (time.process_time() - t0) / steps)
    return best


B1_MODEL = Path(__file__).resolve().parents[1] / "models" / "haug_beam.toml"
B1_SMALL = ["superelements=1", "modes=2", "stiffening=true", "step=0.04"]


def b1_arguments(doc: str) -> argparse.ArgumentParser:
    """A parser described by the script's first docstring line, with `--config KEY=V ...` (B1_SMALL)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--config", nargs="*", default=B1_SMALL)
    return ap


def b1_spinup(config):
    """(scene, body, system, inputs) of B1's spin-up under the overrides `config`: the reduced body from
    the cache, the system on its default backend."""
    model = load_model(B1_MODEL, config)
    scene = model.scene("spinup")
    body = scene_body_data(model.body, scene)
    system, inputs = sim.build_system(body, scene)
    return scene, body, system, inputs
