"""Reduced beam bodies cached on disk: a repeated run of the same body skips the FE model, the
reduction and the import of scipy (together most of a short CLI run's process time).

The key is the body as the scene runs it (model.scene_body: every value of the [body] table, with the
scene's causality), the reduction's options, the sources of the code that reduces (reduction.py, fe/,
invariants.py, runtime/data.py) and the numpy and scipy versions: any change reduces afresh. The
sources' digest is remembered under their stat signature (runtime/native/build.py remembered_digest).
Entries are BodyData's arrays and its layout (runtime/layout.py: the Newton index maps a BodySystem of it
takes, `Layout.remember`) in one raw file (`write`, `read`: a JSON index, then the values, read with one
system call and no zip or .npy header to parse), written atomically under <cache>/bodies/ (the
cache of runtime/native/build.py); the cached path imports neither scipy nor the reduction. Only beam
bodies: a solid's mesh or export lives in files the key would have to read whole (a solid is reduced
afresh every time).
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import os
import struct
from pathlib import Path

import numpy as np

from .model import Body, reduction_options, scene_body
from .runtime.data import BodyData
from .runtime.layout import Layout
from .runtime.native.build import cache_root, remembered_digest

HERE = Path(__file__).resolve().parent
HERE_STR = str(HERE)
# the code of what a file holds: the reduction, and the layout and Newton maps stored beside it (runtime/layout.py)
REDUCING_CODE = ("reduction.py", "invariants.py", "runtime/data.py", "runtime/layout.py", "fe")


def _code_files() -> list[str]:
    """The files of REDUCING_CODE (a folder's .py files at any depth, as os.walk finds them: symbolic links
    to folders not followed), in a fixed order. (os.scandir: os.walk's generator costs five times more.)"""
    out = []
    for name in REDUCING_CODE:
        p = os.path.join(HERE_STR, name)
        if os.path.isdir(p):
            folders, found = [p], []
            while folders:
                with os.scandir(folders.pop()) as entries:
                    for e in entries:
                        if e.is_dir():
                            if not e.is_symlink():
                                folders.append(e.path)
                        elif e.name.endswith(".py"):
                            found.append(e.path)
            out += sorted(found)
        else:
            out.append(p)
    return out


def _code_digest() -> bytes:
    return remembered_digest(_code_files(), (np.__version__, _scipy_version().decode(errors="replace"))).encode()


def _scipy_version() -> bytes:
    """The text of scipy's version.py (version and git revision), read without importing scipy:
    importlib.metadata.version parses every installed distribution's METADATA with the email parser
    (about 3 ms of each CLI run's 4 ms body load)."""
    spec = importlib.util.find_spec("scipy")
    origin = spec.origin if spec is not None else None
    if origin is None:
        return b"no scipy"
    try:  # (os, not pathlib: a Path's first calls cost more than the read)
        with open(os.path.join(os.path.dirname(origin), "version.py"), "rb") as fh:
            return fh.read()
    except OSError:
        pass
    from importlib import metadata  # (here: its import pulls in the email package, 3-5 ms of every run)

    return metadata.version("scipy").encode()


def key(body: Body, options: dict) -> str:
    """The cache key of a body (as its scene runs it) reduced with `options`."""
    h = hashlib.sha256(_code_digest())
    h.update(repr(body).encode())
    h.update(repr(sorted(options.items())).encode())
    return h.hexdigest()[:24]


MAGIC = b"FFRF-BODY-CACHE2"  # 16 bytes (the last the format version), then u64 index bytes, the JSON index, the values (8-aligned)
HEAD = struct.Struct("<16sQ")


def write(data: BodyData, path: Path) -> None:
    """BodyData's arrays (BodyData.arrays) and its layout (runtime/layout.py Layout.packed: the index maps a
    BodySystem of it would compute; the array "layout", its spec in the meta) in one file: MAGIC, the JSON
    index {"meta", "arrays": [name, dtype, shape, offset]}, then each array's bytes (C order) at its offset."""
    arrays, meta = data.arrays()
    meta["layout"], arrays["layout"] = Layout.compute(data).packed()
    index, blobs, offset = [], [], 0
    for name, value in arrays.items():
        a = np.ascontiguousarray(value)
        if a.dtype.kind not in "fiub":
            raise ValueError(f"body cache: array {name!r} of dtype {a.dtype} is not numeric")
        index.append([name, a.dtype.str, list(a.shape), offset])
        blobs.append(a.tobytes())
        offset += -(-len(blobs[-1]) // 8) * 8
        blobs[-1] += b"\0" * (-len(blobs[-1]) % 8)
    text = json.dumps({"meta": meta, "arrays": index}).encode()
    text += b" " * (-(HEAD.size + len(text)) % 8)
    with open(path, "wb") as fh:
        fh.write(HEAD.pack(MAGIC, len(text)) + text + b"".join(blobs))


def read(path: Path) -> BodyData:
    """The BodyData of a file `write` wrote, its layout remembered (Layout.of gives it, not computed
    afresh); ValueError when it is not one (or is cut short), KeyError when a part is missing."""
    with open(path, "rb") as fh:
        raw = bytearray(fh.read())  # writable: the arrays are views of it, as np.load's are their own
    if len(raw) < HEAD.size:
        raise ValueError(f"{path}: not a cached body")
    magic, n = HEAD.unpack_from(raw)
    if magic != MAGIC or len(raw) < HEAD.size + n:
        raise ValueError(f"{path}: not a cached body of this version")
    index = json.loads(bytes(raw[HEAD.size: HEAD.size + n]))
    base, size, arrays, dtypes = HEAD.size + n, len(raw), {}, {}
    for name, dtype, shape, offset in index["arrays"]:
        dt = dtypes.get(dtype)
        if dt is None:
            dt = dtypes[dtype] = np.dtype(dtype)
        count, start = math.prod(shape), base + offset
        if start + count * dt.itemsize > size:
            raise ValueError(f"{path}: cut short (array {name!r})")
        arrays[name] = np.frombuffer(raw, dt, count, start).reshape(shape)
    meta = index["meta"]
    layout = Layout.unpacked(meta.pop("layout"), arrays.pop("layout"))
    data = BodyData.from_arrays(arrays, meta)
    layout.remember(data)
    return data


def scene_body_data(body: Body, scene) -> BodyData:
    """reduction.reduce_scene_body(body, scene).data, from the cache when this body was reduced before."""
    if body.solid is not None:
        from .reduction import reduce_scene_body

        return reduce_scene_body(body, scene).data
    run_body, options = scene_body(body, scene), reduction_options(scene)
    path = cache_root() / "bodies" / f"{key(run_body, options)}.body"
    try:
        return read(path)
    except (OSError, ValueError, KeyError):
        pass
    from .reduction import reduce_body

    data = reduce_body(run_body, **options).data
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.body")
        write(data, tmp)
        os.replace(tmp, path)
    except OSError:  # a read-only cache: the run goes on without it
        pass
    return data
