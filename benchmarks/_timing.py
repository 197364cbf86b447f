"""CPU time per body step, shared by the cost benchmarks (stiffening_cost.py, term_cost.py)."""
from __future__ import annotations

import time

from ffrf_fmu import simulate as sim
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
