"""Reduced beam bodies cached on disk: a repeated run of the same body skips the FE model, the
reduction and the import of scipy (together most of a short CLI run's process time).

The key is the body as the scene runs it (model.scene_body: every value of the [body] table, with the
scene's causality), the reduction's options, the sources of the code that reduces (reduction.py, fe/,
invariants.py, runtime/data.py) and the numpy and scipy versions: any change reduces afresh. Entries
are BodyData's own .npz (BodyData.save/load), written atomically under <cache>/bodies/ (the cache of
runtime/native/build.py). Only beam bodies: a solid's mesh or export lives in files the key would have
to read whole (a solid is reduced afresh every time).
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
from importlib import metadata
from pathlib import Path

import numpy as np

from .model import Body, scene_body
from .runtime.data import BodyData

HERE = Path(__file__).resolve().parent
REDUCING_CODE = ("reduction.py", "invariants.py", "runtime/data.py", "fe")


def _code_digest() -> bytes:
    h = hashlib.sha256()
    for name in REDUCING_CODE:
        p = HERE / name
        for f in sorted(p.rglob("*.py")) if p.is_dir() else [p]:
            h.update(f.name.encode() + b"\0" + f.read_bytes())
    h.update(np.__version__.encode())
    h.update(_scipy_version())
    return h.digest()


def _scipy_version() -> bytes:
    """The text of scipy's version.py (version and git revision), read without importing scipy:
    importlib.metadata.version parses every installed distribution's METADATA with the email parser
    (about 3 ms of each CLI run's 4 ms body load)."""
    spec = importlib.util.find_spec("scipy")
    origin = spec.origin if spec is not None else None
    if origin is None:
        return b"no scipy"
    version_py = Path(origin).with_name("version.py")
    return version_py.read_bytes() if version_py.is_file() else metadata.version("scipy").encode()


def key(body: Body, options: dict) -> str:
    """The cache key of a body (as its scene runs it) reduced with `options`."""
    h = hashlib.sha256(_code_digest())
    h.update(repr(body).encode())
    h.update(repr(sorted(options.items())).encode())
    return h.hexdigest()[:24]


def scene_body_data(body: Body, scene) -> BodyData:
    """reduction.reduce_scene_body(body, scene).data, from the cache when this body was reduced before."""
    from .reduction import reduction_options
    from .runtime.native.build import cache_root

    if body.solid is not None:
        from .reduction import reduce_scene_body

        return reduce_scene_body(body, scene).data
    run_body, options = scene_body(body, scene), reduction_options(scene)
    path = cache_root() / "bodies" / f"{key(run_body, options)}.npz"
    try:
        return BodyData.load(path)
    except (OSError, ValueError, KeyError):
        pass
    from .reduction import reduce_body

    data = reduce_body(run_body, **options).data
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.npz")
        data.save(tmp)
        os.replace(tmp, path)
    except OSError:  # a read-only cache: the run goes on without it
        pass
    return data
