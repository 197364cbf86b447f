"""A reference that proves itself: before `advise --check` or `chart` judges a run against the
full-order beam, the reference is refined, mesh and step, until the scene's primary metric moves by
less than a tenth of the tolerance (RESOLVED_SHARE).

Each round runs the current reference (n elements, step h) and its two refinements, 2n elements at h
and n elements at h/2, as tasks of the sweep layer (results kept in the store: a refinement that ran
before is read, not repeated). The moves
    mesh: |m(2n, h) - m(n, h)| / |m(n, h)|,   step: |m(n, h/2) - m(n, h)| / |m(n, h)|
(the trajectory's RMS difference over its peak where the scene has no primary metric) say whether the
reference resolves the metric. Where both are below RESOLVED_SHARE x tolerance, the reference is the
finest run of the round (2n, h/2 is not run: the finer of the two refinements by the larger move);
otherwise the direction(s) that moved too much are refined and the next round runs, up to MAX_ROUNDS
rounds, MAX_ELEMENTS elements and a step of MIN_STEP_FRACTION of the first. A reference still moving
then is unresolved: `advise --check` and `chart` report the table and refuse to call a run within or
not within the tolerance.

A scene's [reference] table (elements, step) is the starting point; the verdict is stored in the
result directory (`resolution.json`, keyed by model content, overrides, scene and tolerance), so the
check runs once per scene and tolerance.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

RESOLVED_SHARE = 0.1  # the reference must not move by more than this share of the tolerance
MAX_ROUNDS = 3
MAX_ELEMENTS = 128
MIN_STEP_FRACTION = 1.0 / 8.0
RESOLUTION_FILE = "resolution.json"


@dataclass(frozen=True)
class RefinementRow:
    """One reference run of the refinement: its mesh, step, primary metric, and its move against the
    run it refines (None for the round's base)."""

    n_elements: int
    step: float
    metric: float | None
    refines: str  # "base", "mesh" or "step"
    move: float | None  # relative change against the round's base


@dataclass(frozen=True)
class Resolution:
    """The refinement's verdict: resolved or not, the reference to judge against, the table."""

    resolved: bool
    n_elements: int
    step: float
    metric: float | None
    target: float  # RESOLVED_SHARE x tolerance
    tolerance: float
    rows: tuple[RefinementRow, ...]
    reason: str

    def as_dict(self) -> dict:
        return {**asdict(self), "rows": [asdict(r) for r in self.rows]}

    @staticmethod
    def from_dict(d: dict) -> "Resolution":
        return Resolution(**{**d, "rows": tuple(RefinementRow(**r) for r in d["rows"])})


def _move(fine: dict, base: dict, metric_name: str | None) -> float | None:
    """The relative change of the metric (or of the trajectory, RMS over its peak) from base to fine."""
    from .errors import errors

    if not (fine.get("completed", True) and base.get("completed", True)):
        return None
    err = errors(fine, base, metric_name)
    return err["metric_error_rel"] if metric_name else err["rms_error_rel"]


def _key(model_path, overrides: Sequence[str], scene: str, tolerance: float, n0: int, h0: float) -> str:
    h = hashlib.sha256(Path(model_path).read_bytes())
    h.update(json.dumps([list(overrides), scene, tolerance, n0, h0]).encode())
    return h.hexdigest()[:20]


def stored_resolution(out_dir, key: str) -> Resolution | None:
    path = Path(out_dir) / RESOLUTION_FILE
    if not path.exists():
        return None
    entry = json.loads(path.read_text()).get(key)
    return Resolution.from_dict(entry) if entry else None


def _store(out_dir, key: str, res: Resolution) -> None:
    path = Path(out_dir) / RESOLUTION_FILE
    data = json.loads(path.read_text()) if path.exists() else {}
    data[key] = res.as_dict()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)


def resolve_reference(model_path, scene_name: str | None, tolerance: float, *, overrides: Sequence[str] = (),
                      n_elements: int | None = None, step: float | None = None, out_dir="chart", sweep=None,
                      max_rounds: int | None = None) -> tuple[Resolution, dict]:
    """Refine the scene's reference until its primary metric moves by < RESOLVED_SHARE x tolerance
    (module doc). n_elements, step: the starting reference (default the scene's [reference], else the
    reference's defaults, runners.reference_elements). Returns (Resolution, the reference result to
    judge against: runners.run_reference's dict)."""
    from ..model import load_model
    from .errors import primary_metric
    from .runners import reference_elements
    from .sweep import SweepOptions, sweep_into
    from .task import make_task

    max_rounds = MAX_ROUNDS if max_rounds is None else max_rounds
    model = load_model(model_path, overrides)
    scene = model.scene(scene_name)
    metric_name = primary_metric(scene)
    n = reference_elements(model, scene, n_elements)
    h = float(step or scene.reference.step or scene.step)
    key = _key(model_path, overrides, scene.name, tolerance, n, h)
    target = RESOLVED_SHARE * tolerance
    sweep = sweep or SweepOptions()
    n_min_step = h * MIN_STEP_FRACTION
    rows: list[RefinementRow] = []
    results: dict = {}

    def run(cases):
        tasks = {c: make_task(model_path, overrides, scene.name, "reference", elements=c[0], step=c[1]) for c in cases}
        todo = {c: t for c, t in tasks.items() if c not in results}
        if todo:
            out = sweep_into(out_dir, list(todo.values()), f"reference refinement {model.body.name}/{scene.name}",
                             {t.key: f"reference {c[0]} el., h = {c[1]:g} s" for c, t in todo.items()}, sweep)
            results.update({c: out.results[t.key] for c, t in todo.items()})

    stored = stored_resolution(out_dir, key)
    if stored is not None:
        run([(stored.n_elements, stored.step)])
        return stored, results[(stored.n_elements, stored.step)]

    reason = ""
    best = (n, h)
    for _ in range(max_rounds):
        cases = [(n, h), (2 * n, h), (n, h / 2)]
        run(cases)
        base = results[(n, h)]
        if not base.get("completed", True):
            reason = f"the reference with {n} elements, h = {h:g} s failed: {base.get('failure')}"
            break
        m = lambda c: (results[c].get("metrics") or {}).get(metric_name) if metric_name else None  # noqa: E731
        dn, dh = _move(results[(2 * n, h)], base, metric_name), _move(results[(n, h / 2)], base, metric_name)
        rows += [RefinementRow(n, h, m((n, h)), "base", None), RefinementRow(2 * n, h, m((2 * n, h)), "mesh", dn),
                 RefinementRow(n, h / 2, m((n, h / 2)), "step", dh)]
        if dn is None or dh is None:
            reason = "a refinement of the reference failed"
            break
        if dn < target and dh < target:
            best = (2 * n, h) if dn >= dh else (n, h / 2)
            res = Resolution(True, best[0], best[1], m(best), target, tolerance, tuple(rows),
                             f"mesh {dn:.3%} and step {dh:.3%} moves < {target:.3%} (a tenth of the tolerance)")
            _store(out_dir, key, res)
            return res, results[best]
        best = (2 * n if dn >= target else n, h / 2 if dh >= target else h)
        if best[0] > MAX_ELEMENTS or best[1] < n_min_step * (1 - 1e-9):
            reason = (f"the next refinement ({best[0]} elements, h = {best[1]:g} s) is beyond the limits "
                      f"({MAX_ELEMENTS} elements, h >= {n_min_step:g} s)")
            break
        n, h = best
    else:
        reason = f"still moving after {max_rounds} rounds"
    last = rows[-3] if rows else None
    ref_case = (last.n_elements, last.step) if last else (n, h)
    moves = [r for r in rows[-2:] if r.move is not None]
    res = Resolution(False, ref_case[0], ref_case[1], last.metric if last else None, target, tolerance, tuple(rows),
                     reason + ("; last moves " + ", ".join(f"{r.refines} {r.move:.3%}" for r in moves)
                               + f" against {target:.3%}" if moves else ""))
    _store(out_dir, key, res)
    return res, results.get(ref_case, {})


def format_resolution(res: Resolution) -> str:
    """The refinement table as text."""
    verdict = "resolved" if res.resolved else "NOT resolved"
    lines = [f"reference {verdict} at a tenth of the tolerance ({res.target:.3%}): {res.reason}",
             "  elements  step [s]   metric        refines  move"]
    for r in res.rows:
        metric = "-" if r.metric is None else f"{r.metric:.7g}"
        move = "" if r.move is None else f"{r.move:.4%}"
        lines.append(f"  {r.n_elements:>8}  {r.step:<9g}  {metric:<12}  {r.refines:<7}  {move}")
    if res.resolved:
        lines.append(f"  judged against: {res.n_elements} elements, h = {res.step:g} s")
    return "\n".join(lines)
