"""The result store of a sweep: a directory with one JSON line per finished run, keyed by the
content that defines the run (task.Task.key), and the run's arrays beside it.

    DIR/runs.jsonl          {"key", "code_version", "task", "result", "arrays", "attempts", "lost_worker"}
    DIR/arrays/<key>.npz    the result's numpy arrays (time grids, trajectories), when it has any

A line is appended (one write, then fsync) only after its arrays are in place (written to a
temporary name, then renamed), so a sweep killed at any moment leaves finished runs readable and
at most a torn last line, which reading skips. Failed runs are lines too, with their cause:
rerunning a sweep does not repeat them, except runs whose worker was lost (killed, out of
memory) on every attempt (`lost_worker`), which a rerun tries again. When a key is there twice
the later line wins.

One store holds one code version (task.code_version): `check_version` refuses to add results of
another version to a store that holds some, naming both.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Iterable

import numpy as np

RUNS = "runs.jsonl"
ARRAYS = "arrays"


class StoreVersionError(RuntimeError):
    """The store holds results of another code version than the running sweep's."""


def _json_safe(v: Any):
    if isinstance(v, dict):
        return {str(k): _json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_json_safe(x) for x in v]
    if isinstance(v, np.generic):
        return v.item()
    return v


def split_arrays(result: dict) -> tuple[dict, dict[str, np.ndarray]]:
    """(the result without its top-level numpy arrays, those arrays)."""
    arrays = {k: v for k, v in result.items() if isinstance(v, np.ndarray)}
    return {k: v for k, v in result.items() if k not in arrays}, arrays


class ResultStore:
    """Finished runs of DIR, read once at construction and appended to as runs finish."""

    def __init__(self, directory):
        self.dir = Path(directory)
        self.path = self.dir / RUNS
        self.torn_lines = 0
        self._entries: dict[str, dict] = {}
        if self.path.exists():
            with open(self.path, encoding="utf-8") as fh:
                for line in fh:
                    try:
                        entry = json.loads(line)
                        self._entries[entry["key"]] = entry
                    except (json.JSONDecodeError, KeyError, TypeError):  # a write cut by a kill
                        self.torn_lines += 1

    # -------------------------------------------------------------------------- reading
    def __contains__(self, key: str) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def finished(self, key: str) -> bool:
        """A run the sweep need not repeat: stored, and not lost with its worker."""
        e = self._entries.get(key)
        return e is not None and not e.get("lost_worker")

    def versions(self) -> set[str]:
        return {e.get("code_version") for e in self._entries.values()}

    def entry(self, key: str) -> dict:
        return self._entries[key]

    def result(self, key: str) -> dict:
        """The stored result with its arrays loaded."""
        e = self._entries[key]
        out = dict(e["result"])
        if e.get("arrays"):
            with np.load(self.dir / e["arrays"], allow_pickle=False) as z:
                out |= {k: z[k] for k in z.files}
        return out

    def entries(self) -> Iterable[dict]:
        return self._entries.values()

    # -------------------------------------------------------------------------- writing
    def check_version(self, version: str) -> None:
        """Raise StoreVersionError when the store holds results of another code version."""
        other = sorted(v for v in self.versions() if v != version)
        if other:
            raise StoreVersionError(
                f"{self.path} holds {len(self)} results of code version {', '.join(map(str, other))}; this is "
                f"{version}: a sweep does not mix versions (rerun with --fresh to discard them, or use another "
                "output directory)")

    def discard(self) -> None:
        """Forget every stored run (--fresh): the JSON lines and the arrays go."""
        if self.path.exists():
            self.path.unlink()
        for f in (self.dir / ARRAYS).glob("*.npz") if (self.dir / ARRAYS).is_dir() else ():
            f.unlink()
        self._entries.clear()

    def add(self, task, result: dict, attempts: int = 1, lost_worker: bool = False) -> dict:
        """Store one finished run (arrays first, then its line); returns the entry."""
        self.dir.mkdir(parents=True, exist_ok=True)
        scalars, arrays = split_arrays(result)
        rel = None
        if arrays:
            (self.dir / ARRAYS).mkdir(exist_ok=True)
            rel = f"{ARRAYS}/{task.key}.npz"
            tmp = self.dir / ARRAYS / f"{task.key}.tmp.npz"
            np.savez(tmp, **arrays)
            os.replace(tmp, self.dir / rel)
        entry = {"key": task.key, "code_version": result.get("code_version"), "task": task.describe(),
                 "result": _json_safe(scalars), "arrays": rel, "attempts": attempts, "lost_worker": lost_worker}
        line = (json.dumps(entry, default=float) + "\n").encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line)
            os.fsync(fd)
        finally:
            os.close(fd)
        self._entries[task.key] = entry
        return entry
