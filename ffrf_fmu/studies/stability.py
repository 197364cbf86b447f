"""Stability and accuracy maps: where the models, the integrator and the co-simulation fail.

    ffrf-fmu stability MODEL --scene NAME --map spin|integrator|cosim [-o DIR]

writes DIR/map.csv (one row per run) and DIR/map.png. docs/stability.md shows the maps that ship
with the project and explains every boundary.

Definitions used by every map
-----------------------------
unstable  the run did not reach its end time in a meaningful state: the body integrator raised
          StepFailure (Newton did not converge, a non-finite value), or, for the beam maps, the
          transverse elastic tip deflection (eq. 92) exceeded the beam length L (a body that
          bends by more than its own length has left every model's range: it is diverging), or,
          for the integrator map, the integrator created energy (see `ENERGY_GROWTH`).
error     the relative error of the quantity of interest against the reference of the map
          (nonlinear full-order beam, converged small-step run, monolithic run); defined per map.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..model import Model, Scene, effective_ports, load_model
from ..reference.solver import ENERGY_ERROR_SUSPECT
from ..runtime.ports import StepFailure

# ------------------------------------------------------------------------------------ common


def _body_for(model: Model, scene: Scene):
    from ..reduction import build_body, reduction_options

    return build_body(dataclasses.replace(model.body, ports=effective_ports(model, scene)), **reduction_options(scene))[0]


def _transverse(d: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Norm of the part of d (..., 3) normal to the unit beam axis."""
    axial = d @ axis
    return np.linalg.norm(d - axial[..., None] * axis, axis=-1)


@dataclass
class BeamRun:
    """A standalone beam run reduced to what the maps need."""

    t: np.ndarray
    deflection: np.ndarray  # transverse elastic tip deflection (eq. 92) [m]
    completed: bool
    unstable: bool
    failure: str
    wall_time_s: float
    energy_gap: np.ndarray | None = None  # E(t) - E(0) - W_ext(t) [J]
    energy_level: float = 0.0  # max of the total energy and of |W_ext| [J]
    signal: np.ndarray | None = None  # a second quantity of interest (per map)

    @property
    def max_deflection(self) -> float:
        return float(np.max(self.deflection)) if len(self.deflection) else float("nan")


def run_beam(model: Model, scene: Scene, *, stop_deflection: float | None = None, record_every: int = 1,
             signal: Callable | None = None) -> BeamRun:
    """Step the standalone body through `scene` (simulate.build_system), recording the transverse
    elastic tip deflection of eq. (92) between the first and the last boundary node, the energy
    gap, and optionally `signal(system)`. Stops at a StepFailure, a non-finite value or when the
    deflection exceeds `stop_deflection` (default: the beam length): those runs are unstable."""
    from ..simulate import build_system, end_ports

    start = time.perf_counter()
    body = _body_for(model, scene)
    system, inputs = build_system(body, scene, model.body.origin)
    hub, tip = end_ports(body)
    n_hub, n_tip = body.port(hub).node, body.port(tip).node
    X = body.node_positions[n_tip] - body.node_positions[n_hub]
    axis = X / np.linalg.norm(X)
    limit = model.body.length if stop_deflection is None else stop_deflection
    n_steps = int(round(scene.duration / scene.step))

    def sample():
        o = system.outputs()
        d = o[hub].R.T @ (o[tip].r - o[hub].r) - X
        e = system.energies()
        tot = e["kinetic_rigid"] + e["kinetic_elastic"] + e["strain"]
        return float(_transverse(d, axis)), tot, e["work_external"]

    ts, ds, tots, works, sig = [], [], [], [], []

    def keep(s):
        ts.append(system.t)
        ds.append(s[0])
        tots.append(s[1])
        works.append(s[2])
        if signal is not None:
            sig.append(signal(system))

    keep(sample())
    failure, unstable = "", False
    for k in range(1, n_steps + 1):
        try:
            system.step(scene.step, inputs)
        except StepFailure as exc:
            failure, unstable = f"StepFailure: {exc}", True
            break
        s = sample()
        if not all(math.isfinite(x) for x in s):
            failure, unstable = f"non-finite state at t = {system.t:.4g} s", True
            break
        if s[0] > limit:
            keep(s)
            failure, unstable = f"tip deflection {s[0]:.3g} m > {limit:g} m at t = {system.t:.4g} s", True
            break
        if k % record_every == 0 or k == n_steps:
            keep(s)
    tot, work = np.array(tots), np.array(works)
    return BeamRun(
        t=np.array(ts), deflection=np.array(ds), completed=not unstable, unstable=unstable, failure=failure,
        wall_time_s=time.perf_counter() - start, energy_gap=tot - tot[0] - work,
        energy_level=float(max(np.max(np.abs(tot)), np.max(np.abs(work)))),
        signal=np.array(sig) if signal is not None else None,
    )


def write_csv(path, rows: Sequence[dict]) -> None:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def read_csv(path) -> list[dict]:
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            row = {}
            for k, v in r.items():
                try:
                    row[k] = float(v) if v not in ("True", "False") else v == "True"
                except ValueError:
                    row[k] = v
            out.append(row)
    return out


# ------------------------------------------------------------------------------------ 1. spin map

SPIN_RATES = (1.0, 2.0, 2.5, 3.0, 3.5, 4.0, 6.0, 8.0, 10.0, 12.0)
SPIN_MODELS = tuple((n, terms) for terms in ("linear", "gyroscopic") for n in (1, 2, 4))


def spin_scene(model_path, scene: str, omega: float, *, T: float, duration: float, n_se: int | None = None,
               terms: str | None = None, step: float | None = None, extra: Sequence[str] = ()) -> tuple[Model, Scene]:
    """The B1/B3 scene with final spin `omega`, spin-up time T and the run's duration."""
    ov = [f"scenes.{scene}.drives.hub.rotation.angle.omega={omega!r}",
          f"scenes.{scene}.drives.hub.rotation.angle.T={T!r}", f"scenes.{scene}.duration={duration!r}"]
    if n_se is not None:
        ov.append(f"superelements={n_se}")
    if terms is not None:
        ov.append(f"scenes.{scene}.terms={terms}")
    if step is not None:
        ov.append(f"scenes.{scene}.step={step!r}")
    model = load_model(model_path, [*ov, *extra])
    return model, model.scene(scene)


def reference_step(omega: float) -> float:
    """Step of the nonlinear reference: its Lie-group generalized-alpha needs spin x step below
    ~0.12 rad (reference/__init__.py); we keep it at 0.05 rad and at most 10 ms."""
    return min(0.01, 0.05 / omega)


def reference_deflection(model: Model, scene: Scene, n_elements: int = 16) -> tuple[np.ndarray, np.ndarray, float]:
    """(t, transverse elastic tip deflection, energy error) of the full-order nonlinear beam
    (Simo-Reissner). The energy error is the reference solver's (info["energy_error"]); above
    ENERGY_ERROR_SUSPECT the solver warns and the map marks the rows compared against it."""
    from ..reference import simulate_reference, tip_from_hub

    omega = max(abs(dict(d.rotation.angle.params).get("omega", 0.0)) for d in scene.drives if d.rotation)
    ref = simulate_reference(model.body, scene, n_elements=n_elements, step=reference_step(omega))
    d = tip_from_hub(ref, "hub", "tip")
    axis = np.asarray(model.body.direction, float)
    return ref.t, _transverse(d, axis / np.linalg.norm(axis)), float(ref.info["energy_error"])


@dataclass
class SpinSettings:
    """The spin sweep. T and duration default to half of B1's (15 s, 20 s): the same profile in
    half the time (docs/stability.md shows the conclusions do not change)."""

    omegas: tuple[float, ...] = SPIN_RATES
    models: tuple[tuple[int, str], ...] = SPIN_MODELS
    T: float = 7.5
    duration: float = 10.0
    reference_elements: int = 16
    overrides: tuple[str, ...] = ()  # --set values for every run


def _done(rows: list[dict], **key) -> dict | None:
    for r in rows:
        if all(r.get(k) == v or (isinstance(v, float) and isinstance(r.get(k), float) and abs(r[k] - v) < 1e-12)
               for k, v in key.items()):
            return r
    return None


def spin_map(model_path, scene: str, settings: SpinSettings, out_dir, *, log=print) -> list[dict]:
    """Sweep the final spin rate against (superelements, term set); one CSV row per run:
    max transverse tip deflection of the model and of the nonlinear reference, the relative
    error, and `unstable` (StepFailure or deflection > L). Resumable: rows already in
    out_dir/map.csv are kept and not run again."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "map.csv"
    rows = read_csv(path) if path.exists() else []
    series = dict(np.load(out_dir / "series.npz")) if (out_dir / "series.npz").exists() else {}
    for omega in settings.omegas:
        ref = _done(rows, omega=float(omega), model="reference")
        if ref is None:
            model, sc = spin_scene(model_path, scene, omega, T=settings.T, duration=settings.duration,
                                   extra=settings.overrides)
            t0 = time.perf_counter()
            t, d, energy_error = reference_deflection(model, sc, settings.reference_elements)
            ref = {"omega": float(omega), "model": "reference", "superelements": 0, "terms": "nonlinear",
                   "max_deflection": float(np.max(d)), "ref_max_deflection": float(np.max(d)), "rel_error": 0.0,
                   "unstable": bool(np.max(d) > model.body.length), "failure": "", "t_end": float(t[-1]),
                   "T": settings.T, "duration": settings.duration, "step": reference_step(omega),
                   "wall_time_s": time.perf_counter() - t0, "ref_energy_error": energy_error,
                   "reference_suspect": energy_error > ENERGY_ERROR_SUSPECT}
            rows.append(ref)
            series[f"reference_w{omega:g}"] = np.column_stack([t, d])[:: max(1, int(round(0.02 / reference_step(omega))))]
            write_csv(path, rows)
            np.savez_compressed(out_dir / "series.npz", **series)
            log(f"omega {omega:g}: reference max deflection {ref['max_deflection']:.4f} m ({ref['wall_time_s']:.0f} s)"
                + (f", SUSPECT: energy error {100 * energy_error:.2g} %" if ref["reference_suspect"] else ""))
        for n_se, terms in settings.models:
            name = f"{n_se}SE-{terms}"
            if _done(rows, omega=float(omega), model=name) is not None:
                continue
            model, sc = spin_scene(model_path, scene, omega, T=settings.T, duration=settings.duration,
                                   n_se=n_se, terms=terms, extra=settings.overrides)
            run = run_beam(model, sc, record_every=10)
            err = (run.max_deflection - ref["max_deflection"]) / ref["max_deflection"]
            rows.append({"omega": float(omega), "model": name, "superelements": n_se, "terms": terms,
                         "max_deflection": run.max_deflection, "ref_max_deflection": ref["max_deflection"],
                         "rel_error": float(err), "unstable": run.unstable, "failure": run.failure,
                         "t_end": float(run.t[-1]), "T": settings.T, "duration": settings.duration,
                         "step": sc.step, "wall_time_s": run.wall_time_s,
                         "ref_energy_error": ref.get("ref_energy_error"), "reference_suspect": ref.get("reference_suspect")})
            series[f"{name}_w{omega:g}"] = np.column_stack([run.t, run.deflection])
            write_csv(path, rows)
            np.savez_compressed(out_dir / "series.npz", **series)
            log(f"omega {omega:g}: {name} max deflection {run.max_deflection:.4f} m, error {err:+.2%}"
                f"{', UNSTABLE: ' + run.failure if run.unstable else ''} ({run.wall_time_s:.0f} s)"
                + (" [reference suspect]" if ref.get("reference_suspect") else ""))
    return rows


# ------------------------------------------------------------------------------------ 3. co-simulation map
#
# Two coupled systems (docs/stability.md):
#  motor: the beam FMU (scene hub_free: hub rotation force-driven, translation motion-driven)
#         joined at its hub port to the hub drive FMU (ffrf_fmu.examples: hub inertia, motor, PI speed
#         controller on the Wu-Haug profile, torsional shaft to the beam root);
#  split: the beam cut at its middle boundary node into two body FMUs, A (hub motion-driven by the
#         Wu-Haug law, cut force-driven) and B (cut motion-driven, tip free).

COSIM_STEPS = (0.0005, 0.001, 0.002, 0.004, 0.01, 0.02, 0.04)
#: (label, master scheme, extrapolation, order key): order "fwd" = the FMU that owns the force-driven
#: side first (beam before drive, A before B), "rev" = the other one first.
COSIM_SCHEMES = (
    ("jacobi", "jacobi", False, "fwd"),
    ("jacobi+extrapolation", "jacobi", True, "fwd"),
    ("gauss-seidel", "gauss-seidel", False, "fwd"),
    ("gauss-seidel+extrapolation", "gauss-seidel", True, "fwd"),
    ("gauss-seidel reversed", "gauss-seidel", False, "rev"),
    ("gauss-seidel reversed+extrapolation", "gauss-seidel", True, "rev"),
)
#: drive parameters of the motor case (FMU start values; hub_drive_slave.PARAMETERS has the defaults)
DRIVE = {"drive.J": 5.0, "drive.k": 300.0, "drive.c": 0.0, "drive.Kp": 100.0, "drive.Ki": 200.0}
TORQUE_BLOWUP = 10.0  # unstable: shaft torque beyond this many times the monolithic run's peak
GROWTH_DEVIATION = 0.5  # ... or off the monolithic run by half its peak and growing (see _compare)


def _vec(prefix: str, port: str, fld: str) -> list[str]:
    if fld == "R":
        return [f"{prefix}.{port}.R[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
    return [f"{prefix}.{port}.{fld}[{i}]" for i in (1, 2, 3)]


def _rotz(phi: np.ndarray) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    R = np.zeros((len(phi), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def _tip_deflection(R_hub: np.ndarray, r_hub: np.ndarray, r_tip: np.ndarray, X_tip: np.ndarray) -> np.ndarray:
    d = np.einsum("nji,nj->ni", R_hub, r_tip - r_hub) - X_tip
    axis = X_tip / np.linalg.norm(X_tip)
    return _transverse(d, axis)


@dataclass
class CosimSettings:
    steps: tuple[float, ...] = COSIM_STEPS
    schemes: tuple = COSIM_SCHEMES
    T: float = 7.5  # motor case: spin-up time of the speed reference (B1: 15 s, halved as in the spin map)
    duration: float = 10.0
    split_T: float = 1.0  # split case: a fast spin-up (the explicit instability shows within ms)
    split_duration: float = 1.0
    split_steps: tuple[float, ...] = (0.001, 0.002, 0.004, 0.01, 0.02)  # 40 ms: the one body fails (Newton)
    split_internal_is_H: bool = True  # split case: the body FMUs' internal step (solver.step) = H
    implicit_iterations: int = 50
    implicit_tolerance: tuple[float, float] = (1e-5, 1e-6)  # relative, absolute (N, N m): above the FMUs' Newton noise
    drive: dict = field(default_factory=lambda: dict(DRIVE))
    reference_step: float = 0.001  # motor: implicit coupling at H = the beam's internal step = 1 ms
    beam_step: float = 0.002  # motor: the beam FMU's internal step is min(H, beam_step)
    overrides: tuple[str, ...] = ()  # --set values for the beam model


@dataclass
class CosimRun:
    t: np.ndarray
    deflection: np.ndarray
    speed: np.ndarray  # hub (beam root) angular velocity about Z
    torque: np.ndarray  # interface moment about Z on the downstream side
    stopped_early: str
    wall_time_s: float
    sweeps: float = 1.0


class CosimCase:
    """FMUs and runs of one coupled system ("motor" or "split") under ffrf_fmu.master."""

    def __init__(self, kind: str, model_path, fmu_dir, settings: CosimSettings):
        from ..fmu.builder import build_from_model

        self.kind, self.settings = kind, settings
        fmu_dir = Path(fmu_dir)
        fmu_dir.mkdir(parents=True, exist_ok=True)
        ov = list(settings.overrides)
        model = load_model(model_path, ov)
        self.length = model.body.length
        if kind == "motor":
            from ..examples import build_hub_drive

            self.fmus = {"beam": build_from_model(model_path, fmu_dir / "beam_hub_free.fmu", scene="hub_free",
                                                  overrides=[*ov, f"scenes.hub_free.duration={settings.duration!r}"]),
                         "drive": build_hub_drive(fmu_dir / "hub_drive.fmu")}
            self.order = {"fwd": ["beam", "drive"], "rev": ["drive", "beam"]}
            self.start_values = {**{f"drive.{k}": v for k, v in settings.drive.items()},
                                 "drive.profile.T": settings.T}
            omega = dict(model.scene("spinup").drives[0].rotation.angle.params)["omega"]
            self.start_values["drive.profile.omega"] = omega
            self.X_tip = np.array([self.length, 0.0, 0.0])
            self.duration = settings.duration
            self.sources = None
        elif kind == "split":
            halves = split_models(model_path, fmu_dir, ov)
            self.fmus = {"A": build_from_model(halves[0], fmu_dir / "split_a.fmu"),
                         "B": build_from_model(halves[1], fmu_dir / "split_b.fmu")}
            ov = [*ov, f"scenes.spinup.drives.hub.rotation.angle.T={settings.split_T!r}",
                  f"scenes.spinup.duration={settings.split_duration!r}"]
            self.one = build_from_model(model_path, fmu_dir / "split_one_body.fmu", scene="spinup", overrides=ov)
            self.order = {"fwd": ["A", "B"], "rev": ["B", "A"]}
            self.start_values = {}
            self.X_tip = np.array([self.length, 0.0, 0.0])
            self.duration = settings.split_duration
            self.profile = dict(model.scene("spinup").drives[0].rotation.angle.params)
            self.profile["T"] = settings.split_T
        else:
            raise ValueError(f"unknown co-simulation case {kind!r}: motor or split")

    # ----------------------------------------------------------------------------- split helpers
    def _phi(self, t: np.ndarray) -> np.ndarray:
        from ..runtime.drives import evaluate

        return np.array([evaluate("haug_spinup", self.profile, float(x))[0] for x in t])

    def _hub_sources(self, prefix: str) -> Callable[[float], dict]:
        from ..runtime.drives import evaluate
        from ..runtime.rotation import expm

        names_R, names_w = _vec(prefix, "hub", "R"), _vec(prefix, "hub", "w")
        names_r, names_v = _vec(prefix, "hub", "r"), _vec(prefix, "hub", "v")

        def f(t):
            phi, dphi, _ = evaluate("haug_spinup", self.profile, t)
            R = expm(np.array([0.0, 0.0, phi]))
            out = dict(zip(names_R, R.ravel()))
            out.update(zip(names_w, (0.0, 0.0, dphi)))
            out.update(zip(names_r, (0.0, 0.0, 0.0)))
            out.update(zip(names_v, (0.0, 0.0, 0.0)))
            return out

        return f

    # ----------------------------------------------------------------------------- runs
    def _implicit(self, iterations: int) -> dict:
        if iterations <= 1:
            return {"iterations": 1}
        rel, ab = self.settings.implicit_tolerance
        return {"iterations": iterations, "tolerance": rel, "abs_tolerance": ab}

    def run(self, H: float, scheme: str = "gauss-seidel", extrapolation: bool = False, order: str = "fwd",
            iterations: int = 1, duration: float | None = None, one_body: bool = False,
            interface_jacobian: bool = False) -> CosimRun:
        from ..master import CoSimulation

        duration = self.duration if duration is None else duration
        t0 = time.perf_counter()
        if self.kind == "motor":
            rec = _vec("beam", "hub", "R") + _vec("beam", "tip", "r") + ["beam.hub.w[3]", "drive.drive.shaft_torque"]
            sv = {**self.start_values, "beam.solver.step": min(H, self.settings.beam_step)}
            with CoSimulation(self.fmus, step=H, scheme=scheme, extrapolation=extrapolation, order=self.order[order],
                              start_values=sv, **self._implicit(iterations),
                              interface_jacobian=interface_jacobian) as sim:
                sim.connect_ports("beam", "hub", "drive", "hub")
                res = sim.run(duration, record=rec)
            c = res.columns
            R = np.stack([c[n] for n in _vec("beam", "hub", "R")], -1).reshape(-1, 3, 3)
            speed, torque = c["beam.hub.w[3]"], c["drive.drive.shaft_torque"]
        else:
            sv = lambda *names: {f"{n}.solver.step": H for n in names} if self.settings.split_internal_is_H else {}  # noqa: E731
            if one_body:
                rec = _vec("F", "tip", "r") + ["F.hub.t[3]"]
                with CoSimulation({"F": self.one}, step=H, start_values=sv("F")) as sim:
                    res = sim.run(duration, sources=self._hub_sources("F"), record=rec)
                tip, torque = _vec("F", "tip", "r"), res.columns["F.hub.t[3]"]
            else:
                rec = _vec("B", "tip", "r") + ["A.cut.t[3]"]
                with CoSimulation(self.fmus, step=H, scheme=scheme, extrapolation=extrapolation,
                                  order=self.order[order], start_values=sv("A", "B"), **self._implicit(iterations),
                              interface_jacobian=interface_jacobian) as sim:
                    sim.connect_ports("A", "cut", "B", "cut")
                    res = sim.run(duration, sources=self._hub_sources("A"), record=rec)
                tip, torque = _vec("B", "tip", "r"), res.columns["A.cut.t[3]"]
            c = res.columns
            R = _rotz(self._phi(res.t))
            speed = np.full(len(res.t), np.nan)
        r_tip = np.stack([c[n] for n in (tip if self.kind == "split" else _vec("beam", "tip", "r"))], -1)
        d = _tip_deflection(R, np.zeros_like(r_tip), r_tip, self.X_tip)
        return CosimRun(res.t, d, speed, torque, res.stopped_early, time.perf_counter() - t0,
                        float(np.mean(res.sweeps)) if len(res.sweeps) else 1.0)


def split_models(model_path, out_dir, overrides: Sequence[str] = (), coupling: str = "") -> tuple[Path, Path]:
    """Two model files for the beam of `model_path` cut at its middle boundary node (its number
    of superelements must be even): A from the hub (motion-driven) to the cut (force-driven), B from
    the cut (motion-driven) to the tip (free). Same section, superelements and modes as the one
    body, so the split system has the same superelements as the one-body model.
    coupling: '' (rigid joint: B's cut motion-driven) or a TOML inline table for a compliant cut
    (docs/cosim.md): A's cut compliant with that coupling, B's cut force-driven."""
    model = load_model(model_path, overrides)
    b = model.body
    if b.superelements % 2:
        raise ValueError(f"{model_path}: {b.superelements} superelements cannot be cut at a middle node")
    s = b.section
    section = "\n".join(f"{k} = {getattr(s, k)!r}" for k in ("EA", "GA2", "GA3", "GJ", "EI2", "EI3", "m", "m22", "m33", "m11")
                        if getattr(s, k) is not None)
    half = b.length / 2
    d = [float(x) for x in b.direction]
    out = []
    cut_a, cut_b = ("compliant", "force") if coupling else ("force", "motion")
    for name, x0, p0, c0, p1, c1 in (("half_a", [float(x) for x in b.origin], "hub", "motion", "cut", cut_a),
                                     ("half_b", [float(o + half * e) for o, e in zip(b.origin, d)], "cut", cut_b,
                                      "tip", "force")):
        text = f"""# generated by ffrf_fmu.studies.stability.split_models from {Path(model_path).name}: half of the beam
[body]
name = "{b.name}_{name}"
length = {half!r}
origin = [{x0[0]!r}, {x0[1]!r}, {x0[2]!r}]
direction = [{d[0]!r}, {d[1]!r}, {d[2]!r}]
superelements = {b.superelements // 2}
elements_per_superelement = {b.elements_per_superelement}
modes = {b.modes}
[body.section]
{section}
[body.ports.{p0}]
node = 0
translation = "{c0}"
rotation = "{c0}"
[body.ports.{p1}]
node = -1
translation = "{c1}"
rotation = "{c1}"
{f"coupling = {coupling}" if c1 == "compliant" else ""}
[scenes.run]
duration = 1.0
step = {model.scene("spinup").step!r}
rho_inf = {model.scene("spinup").rho_inf!r}
terms = "{model.scene("spinup").terms}"
"""
        path = Path(out_dir) / f"{b.name}_{name}{'_compliant' if coupling else ''}.toml"
        path.write_text(text)
        out.append(path)
    return out[0], out[1]


IMPLICIT = ("gauss-seidel implicit", "gauss-seidel", False, "fwd")
#: motor case with the shaft in the beam's compliant hub (ffrf_fmu/compliant_b5.py, docs/cosim.md)
COMPLIANT = ("compliant jacobi", "jacobi", False, "fwd")
#: linearly implicit coupling (master.CoSimulation(interface_jacobian=True), docs/cosim.md)
INTERFACE_JACOBIAN = ("interface-jacobian", "gauss-seidel", False, "fwd")


def _compare(run: CosimRun, ref: CosimRun, length: float, ref_torque_peak: float) -> dict:
    """Errors of a coupled run against its monolithic reference, and the stability verdict."""
    n = len(run.t)
    d_ref = np.interp(run.t, ref.t, ref.deflection)
    scale = float(np.max(np.abs(ref.deflection)))
    finite = np.all(np.isfinite(run.deflection)) and np.all(np.isfinite(run.torque))
    err = float(np.max(np.abs(run.deflection - d_ref)) / scale) if n and finite else float("nan")
    speed_err = float("nan")
    if np.any(np.isfinite(run.speed)) and finite:
        s_ref = np.interp(run.t, ref.t, ref.speed)
        speed_err = float(np.max(np.abs(run.speed - s_ref)) / max(np.max(np.abs(ref.speed)), 1e-300))
    reasons = []
    if run.stopped_early:
        reasons.append(run.stopped_early.split(": Newton")[0] + (": Newton failure" if "Newton" in run.stopped_early else ""))
    if not finite:
        reasons.append("non-finite values")
    elif np.max(run.deflection) > length:
        reasons.append(f"tip deflection {np.max(run.deflection):.3g} m > L")
    elif np.max(np.abs(run.torque)) > TORQUE_BLOWUP * ref_torque_peak:
        reasons.append(f"interface torque {np.max(np.abs(run.torque)):.3g} N m > {TORQUE_BLOWUP:g} x monolithic peak")
    elif n > 10:
        # a growing oscillation that has not failed yet: the interface torque has left the monolithic
        # run by more than half its peak over the last second, and by 10x more than in the first half
        dev = np.abs(run.torque - np.interp(run.t, ref.t, ref.torque))
        last, first = dev[run.t >= run.t[-1] - 1.0], dev[run.t <= run.t[-1] / 2]
        if np.max(last) > GROWTH_DEVIATION * ref_torque_peak and np.max(last) > 10.0 * max(np.max(first), 1e-12):
            reasons.append(f"growing interface oscillation: torque off the monolithic run by {np.max(last):.3g} N m "
                           f"in the last second, {np.max(first):.2g} N m in the first half")
    return {"rel_error": err, "speed_rel_error": speed_err, "unstable": bool(reasons), "failure": "; ".join(reasons),
            "t_end": float(run.t[-1]) if n else 0.0, "sweeps": run.sweeps, "wall_time_s": run.wall_time_s}


def cosim_map(model_path, settings: CosimSettings, out_dir, *, cases=("motor", "split"),
              implicit_steps: Sequence[float] = (0.002, 0.01, 0.04), log=print) -> list[dict]:
    """Communication step against coupling scheme for the motor and the split systems; one CSV row
    per run (resumable like spin_map). Monolithic references (docs/stability.md): motor -> the same
    two FMUs with implicit (iterated) coupling at H = the beam's internal step; split -> the
    one-body FMU at the same H."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "map.csv"
    rows = read_csv(path) if path.exists() else []
    series = dict(np.load(out_dir / "series.npz")) if (out_dir / "series.npz").exists() else {}

    def save(row, run, key):
        rows.append(row)
        series[key] = np.column_stack([run.t, run.deflection, run.speed, run.torque])
        write_csv(path, rows)
        np.savez_compressed(out_dir / "series.npz", **series)

    def load(key) -> CosimRun:
        a = series[key]
        return CosimRun(a[:, 0], a[:, 1], a[:, 2], a[:, 3], "", 0.0)

    for kind in cases:
        case = CosimCase(kind, model_path, out_dir / "fmus", settings)
        refs: dict[float, CosimRun] = {}

        def reference(H):
            if kind == "motor":
                H = settings.reference_step
            if H in refs:
                return refs[H]
            key = f"{kind}_reference_H{H:g}"
            if key not in series:
                run = (case.run(H, "gauss-seidel", iterations=settings.implicit_iterations) if kind == "motor" else case.run(H, one_body=True))
                if run.stopped_early:
                    raise RuntimeError(f"{kind}: the monolithic reference failed: {run.stopped_early}")
                save({"case": kind, "scheme": "monolithic reference", "H": H, "rel_error": 0.0, "unstable": False,
                      "failure": "", "t_end": float(run.t[-1]), "sweeps": run.sweeps, "wall_time_s": run.wall_time_s},
                     run, key)
                log(f"{kind}: monolithic reference at H = {H:g} s ({run.wall_time_s:.0f} s)")
            refs[H] = load(key)
            return refs[H]

        schemes = list(settings.schemes) + [IMPLICIT, INTERFACE_JACOBIAN] + ([COMPLIANT] if kind == "motor" else [])
        compliant_fmus = None
        for H in (settings.steps if kind == "motor" else settings.split_steps):
            ref = reference(H)
            peak = float(np.max(np.abs(ref.torque)))
            for label, scheme, extrap, order in schemes:
                implicit = label == IMPLICIT[0]
                if implicit and kind == "motor" and not any(abs(H - h) < 1e-12 for h in implicit_steps):
                    continue
                if _done(rows, case=kind, scheme=label, H=float(H)) is not None:
                    continue
                if label == COMPLIANT[0]:  # the shaft moves into the beam FMU (docs/cosim.md)
                    from .. import compliant_b5

                    compliant_fmus = compliant_fmus or compliant_b5.build(model_path, out_dir / "fmus", settings)
                    run = compliant_b5.run_master(compliant_fmus, settings, H, case.duration)
                else:
                    run = case.run(H, scheme, extrap, order, iterations=settings.implicit_iterations if implicit else 1,
                                   interface_jacobian=label == INTERFACE_JACOBIAN[0])
                row = {"case": kind, "scheme": label, "H": float(H), **_compare(run, ref, case.length, peak)}
                save(row, run, f"{kind}_{label}_H{H:g}")
                log(f"{kind} H = {H:g} s {label}: error {row['rel_error']:.3g}"
                    f"{', UNSTABLE: ' + row['failure'] if row['unstable'] else ''} ({run.wall_time_s:.0f} s)")
    return rows


# ------------------------------------------------------------------------------------ 2. integrator map

RHO_INFS = (0.0, 0.5, 0.8, 1.0)
ENERGY_GROWTH = 0.05  # unstable: the integrator created more than 5 % of the energy level


@dataclass
class IntegratorSettings:
    """Step sizes against rho_inf for one scene; the converged run uses `converged_step`."""

    steps: tuple[float, ...]
    rhos: tuple[float, ...] = RHO_INFS
    converged_step: float = 5e-4
    converged_rho: float = 0.8
    duration: float | None = None  # None: the scene's
    overrides: tuple[str, ...] = ()


#: per benchmark scene: B1 spin-up halved like the spin map (T = 7.5 s, 10 s), B2 cut after 20 s
#: (torque 0-10 s, tip load 15-15.2 s, 4.8 s of the 1.74 Hz vibration after it)
INTEGRATOR_DEFAULTS = {
    ("haug_beam", "spinup"): IntegratorSettings(steps=(1e-3, 2e-3, 5e-3, 0.01, 0.02, 0.05, 0.1, 0.2),
                                                converged_step=5e-4, duration=10.0,
                                                overrides=("scenes.spinup.drives.hub.rotation.angle.T=7.5",)),
    ("spherical_beam", "torque_then_tip"): IntegratorSettings(steps=(5e-3, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5),
                                                               converged_step=1e-3, duration=20.0),
}


def integrator_run(model_path, scene: str, step: float, rho: float, settings: IntegratorSettings) -> tuple[BeamRun, Model]:
    ov = [*settings.overrides, f"scenes.{scene}.step={step!r}", f"scenes.{scene}.rho_inf={rho!r}"]
    if settings.duration is not None:
        ov.append(f"scenes.{scene}.duration={settings.duration!r}")
    model = load_model(model_path, ov)
    return run_beam(model, model.scene(scene)), model


def energy_growth(run: BeamRun) -> float:
    """Largest energy the integrator created, max_t (E(t) - E(0) - W_ext(t)), over the energy level."""
    return float(max(np.max(run.energy_gap), 0.0) / run.energy_level) if run.energy_level > 0 else 0.0


def integrator_map(model_path, scene: str, settings: IntegratorSettings, out_dir, *, log=print) -> list[dict]:
    """Step size against rho_inf on one scene: error of the maximum transverse tip deflection
    (`peak_rel_error`, signed) and of its history (`rel_error`: max over time of the difference,
    over the converged run's peak), energy growth, stability."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "map.csv"
    rows = read_csv(path) if path.exists() else []
    series = dict(np.load(out_dir / "series.npz")) if (out_dir / "series.npz").exists() else {}
    name = Path(model_path).stem
    key = f"{name}_{scene}_converged"
    if key not in series:
        conv, _ = integrator_run(model_path, scene, settings.converged_step, settings.converged_rho, settings)
        if conv.unstable:
            raise RuntimeError(f"{name}/{scene}: the converged run failed: {conv.failure}")
        series[key] = np.column_stack([conv.t, conv.deflection])
        rows.append({"benchmark": name, "scene": scene, "step": settings.converged_step, "rho_inf": settings.converged_rho,
                     "converged": True, "peak_rel_error": 0.0, "rel_error": 0.0, "energy_growth": energy_growth(conv),
                     "unstable": False,
                     "failure": "", "t_end": float(conv.t[-1]), "wall_time_s": conv.wall_time_s})
        write_csv(path, rows)
        np.savez_compressed(out_dir / "series.npz", **series)
        log(f"{name}/{scene}: converged run h = {settings.converged_step:g} s ({conv.wall_time_s:.0f} s)")
    t_c, d_c = series[key][:, 0], series[key][:, 1]
    peak = float(np.max(np.abs(d_c)))
    for rho in settings.rhos:
        for h in settings.steps:
            if _done(rows, benchmark=name, scene=scene, step=float(h), rho_inf=float(rho), converged=False):
                continue
            run, model = integrator_run(model_path, scene, h, rho, settings)
            n = len(run.t)
            err = float(np.max(np.abs(run.deflection - np.interp(run.t, t_c, d_c))) / peak) if n else float("nan")
            peak_err = float((run.max_deflection - peak) / peak)
            growth = energy_growth(run)
            failure = run.failure
            if not run.unstable and growth > ENERGY_GROWTH:
                failure = f"energy growth {growth:.3g} > {ENERGY_GROWTH:g} of the energy level"
            rows.append({"benchmark": name, "scene": scene, "step": float(h), "rho_inf": float(rho), "converged": False,
                         "peak_rel_error": peak_err, "rel_error": err, "energy_growth": growth,
                         "unstable": bool(failure), "failure": failure,
                         "t_end": float(run.t[-1]), "wall_time_s": run.wall_time_s})
            series[f"{name}_{scene}_h{h:g}_rho{rho:g}"] = np.column_stack([run.t, run.deflection])
            write_csv(path, rows)
            np.savez_compressed(out_dir / "series.npz", **series)
            log(f"{name}/{scene} h = {h:g} s rho_inf {rho:g}: error {err:.3g}, energy growth {growth:.2g}"
                f"{', UNSTABLE: ' + failure if failure else ''} ({run.wall_time_s:.0f} s)")
    return rows


# ------------------------------------------------------------------------------------ plots

def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _is_true(v) -> bool:
    return v is True or v == "True" or v == 1.0


def plot_spin(rows: list[dict], path) -> None:
    plt = _plt()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2))
    ref = sorted((r for r in rows if r["model"] == "reference"), key=lambda r: r["omega"])
    names = sorted({r["model"] for r in rows if r["model"] != "reference"},
                   key=lambda s: (s.split("-")[1], int(s.split("SE")[0])))
    ax2.plot([r["omega"] for r in ref], [r["max_deflection"] for r in ref], "k-o", lw=2, label="nonlinear reference")
    colors = {1: "tab:red", 2: "tab:orange", 4: "tab:green"}
    for name in names:
        rs = sorted((r for r in rows if r["model"] == name), key=lambda r: r["omega"])
        n, terms = int(name.split("SE")[0]), name.split("-")[1]
        style = "-" if terms == "linear" else "--"
        ok = [r for r in rs if not _is_true(r["unstable"])]
        bad = [r for r in rs if _is_true(r["unstable"])]
        kw = dict(color=colors.get(n, "tab:blue"), ls=style, marker="o" if terms == "linear" else "s", ms=4)
        ax1.plot([r["omega"] for r in ok], [max(abs(100 * r["rel_error"]), 1e-3) for r in ok],
                 label=f"{n} SE, {terms}", **kw)
        ax2.plot([r["omega"] for r in ok], [r["max_deflection"] for r in ok], label=f"{n} SE, {terms}", **kw)
        y_bad = 1000.0 if terms == "linear" else 2000.0
        for r in bad:
            ax1.plot(r["omega"], y_bad, "x" if terms == "linear" else "+", color=kw["color"], ms=11, mew=3)
    ax1.axvline(2.915, color="gray", ls=":", lw=1)
    ax1.text(3.0, 0.05, "first cantilever\nfrequency 2.92 rad/s", fontsize=7, color="gray")
    ax1.text(1.0, 3000.0, "unstable (deflection > L or Newton failure): x linear, + gyroscopic", fontsize=7)
    ax1.set_yscale("log")
    ax1.set_ylim(0.03, 6000.0)
    ax1.set_xlabel("final spin rate [rad/s]")
    ax1.set_ylabel("|error| of the max transverse tip deflection [%]")
    ax1.set_title("model error vs the nonlinear beam (x: unstable)")
    ax1.grid(True, alpha=0.3)
    ax1.legend(fontsize=8)
    ax2.set_xlabel("final spin rate [rad/s]")
    ax2.set_ylabel("max transverse tip deflection [m]")
    ax2.set_yscale("log")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=8)
    T = ref[0].get("T") if ref else None
    fig.suptitle(f"B3: spin-up beyond the first bending frequency (Wu-Haug profile, T = {T:g} s, run {ref[0]['duration']:g} s)"
                 if ref else "B3 spin map")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_integrator(rows: list[dict], path) -> None:
    plt = _plt()
    benches = sorted({(r["benchmark"], r["scene"]) for r in rows})
    fig, axes = plt.subplots(1, max(1, len(benches)), figsize=(6.5 * max(1, len(benches)), 5.2), squeeze=False)
    colors = {0.0: "tab:blue", 0.5: "tab:green", 0.8: "tab:orange", 1.0: "tab:red"}
    for ax, (b, sc) in zip(axes[0], benches):
        rs = [r for r in rows if r["benchmark"] == b and r["scene"] == sc and not _is_true(r["converged"])]
        conv = [r for r in rows if r["benchmark"] == b and r["scene"] == sc and _is_true(r["converged"])]
        for irho, rho in enumerate(sorted({r["rho_inf"] for r in rs})):
            rr = sorted((r for r in rs if r["rho_inf"] == rho), key=lambda r: r["step"])
            ok = [r for r in rr if not _is_true(r["unstable"])]
            c = colors.get(rho, None)
            ax.plot([r["step"] for r in ok], [max(abs(r["peak_rel_error"]), 1e-7) for r in ok], "-o", color=c,
                    label=f"rho_inf = {rho:g}: max deflection")
            ax.plot([r["step"] for r in ok], [max(r["rel_error"], 1e-7) for r in ok], ":", color=c, lw=1,
                    label=f"rho_inf = {rho:g}: history")
            for r in rr:
                if _is_true(r["unstable"]):
                    ax.plot(r["step"], 2.0 * 1.6**irho, "x", color=c, ms=10, mew=3)
        ax.axhline(1.0, color="k", lw=0.5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time step h [s]")
        ax.set_ylabel("relative error of the tip deflection\nmaximum (solid), history (dotted)")
        hc = conv[0]["step"] if conv else float("nan")
        ax.set_title(f"{b} / {sc} (converged: h = {hc:g} s)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle("Integrator: generalized-alpha step size against rho_inf "
                 "(x = unstable: Newton failure or energy growth, one row of x per rho_inf)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_cosim(rows: list[dict], path) -> None:
    plt = _plt()
    from matplotlib.colors import LogNorm

    cases = [c for c in ("motor", "split") if any(r["case"] == c for r in rows)]
    fig, axes = plt.subplots(len(cases), 1, figsize=(10, 3.6 * len(cases)), squeeze=False)
    titles = {"motor": "B5 beam FMU + hub drive FMU (shaft k = {k:g} N m/rad, hub J = {J:g} kg m^2): error of the tip deflection",
              "split": "B1 beam split in two body FMUs at its middle node: error of the tip deflection"}
    for ax, case in zip(axes[:, 0], cases):
        rs = [r for r in rows if r["case"] == case and r["scheme"] != "monolithic reference"]
        schemes = [s[0] for s in COSIM_SCHEMES + (IMPLICIT, INTERFACE_JACOBIAN, COMPLIANT) if any(r["scheme"] == s[0] for r in rs)]
        steps = sorted({r["H"] for r in rs})
        grid = np.full((len(schemes), len(steps)), np.nan)
        label = {}
        for r in rs:
            i, j = schemes.index(r["scheme"]), steps.index(r["H"])
            grid[i, j] = -1.0 if _is_true(r["unstable"]) else max(r["rel_error"], 1e-9)
            if _is_true(r["unstable"]) and "did not converge" in str(r["failure"]):
                label[i, j] = "not converged"
        for r in rows:
            if (r["case"] == case == "motor" and r["scheme"] == "monolithic reference" and IMPLICIT[0] in schemes
                    and r["H"] in steps):
                label[schemes.index(IMPLICIT[0]), steps.index(r["H"])] = "reference"
        shown = np.where(grid > 0, grid, np.nan)
        im = ax.imshow(shown, aspect="auto", cmap="viridis", norm=LogNorm(vmin=1e-6, vmax=1.0))
        for i in range(len(schemes)):
            for j in range(len(steps)):
                v = grid[i, j]
                if np.isnan(v):
                    ax.text(j, i, label.get((i, j), "-"), ha="center", va="center", color="gray", fontsize=8)
                elif v < 0:
                    ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, color="tab:red"))
                    ax.text(j, i, label.get((i, j), "unstable"), ha="center", va="center", color="white", fontsize=8,
                            weight="bold")
                else:
                    ax.text(j, i, f"{v:.1e}", ha="center", va="center", color="white" if v < 1e-2 else "black", fontsize=8)
        ax.set_xticks(range(len(steps)), [f"{1000 * h:g} ms" for h in steps])
        ax.set_yticks(range(len(schemes)), schemes, fontsize=8)
        ax.set_xlabel("communication step H")
        ax.set_title(titles[case].format(k=DRIVE["drive.k"], J=DRIVE["drive.J"]), fontsize=9)
        fig.colorbar(im, ax=ax, label="relative error")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


PLOTS = {"spin": plot_spin, "integrator": plot_integrator, "cosim": plot_cosim}


# ------------------------------------------------------------------------------------ established engine
#
# libcosim (Open Simulation Platform, PyPI package libcosimpy) runs the same FMUs with its fixed-step
# algorithm: every slave gets its inputs from the outputs at t_c, then all step: a Jacobi scheme with
# held inputs, i.e. master.CoSimulation(scheme="jacobi", extrapolation=False). Connections with a gain
# (minus the reaction, body_port_links) are ssc:LinearTransformation connections of a generated SSD.


def _ssd(path: Path, components: dict[str, str], connections: list[tuple[str, str, float]]) -> Path:
    """Write a SystemStructure.ssd: components {name: fmu file}, connections (src, dst, factor);
    every connected variable is declared as a connector (libcosim requires it)."""
    used: dict[str, dict[str, str]] = {name: {} for name in components}
    for src, dst, _ in connections:
        se, sc = src.split(".", 1)
        de, dc = dst.split(".", 1)
        used[se][sc] = "output"
        used[de][dc] = "input"
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             '<ssd:SystemStructureDescription name="ffrf" version="1.0" '
             'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
             'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">',
             '  <ssd:System name="ffrf">', "    <ssd:Elements>"]
    for name, src in components.items():
        lines += [f'      <ssd:Component name="{name}" source="{src}">', "        <ssd:Connectors>"]
        lines += [f'          <ssd:Connector name="{c}" kind="{k}"><ssc:Real/></ssd:Connector>' for c, k in used[name].items()]
        lines += ["        </ssd:Connectors>", "      </ssd:Component>"]
    lines += ["    </ssd:Elements>", "    <ssd:Connections>"]
    for src, dst, factor in connections:
        se, sc = src.split(".", 1)
        de, dc = dst.split(".", 1)
        head = f'      <ssd:Connection startElement="{se}" startConnector="{sc}" endElement="{de}" endConnector="{dc}"'
        if factor == 1.0:
            lines.append(head + "/>")
        else:
            lines += [head + ">", f'        <ssc:LinearTransformation factor="{factor!r}" offset="0.0"/>',
                      "      </ssd:Connection>"]
    lines += ["    </ssd:Connections>", "  </ssd:System>", '  <ssd:DefaultExperiment startTime="0.0"/>',
              "</ssd:SystemStructureDescription>"]
    path.write_text("\n".join(lines) + "\n")
    return path


def libcosim_run(case: CosimCase, H: float, duration: float, work_dir) -> CosimRun:
    """The case under libcosim's fixed-step (Jacobi) algorithm; same outputs as CosimCase.run."""
    import shutil

    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver

    from ..master import FmuInstance, Motion, body_port_links, port_causality

    log_output_level(CosimLogLevel.ERROR)
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    comps = {}
    for name, fmu in case.fmus.items():
        shutil.copy(fmu, work / Path(fmu).name)
        comps[name] = Path(fmu).name
    if case.kind == "motor":
        conns = [(f"drive.hub.{f}[{i}]", f"beam.hub.{f}[{i}]", 1.0) for f in ("r", "v") for i in (1, 2, 3)]
        conns += [(f"beam.hub.R[{i},{j}]", f"drive.hub.R[{i},{j}]", 1.0) for i in (1, 2, 3) for j in (1, 2, 3)]
        conns += [(f"beam.hub.w[{i}]", f"drive.hub.w[{i}]", 1.0) for i in (1, 2, 3)]
        conns += [("drive.drive.shaft_torque", "beam.hub.t[3]", 1.0)]  # = -drive.hub.t[3]; t[1], t[2] are 0
        start = {**case.start_values, "beam.solver.step": min(H, case.settings.beam_step)}
    else:
        a, b = (FmuInstance(n, case.fmus[n]) for n in ("A", "B"))
        try:
            links = body_port_links("A", "cut", "B", "cut", port_causality(a, "cut"), port_causality(b, "cut"))
        finally:
            a.close()
            b.close()
        conns = []
        for link in links:
            if isinstance(link, Motion):
                conns += [(s, d, 1.0) for s, d in zip(link.src_pos + link.src_rate, link.dst_pos + link.dst_rate)]
            else:
                conns.append((link.src, link.dst, link.gain))
        start = {f"{n}.solver.step": H for n in ("A", "B")} if case.settings.split_internal_is_H else {}
    ssd = _ssd(work / "SystemStructure.ssd", comps, conns)
    t0 = time.perf_counter()
    ex = CosimExecution.from_ssp_file(str(ssd), step_size=int(round(H * 1e9)))
    index = {info.name.decode(): info.index for info in ex.slave_infos()}
    refs = {n: {v.name.decode(): v.reference for v in ex.slave_variables(i)} for n, i in index.items()}
    for full, value in start.items():
        inst, var = full.split(".", 1)
        ex.real_initial_value(index[inst], refs[inst][var], float(value))
    observer = CosimObserver.create_last_value()
    ex.add_observer(observer)
    manip = CosimManipulator.create_override()
    ex.add_manipulator(manip)
    if case.kind == "motor":
        rec = {"beam": [*(n.split(".", 1)[1] for n in _vec("beam", "hub", "R")),
                        *(n.split(".", 1)[1] for n in _vec("beam", "tip", "r")), "hub.w[3]"],
               "drive": ["drive.shaft_torque"]}
        sources = None
    else:
        rec = {"B": [n.split(".", 1)[1] for n in _vec("B", "tip", "r")], "A": ["cut.t[3]"]}
        sources = case._hub_sources("A")

    def apply_sources(t):
        if sources:
            vals = sources(t)
            names = [n.split(".", 1)[1] for n in vals]
            manip.slave_real_values(index["A"], [refs["A"][n] for n in names], list(vals.values()))

    def read():
        out = {}
        for inst, names in rec.items():
            out.update(zip((f"{inst}.{n}" for n in names),
                           observer.last_real_values(index[inst], [refs[inst][n] for n in names])))
        return out

    n_steps = int(round(duration / H))
    apply_sources(0.0)
    ok = True
    rows, times, stopped = [], [], ""
    for k in range(n_steps):
        apply_sources(k * H)
        if not ex.step(1):
            stopped = f"libcosim: step at t = {k * H:.6g} s failed"
            break
        if k == 0:  # the first step initializes: values at t = 0 are read after it, skip
            pass
        rows.append(read())
        times.append((k + 1) * H)
    wall = time.perf_counter() - t0
    t = np.array(times)
    if case.kind == "motor":
        R = np.stack([[r[n] for n in _vec("beam", "hub", "R")] for r in rows]).reshape(-1, 3, 3) if rows else np.zeros((0, 3, 3))
        r_tip = np.array([[r[n] for n in _vec("beam", "tip", "r")] for r in rows]).reshape(-1, 3)
        speed = np.array([r["beam.hub.w[3]"] for r in rows])
        torque = np.array([r["drive.drive.shaft_torque"] for r in rows])
    else:
        R = case._phi(t)
        R = _rotz(R)
        r_tip = np.array([[r[n] for n in _vec("B", "tip", "r")] for r in rows]).reshape(-1, 3)
        speed = np.full(len(t), np.nan)
        torque = np.array([r["A.cut.t[3]"] for r in rows])
    d = _tip_deflection(R, np.zeros_like(r_tip), r_tip, case.X_tip) if len(t) else np.zeros(0)
    del ex
    return CosimRun(t, d, speed, torque, stopped, wall)


# ------------------------------------------------------------------------------------ steady spin
#
# The spin-up sweep mixes two things: the model error under the spin-up loads, and the loss of
# stability of the spinning model. The second is a property of the model at constant spin: spun
# at the constant rate Omega from t = 0 (hub drive "ramp" started before t = 0, the body starts
# with the rigid velocity field) and kicked by a short transverse tip force, a stable model keeps
# a bounded vibration, an unstable one grows exponentially.

GROWTH_LIMIT = 2.0  # unstable at constant spin: the vibration envelope grows more than 2x


def steady_spin(model_path, scene: str, omega: float, *, n_se: int, terms: str, duration: float = 6.0,
                kick: float = 0.2, extra: Sequence[str] = ()) -> dict:
    """Constant spin `omega` about the hub drive axis with a 0.1 s transverse tip force `kick` [N]
    (normal to the beam, in the plane of rotation). Returns the envelope growth (max deflection
    over the last third of the run / over the second third) and the verdict."""
    ov = [f"scenes.{scene}.drives.hub.rotation.angle={{ kind = \"ramp\", rate = {omega!r}, t_start = -1.0 }}",
          f"scenes.{scene}.loads=[{{ port = \"tip\", force = [0.0, {kick!r}, 0.0], t_start = 0.0, t_end = 0.1 }}]",
          f"scenes.{scene}.duration={duration!r}", f"superelements={n_se}", f"scenes.{scene}.terms={terms}", *extra]
    model = load_model(model_path, ov)
    run = run_beam(model, model.scene(scene))
    t, d = run.t, run.deflection
    third = t[-1] / 3 if len(t) else 0.0
    mid = d[(t >= third) & (t < 2 * third)]
    last = d[t >= 2 * third]
    growth = float(np.max(last) / np.max(mid)) if len(mid) and len(last) and np.max(mid) > 0 else float("inf")
    unstable = run.unstable or growth > GROWTH_LIMIT
    return {"omega": float(omega), "superelements": n_se, "terms": terms, "growth": growth,
            "max_deflection": run.max_deflection, "unstable": bool(unstable),
            "failure": run.failure or (f"envelope grows x{growth:.3g}" if unstable else ""),
            "t_end": float(t[-1]) if len(t) else 0.0, "wall_time_s": run.wall_time_s}


def recheck_cosim(out_dir, length: float = 8.0) -> list[dict]:
    """Re-derive the verdict and errors of every completed coupled run in out_dir/map.csv from its
    stored series with the current `_compare` (runs that stopped early keep their failure).
    length: the beam length L (deflection limit)."""
    out_dir = Path(out_dir)
    rows = read_csv(out_dir / "map.csv")
    series = dict(np.load(out_dir / "series.npz"))
    load = lambda key: CosimRun(*(series[key][:, i] for i in range(4)), "", 0.0)  # noqa: E731
    for r in rows:
        if r["scheme"] == "monolithic reference" or (isinstance(r["failure"], str) and "doStep" in r["failure"]) \
                or (isinstance(r["failure"], str) and "did not converge" in r["failure"]):
            continue
        ref_key = (f"{r['case']}_reference_H{CosimSettings().reference_step:g}" if r["case"] == "motor"
                   else f"split_reference_H{r['H']:g}")
        run = load(f"{r['case']}_{r['scheme']}_H{r['H']:g}")
        ref = load(ref_key)
        new = _compare(run, ref, length, float(np.max(np.abs(ref.torque))))
        r.update({k: new[k] for k in ("rel_error", "speed_rel_error", "unstable", "failure")})
    write_csv(out_dir / "map.csv", rows)
    return rows
