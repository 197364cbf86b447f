"""The one sweep layer: run a list of tasks (task.Task) on a local process pool or a Dask cluster,
with the result store (store.ResultStore) in between.

    scheduler = parse_scheduler(None | "local:N" | "tcp://host:8786", workers=K)
    with connect(scheduler) as runner:        # SweepError naming the address when it cannot connect
        outcome = run_sweep(tasks, runner, store=ResultStore(DIR), on_result=...)

- default: a local process pool of K workers (K = 1: in this process), started with an explicit
  start method (spawn; forkserver works too): the workers import ffrf_fmu afresh and inherit
  nothing from this process, on every platform and Python version.
- `local:N`: a dask.distributed LocalCluster of N one-thread worker processes on this machine.
- anything else: the address of a running dask.distributed scheduler (`dask scheduler` plus
  `dask worker ADDRESS` on each machine, every one with the same ffrf_fmu installed; docs/scale.md).

What travels is a Task (bytes and texts); workers call task.execute, imported by name. Every
result carries the worker's code version; `run_sweep` refuses a result of another version than
this process's (SweepError), and a Dask cluster is asked for its workers' versions before any
run. A run that fails is a result with its cause. A worker that dies (killed, out of memory)
loses its run: the pool is rebuilt and the runs it had are tried again, up to `retries` more
times; Dask reschedules them itself (its `distributed.scheduler.allowed-failures`, 3 by default)
and reports KilledWorker after that. A run lost on every attempt is stored as a failure with
`lost_worker` set, which a rerun tries again.
"""
from __future__ import annotations

import contextlib
import dataclasses
import logging
import multiprocessing
import os
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterator, Sequence

from .task import Task, code_version, execute

START_METHODS = ("spawn", "forkserver")  # workers that inherit nothing (fork is unsafe with threads)
CONNECT_TIMEOUT_S = 10.0  # how long to try reaching a scheduler address before giving up
RETRIES = 2  # a run whose worker dies is tried this many more times


class SweepError(RuntimeError):
    """The sweep cannot run: no scheduler at the address, workers of another code version, ..."""


@dataclasses.dataclass(frozen=True)
class Scheduler:
    """Where the runs go: kind "pool" (workers processes, start_method), "local" (a LocalCluster
    of `workers`) or "address" (a running dask scheduler)."""

    kind: str = "pool"
    workers: int = 1
    address: str | None = None
    start_method: str = "spawn"

    def describe(self) -> str:
        if self.kind == "pool":
            return f"local process pool, {self.workers} worker(s), {self.start_method}" if self.workers > 1 \
                else "this process"
        if self.kind == "local":
            return f"dask LocalCluster, {self.workers} worker(s)"
        return f"dask scheduler {self.address}"


def parse_scheduler(text: str | None, workers: int | None = None, start_method: str = "spawn") -> Scheduler:
    """--scheduler text (None: the process pool) and --workers -> Scheduler."""
    n = int(workers) if workers else (os.cpu_count() or 1)
    if n < 1:
        raise SweepError(f"--workers {workers}: expected a positive number of workers")
    if start_method not in START_METHODS:
        raise SweepError(f"start method {start_method!r}: expected one of {', '.join(START_METHODS)}")
    if not text:
        return Scheduler("pool", n, None, start_method)
    text = text.strip()
    if text == "local" or text.startswith("local:"):
        count = text.partition(":")[2]
        if count and not (count.isdigit() and int(count) >= 1):
            raise SweepError(f"--scheduler {text}: expected local:N with N a positive number of workers")
        return Scheduler("local", int(count) if count else n, None, start_method)
    return Scheduler("address", n, text, start_method)


# ------------------------------------------------------------------------------ runners
class InProcess:
    """Runs the tasks one after the other in this process (one worker)."""

    description = "this process"

    def run(self, tasks: Sequence[Task], retries: int) -> Iterator[tuple[Task, dict, int, bool]]:
        for t in tasks:
            yield t, execute(t), 1, False


class Pool:
    """A process pool with at most `workers` runs in flight, so that a broken pool (a worker died)
    knows which runs it lost: those are resubmitted to a new pool."""

    def __init__(self, workers: int, start_method: str):
        self.workers, self.start_method = workers, start_method
        self.description = f"local process pool, {workers} workers ({start_method})"

    def run(self, tasks: Sequence[Task], retries: int) -> Iterator[tuple[Task, dict, int, bool]]:
        pending, attempts = deque(tasks), {t.key: 0 for t in tasks}
        ctx = multiprocessing.get_context(self.start_method)
        while pending:
            lost: list[Task] = []
            with ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx) as pool:
                inflight = {}
                while (pending or inflight) and not lost:
                    while pending and len(inflight) < self.workers and not lost:
                        t = pending.popleft()
                        try:
                            fut = pool.submit(execute, t)
                        except BrokenProcessPool:  # died before this run was given to it
                            pending.appendleft(t)
                            break
                        attempts[t.key] += 1
                        inflight[fut] = t
                    if not inflight:
                        break
                    done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                    for f in done:
                        t = inflight.pop(f)
                        try:
                            r = f.result()
                        except BrokenProcessPool:  # a worker died: every run in flight is lost
                            lost.append(t)
                            continue
                        yield t, r, attempts[t.key], False
                lost += list(inflight.values())
                if lost:
                    pool.shutdown(wait=True, cancel_futures=True)
            for t in reversed(lost):
                if attempts[t.key] <= retries:
                    pending.appendleft(t)
                else:
                    yield t, lost_result(t, attempts[t.key]), attempts[t.key], True


class Dask:
    """A dask.distributed Client (to a LocalCluster or a running scheduler)."""

    def __init__(self, client, description: str):
        self.client, self.description = client, description

    def run(self, tasks: Sequence[Task], retries: int) -> Iterator[tuple[Task, dict, int, bool]]:
        from distributed import as_completed

        futures = {self.client.submit(execute, t, key=f"ffrf-run-{t.key}", pure=False): t for t in tasks}
        for f in as_completed(futures):
            t = futures[f]
            try:
                yield t, f.result(), 1, False
            except Exception as e:  # noqa: BLE001 - KilledWorker: the scheduler gave up on it
                if type(e).__name__ != "KilledWorker":
                    raise
                yield t, lost_result(t, None, str(e)), 0, True


def lost_result(t: Task, attempts: int | None, detail: str = "") -> dict:
    tried = f" on all {attempts} attempts" if attempts else ""
    return {"completed": False, "failure": f"worker process lost{tried} (killed or crashed, e.g. out of memory)"
            + (f": {detail}" if detail else ""), "key": t.key, "code_version": code_version()}


@contextlib.contextmanager
def connect(scheduler: Scheduler, timeout: float = CONNECT_TIMEOUT_S):
    """The runner for a Scheduler (a context: a cluster or pool is closed after). Connecting comes
    first and fails with SweepError naming the address, before the caller writes anything."""
    if scheduler.kind == "pool":
        yield InProcess() if scheduler.workers == 1 else Pool(scheduler.workers, scheduler.start_method)
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError as e:
        raise SweepError(f"--scheduler needs dask.distributed, which is not installed ({e}): "
                         "pip install -e \".[cluster]\"") from None
    if scheduler.kind == "local":
        # silence_logs: the workers' heartbeat errors while the cluster closes are noise (a run's own
        # failure travels in its result)
        with LocalCluster(n_workers=scheduler.workers, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
            yield Dask(client, scheduler.describe())
        return
    try:
        client = Client(scheduler.address, timeout=timeout)
    except (OSError, TimeoutError, ValueError) as e:
        raise SweepError(f"--scheduler {scheduler.address}: cannot reach a dask scheduler there within "
                         f"{timeout:g} s ({type(e).__name__}: {e})") from None
    try:
        versions = client.run(code_version)
        mine = code_version()
        other = {w: v for w, v in versions.items() if v != mine}
        if other:
            raise SweepError(f"--scheduler {scheduler.address}: workers run another ffrf_fmu than this one ({mine}): "
                             + ", ".join(f"{w}: {v}" for w, v in other.items()))
        if not versions:
            raise SweepError(f"--scheduler {scheduler.address}: the scheduler has no workers")
        yield Dask(client, f"{scheduler.describe()} ({len(versions)} workers)")
    finally:
        client.close()


# ------------------------------------------------------------------------------ the sweep
@dataclasses.dataclass
class Outcome:
    """results: {task key: result}; stored: runs taken from the store (their keys: from_store);
    ran: runs done now; retried: runs tried more than once; lost: runs lost with their worker on
    every attempt; where: the runner's description."""

    results: dict
    stored: int = 0
    ran: int = 0
    retried: int = 0
    lost: int = 0
    from_store: set = dataclasses.field(default_factory=set)
    where: str = ""


def run_sweep(tasks: Sequence[Task], runner, *, store=None, on_result: Callable | None = None,
              retries: int = RETRIES) -> Outcome:
    """Run every task not finished in `store` on `runner`; store each result as it arrives.

    on_result(task, result, from_store) is called once per task (stored ones first). Tasks with the
    same key run once. Raises SweepError for a result of another code version (nothing of it is
    stored) and store.StoreVersionError when the store holds another version."""
    version = code_version()
    unique = list({t.key: t for t in tasks}.values())
    out = Outcome({})
    if store is not None:
        store.check_version(version)
        for t in unique:
            if store.finished(t.key):
                out.results[t.key] = store.result(t.key)
                out.stored += 1
                out.from_store.add(t.key)
                if on_result:
                    on_result(t, out.results[t.key], True)
    todo = [t for t in unique if t.key not in out.results]
    for t, r, attempts, lost in runner.run(todo, retries):
        if r.get("code_version") != version:
            raise SweepError(f"a worker ({runner.description}) returned a result of ffrf_fmu {r.get('code_version')}, "
                             f"this sweep runs {version} (the code changed during the sweep, or the workers have "
                             "another install): not mixing them")
        r["attempts"] = attempts
        if store is not None:
            store.add(t, r, attempts=attempts, lost_worker=lost)
        out.results[t.key] = r
        out.ran += 1
        out.retried += attempts > 1
        out.lost += lost
        if on_result:
            on_result(t, r, False)
    return out


# ------------------------------------------------------------------------------ a sweep into a directory
@dataclasses.dataclass(frozen=True)
class SweepOptions:
    """Where a study's runs go and how it reports: scheduler (default: this process), fresh
    (discard the stored results first), progress (the bar on a terminal), log (one line per run
    done now, e.g. print)."""

    scheduler: Scheduler = Scheduler()
    fresh: bool = False
    progress: bool = True
    log: Callable[[str], None] | None = None


def sweep_into(out_dir, tasks: Sequence[Task], name: str, notes: dict[str, str], options: SweepOptions) -> Outcome:
    """The one way a study runs its tasks: connect to the scheduler (an unreachable one fails
    here, before out_dir is written), keep the results in out_dir's store (store.py: finished runs
    are taken from it), show the progress bar. notes: a short text per task key for the bar and
    the log."""
    from pathlib import Path

    from .progress import Bar
    from .store import ResultStore

    out_dir = Path(out_dir)
    bar = Bar(len({t.key for t in tasks}), name) if options.progress else None
    done = 0

    def on_result(t, result, from_store) -> None:
        nonlocal done
        done += 1
        note = notes.get(t.key, t.runner)
        if bar:
            bar.update(done, note + (" (stored)" if from_store else ""))
        if options.log and not from_store:
            status = "" if result.get("completed") else f": {result.get('failure')}"
            options.log(f"{note}{status} ({result.get('wall_time_s') or 0.0:.0f} s)")

    with connect(options.scheduler) as runner:
        out_dir.mkdir(parents=True, exist_ok=True)
        store = ResultStore(out_dir)
        if options.fresh:
            store.discard()
        outcome = run_sweep(list(tasks), runner, store=store, on_result=on_result)
        outcome.where = runner.description
    if bar:
        bar.close()
    return outcome

