"""The compiled kernel's disk cache (runtime/compiled.py, issue 10 item 1): a fresh process loads
what an earlier one compiled, also from another copy of the same source (an FMU's resources, a
worker's checkout); processes that start together on an empty cache compile once. Compiled or
loaded is read from numba's dispatcher statistics (cache misses, hits), not from timings."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from ffrf_fmu.runtime import compiled

ROOT = Path(__file__).resolve().parent.parent

# one B1 step on the numba backend in a fresh process importing ffrf_fmu from `root`
STEP = """
import json, sys
sys.path.insert(0, {root!r})
import ffrf_fmu
from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import build_body
model = load_model({model!r}, ["superelements=1", "modes=2"])
sc = model.scene("spinup")
body, _ = build_body(model.body)
system, inputs = sim.build_system(body, sc, backend="numba")
system.step(sc.step, inputs)
c = system._compiled
step = c.module.advance.stats
print(json.dumps({{"package": ffrf_fmu.__file__, "backend": system.backend, "compiled": c.compiled,
                  "hits": sum(step.cache_hits.values()), "misses": sum(step.cache_misses.values())}}))
"""


def _step_in_fresh_process(root: Path) -> dict:
    code = STEP.format(root=str(root), model=str(ROOT / "models" / "haug_beam.toml"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=3600)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_second_process_loads_the_kernel_from_another_copy(tmp_path):
    """The second process imports ffrf_fmu from a copy at another path, as an FMU's unpacked
    resources or a worker's checkout do: the kernel's cache is keyed by content, so it loads."""
    first = _step_in_fresh_process(ROOT)  # compiles on an empty cache, else loads
    assert first["backend"] == "numba"
    copy = tmp_path / "elsewhere"
    shutil.copytree(ROOT / "ffrf_fmu", copy / "ffrf_fmu", ignore=shutil.ignore_patterns("__pycache__"))
    second = _step_in_fresh_process(copy)
    assert Path(second["package"]).resolve().is_relative_to(copy.resolve())
    assert second["backend"] == "numba"
    assert second["compiled"] is False and second["misses"] == 0 and second["hits"] == 1, second


# a function that takes numba about a second to compile, so two processes started together overlap
SLOW = "import numba\n\n@numba.njit(cache=True)\ndef f(x):\n" + "".join(
    f"    x = x * {1 + k * 1e-3!r} + {k}.0 / (x + {k + 1}.0)\n" for k in range(150)) + "    return x\n"

RACE = """
import json, os, sys, time
sys.path.insert(0, {root!r})
from ffrf_fmu.runtime import compiled
m = compiled.import_by_content({src!r}.encode())
open(sys.argv[2], "w").close()
while not os.path.exists(sys.argv[1]):
    time.sleep(0.002)
with compiled.compile_lock(m.__file__):
    m.f(1.0)
print(json.dumps({{"misses": sum(m.f.stats.cache_misses.values()), "hits": sum(m.f.stats.cache_hits.values())}}))
"""


def test_processes_starting_together_compile_once(tmp_path):
    """Two processes on an empty cache call the kernel at the same moment: one compiles under the
    lock, the other waits and loads what it saved (without the lock both compile)."""
    code = RACE.format(root=str(ROOT), src=SLOW)
    env = {**os.environ, "FFRF_FMU_CACHE_DIR": str(tmp_path / "cache")}
    go = tmp_path / "go"
    ready = [tmp_path / f"ready{i}" for i in range(2)]
    procs = [subprocess.Popen([sys.executable, "-c", code, str(go), str(r)], env=env, stdout=subprocess.PIPE, text=True)
             for r in ready]
    deadline = time.monotonic() + 300
    while not all(r.exists() for r in ready):  # both imported numba and the module
        assert time.monotonic() < deadline, "the processes did not start"
        time.sleep(0.01)
    go.touch()
    results = [json.loads(p.communicate(timeout=600)[0].strip().splitlines()[-1]) for p in procs]
    assert sorted(r["misses"] for r in results) == [0, 1], results
    assert sorted(r["hits"] for r in results) == [0, 1], results


def test_kernel_file_is_created_once(tmp_path, monkeypatch):
    """An intact content-keyed file is never rewritten (numba before 0.68 stamped its cache with the
    file's mtime; a rewrite by a second process would have made the first one's entries stale)."""
    monkeypatch.setenv("FFRF_FMU_CACHE_DIR", str(tmp_path))
    src = b"X = 1\n"
    f = compiled._kernel_file(src, "d1")
    before = f.stat()
    time.sleep(0.01)
    assert compiled._kernel_file(src, "d1") == f
    after = f.stat()
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    f.write_bytes(b"damaged")
    assert compiled._kernel_file(src, "d1").read_bytes() == src


def test_stale_kernel_versions_are_pruned_when_a_new_one_is_cached(tmp_path):
    """Caching a kernel version removes the versions unused for STALE_AFTER_DAYS (about 6 MB of machine
    code each), keeps the recent ones, the one being cached, and one whose compile lock another
    process holds (it is compiling or loading it)."""
    import fcntl
    import time

    from ffrf_fmu.runtime import compiled

    kernels = tmp_path / "kernels"
    old = time.time() - (compiled.STALE_AFTER_DAYS + 1) * 86400.0
    for name in ("stale", "recent", "current", "busy", "stamped"):
        (kernels / name).mkdir(parents=True)
        (kernels / name / "code.nbc").write_bytes(b"x")
    (kernels / "stamped" / ".last-used").touch()  # used recently though the directory is old
    with open(kernels / "busy" / ".compile.lock", "ab") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        for name in ("stale", "current", "busy", "stamped"):  # after the files: creating one stamps its directory
            os.utime(kernels / name, (old, old))
        # the lock is per open file description: prune_stale's own open conflicts with it
        removed = compiled.prune_stale(kernels, keep="current")
    assert removed == ["stale"]
    assert sorted(p.name for p in kernels.iterdir()) == ["busy", "current", "recent", "stamped"]
