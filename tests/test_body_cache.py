"""body_cache.py: a cached reduced body is the body the reduction gives (every array bit for bit, the
ports, the damping), a damaged file is refused rather than read, and the cached path imports neither
scipy nor the reduction."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ffrf_fmu import body_cache
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_scene_body

ROOT = Path(__file__).resolve().parents[1]
B1 = ["superelements=2", "modes=2", "stiffening=true", "step=0.04"]


def same_body(a, b) -> None:
    arrays_a, meta_a = a.arrays()
    arrays_b, meta_b = b.arrays()
    assert meta_a == meta_b
    assert arrays_a.keys() == arrays_b.keys()
    for k in arrays_a:
        assert arrays_a[k].dtype == arrays_b[k].dtype and np.array_equal(arrays_a[k], arrays_b[k]), k


@pytest.fixture(scope="module")
def b1():
    model = load_model(ROOT / "models" / "haug_beam.toml", B1)
    scene = model.scene("spinup")
    return model, scene, reduce_scene_body(model.body, scene).data


def test_write_read_is_the_body(b1, tmp_path):
    _, _, data = b1
    assert data.superelements[0].vk_a is not None  # the stiffening's optional arrays go through too
    path = tmp_path / "b.body"
    body_cache.write(data, path)
    back = body_cache.read(path)
    same_body(back, data)
    back.superelements[0].K[0, 0] += 1.0  # writable, as np.load's arrays are; the file is not changed
    same_body(body_cache.read(path), data)


def test_a_damaged_file_is_refused(b1, tmp_path):
    _, _, data = b1
    path = tmp_path / "b.body"
    body_cache.write(data, path)
    raw = path.read_bytes()
    path.write_bytes(raw[:-8])
    with pytest.raises(ValueError, match="cut short"):
        body_cache.read(path)
    path.write_bytes(b"PK" + raw[2:])
    with pytest.raises(ValueError, match="not a cached body"):
        body_cache.read(path)


def test_scene_body_data_caches_the_reduction(b1, tmp_path, monkeypatch):
    model, scene, data = b1
    monkeypatch.setenv("FFRF_FMU_CACHE_DIR", str(tmp_path))
    first = body_cache.scene_body_data(model.body, scene)  # reduced and written
    files = list((tmp_path / "bodies").glob("*.body"))
    assert len(files) == 1
    same_body(first, data)
    same_body(body_cache.scene_body_data(model.body, scene), data)  # read back
    files[0].write_bytes(b"garbage")  # a damaged entry is reduced afresh and rewritten
    same_body(body_cache.scene_body_data(model.body, scene), data)
    same_body(body_cache.read(files[0]), data)


def test_cached_path_imports_neither_scipy_nor_the_reduction(b1, tmp_path):
    model, scene, _ = b1
    env = dict(os.environ, FFRF_FMU_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    script = ("import sys\nfrom ffrf_fmu.model import load_model\nfrom ffrf_fmu.body_cache import scene_body_data\n"
              f"m = load_model({str(ROOT / 'models' / 'haug_beam.toml')!r}, {B1!r})\n"
              "scene_body_data(m.body, m.scene('spinup'))\n"
              "print(sorted(k for k in ('scipy', 'ffrf_fmu.reduction') if k in sys.modules))\n")
    runs = [subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
            for _ in range(2)]
    assert runs[1].stdout.strip() == "[]", runs[1].stdout + runs[1].stderr
    assert "ffrf_fmu.reduction" in runs[0].stdout  # the first run reduced: the check can see an import


def same_layout(a, b) -> None:
    arrays_a, arrays_b = a.arrays(), b.arrays()
    assert arrays_a.keys() == arrays_b.keys()
    for k in arrays_a:
        assert arrays_a[k].dtype == arrays_b[k].dtype and np.array_equal(arrays_a[k], arrays_b[k]), k


@pytest.mark.parametrize("model, sets", [("haug_beam.toml", B1), ("free_beam.toml", ["superelements=3"]),
                                         ("jeffcott_rotor.toml", [])])
def test_the_remembered_layout_is_the_computed_one(model, sets, tmp_path):
    """The layout and Newton maps read with a cached body (runtime/layout.py Layout.remember) are those
    Layout.compute gives, array by array and dtype; a BodySystem of the body read back takes them
    (read-only: they are shared), one of another BodyData computes its own."""
    from ffrf_fmu.runtime.body import BodySystem
    from ffrf_fmu.runtime.layout import Layout

    m = load_model(ROOT / "models" / model, sets)
    data = reduce_scene_body(m.body, m.scene()).data
    path = tmp_path / "b.body"
    body_cache.write(data, path)
    back = body_cache.read(path)
    remembered = Layout.of(back)
    assert remembered is Layout.of(back) and Layout.of(data) is not Layout.of(data)
    same_layout(remembered, Layout.compute(data))
    same_layout(remembered, Layout.compute(back))
    assert all(getattr(remembered, k) == getattr(Layout.compute(data), k) for k in Layout._DIMS)
    s = BodySystem(back, backend="numpy")
    assert s.layout is remembered and not s._newton_flat.flags.writeable
    other = BodySystem(data, backend="numpy")
    for k in ("_newton_idx", "_newton_flat", "_field_perm", "_stage_mask", "_motion_x", "_world_free", "_motion_parts",
              "_port_nodes"):
        assert np.array_equal(getattr(s, k), getattr(other, k)) and getattr(s, k).dtype == getattr(other, k).dtype, k
    assert [(k, p.tolist()) for k, p in s._torque_rows] == [(k, p.tolist()) for k, p in other._torque_rows]
    assert all(np.array_equal(a, b) for a, b in zip(s._port_codes, other._port_codes))
