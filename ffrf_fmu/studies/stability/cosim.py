"""The co-simulation map (docs/stability.md): communication step against coupling scheme for two
coupled systems, each run's tip deflection against its monolithic reference.

 motor: the beam FMU (scene hub_free: hub rotation force-driven, translation motion-driven)
        joined at its hub port to the hub drive FMU (ffrf_fmu.examples: hub inertia, motor, PI speed
        controller on the Wu-Haug profile, torsional shaft to the beam root);
 split: the beam cut at its middle boundary node into two body FMUs (split.py), A (hub
        motion-driven by the Wu-Haug law, cut force-driven) and B (cut motion-driven, tip free).

Every run is a task of the sweep layer (runner "cosim": case, H, scheme and the run settings as
options, `run_task`); a worker builds the case's FMUs once per process (`_case`).
"""
from __future__ import annotations

import hashlib
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ...fmu.variables import port_variables
from ...model import load_model
from ..runners import transverse
from ..task import make_task
from .common import SweepOptions, run_tasks, write_map

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
IMPLICIT = ("gauss-seidel implicit", "gauss-seidel", False, "fwd")
#: motor case with the shaft in the beam's compliant hub (compliant_b5.py, docs/cosim.md)
COMPLIANT = ("compliant jacobi", "jacobi", False, "fwd")
#: linearly implicit coupling (master.CoSimulation(interface_jacobian=True), docs/cosim.md)
INTERFACE_JACOBIAN = ("interface-jacobian", "gauss-seidel", False, "fwd")
REFERENCE = "monolithic reference"
SCHEMES = {s[0]: s for s in (*COSIM_SCHEMES, IMPLICIT, COMPLIANT, INTERFACE_JACOBIAN)}
#: drive parameters of the motor case (FMU start values; hub_drive_slave.PARAMETERS has the defaults)
DRIVE = {"drive.J": 5.0, "drive.k": 300.0, "drive.c": 0.0, "drive.Kp": 100.0, "drive.Ki": 200.0}
TORQUE_BLOWUP = 10.0  # unstable: shaft torque beyond this many times the monolithic run's peak
GROWTH_DEVIATION = 0.5  # ... or off the monolithic run by half its peak and growing (see compare)


def _vec(prefix: str, port: str, fld: str) -> list[str]:
    return port_variables(f"{prefix}.{port}", fld)


def _rotz(phi: np.ndarray) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    R = np.zeros((len(phi), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def tip_deflection(R_hub: np.ndarray, r_hub: np.ndarray, r_tip: np.ndarray, X_tip: np.ndarray) -> np.ndarray:
    """Transverse elastic tip deflection (eq. 92) from the hub frame and the tip position histories."""
    d = np.einsum("nji,nj->ni", R_hub, r_tip - r_hub) - X_tip
    return transverse(d, X_tip / np.linalg.norm(X_tip))


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


#: the settings that define a run (the rest choose which runs the map makes): a task's options
RUN_SETTINGS = ("T", "duration", "split_T", "split_duration", "split_internal_is_H", "implicit_iterations",
                "implicit_tolerance", "drive", "reference_step", "beam_step")


@dataclass
class CosimRun:
    t: np.ndarray
    deflection: np.ndarray
    speed: np.ndarray  # hub (beam root) angular velocity about Z
    torque: np.ndarray  # interface moment about Z on the downstream side
    stopped_early: str
    wall_time_s: float
    sweeps: float = 1.0

    def as_result(self) -> dict:
        return {"t": self.t, "deflection": self.deflection, "speed": self.speed, "torque": self.torque,
                "stopped_early": self.stopped_early, "wall_time_s": self.wall_time_s, "sweeps": self.sweeps,
                "completed": True, "failure": None}

    @classmethod
    def of(cls, r: dict) -> "CosimRun":
        return cls(*(np.asarray(r[k]) for k in ("t", "deflection", "speed", "torque")), r["stopped_early"],
                   float(r["wall_time_s"]), float(r["sweeps"]))


class CosimCase:
    """FMUs and runs of one coupled system ("motor" or "split") under ffrf_fmu.master."""

    def __init__(self, kind: str, model_path, fmu_dir, settings: CosimSettings):
        from ...fmu.builder import build_from_model
        from .split import split_models

        self.kind, self.settings = kind, settings
        fmu_dir = Path(fmu_dir)
        fmu_dir.mkdir(parents=True, exist_ok=True)
        ov = list(settings.overrides)
        model = load_model(model_path, ov)
        self.length = model.body.length
        self.X_tip = np.array([self.length, 0.0, 0.0])
        if kind == "motor":
            from ...examples import build_hub_drive

            self.fmus = {"beam": build_from_model(model_path, fmu_dir / "beam_hub_free.fmu", scene="hub_free",
                                                  overrides=[*ov, f"scenes.hub_free.duration={settings.duration!r}"]),
                         "drive": build_hub_drive(fmu_dir / "hub_drive.fmu")}
            self.order = {"fwd": ["beam", "drive"], "rev": ["drive", "beam"]}
            self.start_values = {**{f"drive.{k}": v for k, v in settings.drive.items()},
                                 "drive.profile.T": settings.T}
            omega = dict(model.scene("spinup").drives[0].rotation.angle.params)["omega"]
            self.start_values["drive.profile.omega"] = omega
            self.duration = settings.duration
        elif kind == "split":
            halves = split_models(model_path, fmu_dir, ov)
            self.fmus = {"A": build_from_model(halves[0], fmu_dir / "split_a.fmu"),
                         "B": build_from_model(halves[1], fmu_dir / "split_b.fmu")}
            ov = [*ov, f"scenes.spinup.drives.hub.rotation.angle.T={settings.split_T!r}",
                  f"scenes.spinup.duration={settings.split_duration!r}"]
            self.one = build_from_model(model_path, fmu_dir / "split_one_body.fmu", scene="spinup", overrides=ov)
            self.order = {"fwd": ["A", "B"], "rev": ["B", "A"]}
            self.start_values = {}
            self.duration = settings.split_duration
            self.profile = dict(model.scene("spinup").drives[0].rotation.angle.params)
            self.profile["T"] = settings.split_T
        else:
            raise ValueError(f"unknown co-simulation case {kind!r}: motor or split")

    # ----------------------------------------------------------------------------- split helpers
    def _phi(self, t: np.ndarray) -> np.ndarray:
        from ...runtime.drives import evaluate

        return np.array([evaluate("haug_spinup", self.profile, float(x))[0] for x in t])

    def _hub_sources(self, prefix: str) -> Callable[[float], dict]:
        from ...runtime.drives import evaluate
        from ...runtime.rotation import expm

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
            interface_jacobian: bool = False, jacobian: str = "auto") -> CosimRun:
        from ...master import CoSimulation

        duration = self.duration if duration is None else duration
        t0 = time.perf_counter()
        if self.kind == "motor":
            rec = _vec("beam", "hub", "R") + _vec("beam", "tip", "r") + ["beam.hub.w[3]", "drive.drive.shaft_torque"]
            sv = {**self.start_values, "beam.solver.step": min(H, self.settings.beam_step)}
            with CoSimulation(self.fmus, step=H, scheme=scheme, extrapolation=extrapolation, order=self.order[order],
                              start_values=sv, **self._implicit(iterations),
                              interface_jacobian=interface_jacobian, jacobian=jacobian) as sim:
                sim.connect_ports("beam", "hub", "drive", "hub")
                res = sim.run(duration, record=rec)
            c = res.columns
            R = np.stack([c[n] for n in _vec("beam", "hub", "R")], -1).reshape(-1, 3, 3)
            speed, torque = c["beam.hub.w[3]"], c["drive.drive.shaft_torque"]
            tip = _vec("beam", "tip", "r")
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
                                  interface_jacobian=interface_jacobian, jacobian=jacobian) as sim:
                    sim.connect_ports("A", "cut", "B", "cut")
                    res = sim.run(duration, sources=self._hub_sources("A"), record=rec)
                tip, torque = _vec("B", "tip", "r"), res.columns["A.cut.t[3]"]
            c = res.columns
            R = _rotz(self._phi(res.t))
            speed = np.full(len(res.t), np.nan)
        r_tip = np.stack([c[n] for n in tip], -1)
        d = tip_deflection(R, np.zeros_like(r_tip), r_tip, self.X_tip)
        return CosimRun(res.t, d, speed, torque, res.stopped_early, time.perf_counter() - t0,
                        float(np.mean(res.sweeps)) if len(res.sweeps) else 1.0)

    def libcosim(self, H: float, duration: float, work_dir) -> CosimRun:
        """The case under libcosim's fixed-step (Jacobi, held inputs) algorithm (engines.libcosim_run);
        same outputs as `run`."""
        from ...engines import libcosim_run
        from ...master import FmuInstance, Motion, body_port_links, port_causality

        if self.kind == "motor":
            joined = lambda src, dst, fields: [(a, b, 1.0) for f in fields for a, b in zip(_vec(*src, f), _vec(*dst, f))]
            conns = joined(("drive", "hub"), ("beam", "hub"), ("r", "v")) + joined(("beam", "hub"), ("drive", "hub"), ("R", "w"))
            conns += [("drive.drive.shaft_torque", "beam.hub.t[3]", 1.0)]  # = -drive.hub.t[3]; t[1], t[2] are 0
            start = {**self.start_values, "beam.solver.step": min(H, self.settings.beam_step)}
            record = [*_vec("beam", "hub", "R"), *_vec("beam", "tip", "r"), "beam.hub.w[3]", "drive.drive.shaft_torque"]
            sources = None
        else:
            a, b = (FmuInstance(n, self.fmus[n]) for n in ("A", "B"))
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
            start = {f"{n}.solver.step": H for n in ("A", "B")} if self.settings.split_internal_is_H else {}
            record = [*_vec("B", "tip", "r"), "A.cut.t[3]"]
            sources = self._hub_sources("A")
        t, cols, stopped, wall = libcosim_run(self.fmus, conns, start, H, duration, record, work_dir, sources)
        r_tip = np.stack([cols[n] for n in record if ".tip.r[" in n], -1).reshape(-1, 3)
        if self.kind == "motor":
            R = np.stack([cols[n] for n in _vec("beam", "hub", "R")], -1).reshape(-1, 3, 3)
            speed, torque = cols["beam.hub.w[3]"], cols["drive.drive.shaft_torque"]
        else:
            R = _rotz(self._phi(t))
            speed, torque = np.full(len(t), np.nan), cols["A.cut.t[3]"]
        d = tip_deflection(R, np.zeros_like(r_tip), r_tip, self.X_tip) if len(t) else np.zeros(0)
        return CosimRun(t, d, speed, torque, stopped, wall)


def compare(run: CosimRun, ref: CosimRun, length: float, ref_torque_peak: float) -> dict:
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


# ------------------------------------------------------------------------------ runs as tasks
def run_settings(settings: CosimSettings) -> str:
    """The settings that define a run, as the task option `settings` (JSON text)."""
    return json.dumps({k: getattr(settings, k) for k in RUN_SETTINGS}, sort_keys=True)


_CASES: dict[str, tuple[CosimCase, dict]] = {}  # per worker process: a case's FMUs are built once (`_case`)


def _case(kind: str, model_path, settings: CosimSettings) -> tuple[CosimCase, dict]:
    """The case with its FMUs, built once per process into a temporary directory (and the compliant
    B5's, on its first run): they are a function of the key (model bytes, overrides, run settings),
    and building takes longer than many runs."""
    key = hashlib.sha256(Path(model_path).read_bytes() + json.dumps(
        [kind, list(settings.overrides), run_settings(settings)]).encode()).hexdigest()
    if key not in _CASES:
        fmu_dir = Path(tempfile.mkdtemp(prefix=f"ffrf_cosim_{kind}_"))
        _CASES[key] = (CosimCase(kind, model_path, fmu_dir, settings), {"fmu_dir": fmu_dir})
    return _CASES[key]


def run_task(model_path: str, overrides: Sequence[str], opts: dict) -> dict:
    """One run of the map (task runner "cosim"): options case, H, scheme (a SCHEMES label or
    REFERENCE) and settings (run_settings)."""
    raw = json.loads(opts["settings"])
    raw["implicit_tolerance"] = tuple(raw["implicit_tolerance"])
    settings = CosimSettings(**raw, overrides=tuple(overrides))
    kind, H, label = opts["case"], float(opts["H"]), opts["scheme"]
    case, extra = _case(kind, model_path, settings)
    if label == REFERENCE:
        run = (case.run(H, "gauss-seidel", iterations=settings.implicit_iterations) if kind == "motor"
               else case.run(H, one_body=True))
    elif label == COMPLIANT[0]:  # the shaft moves into the beam FMU (docs/cosim.md)
        from . import compliant_b5

        if "compliant" not in extra:
            extra["compliant"] = compliant_b5.build(model_path, extra["fmu_dir"], settings)
        run = compliant_b5.run_master(extra["compliant"], settings, H, case.duration)
    else:
        _, scheme, extrap, order = SCHEMES[label]
        run = case.run(H, scheme, extrap, order, iterations=settings.implicit_iterations if label == IMPLICIT[0] else 1,
                       interface_jacobian=label == INTERFACE_JACOBIAN[0])
    return {**run.as_result(), "length": case.length}


def cosim_map(model_path, settings: CosimSettings, out_dir, *, cases=("motor", "split"),
              implicit_steps: Sequence[float] = (0.002, 0.01, 0.04), sweep: SweepOptions = SweepOptions()) -> list[dict]:
    """Communication step against coupling scheme for the motor and the split systems; one CSV row
    per run. Monolithic references (docs/stability.md): motor -> the same two FMUs with implicit
    (iterated) coupling at H = the beam's internal step; split -> the one-body FMU at the same H."""
    opts = {"settings": run_settings(settings)}
    ov = list(settings.overrides)

    def task(kind, H, label):
        return make_task(model_path, ov, None, "cosim", case=kind, H=float(H), scheme=label, **opts)

    refs, runs, notes = {}, [], {}
    for kind in cases:
        schemes = [*settings.schemes, IMPLICIT, INTERFACE_JACOBIAN, *([COMPLIANT] if kind == "motor" else [])]
        for H in (settings.steps if kind == "motor" else settings.split_steps):
            H_ref = settings.reference_step if kind == "motor" else H
            if (kind, H_ref) not in refs:
                refs[kind, H_ref] = t = task(kind, H_ref, REFERENCE)
                notes[t.key] = f"{kind}: monolithic reference at H = {H_ref:g} s"
            for label, *_ in schemes:
                if label == IMPLICIT[0] and kind == "motor" and not any(abs(H - h) < 1e-12 for h in implicit_steps):
                    continue
                runs.append((kind, H, H_ref, label, t := task(kind, H, label)))
                notes[t.key] = f"{kind} H = {H:g} s {label}"
    results = run_tasks([*refs.values(), *(r[-1] for r in runs)], out_dir, "co-simulation map", notes, sweep)
    rows, series = [], {}
    for (kind, H_ref), t in refs.items():
        r = results[t.key]
        if not r.get("completed") or r.get("stopped_early"):
            raise RuntimeError(f"{kind}: the monolithic reference failed: {r.get('stopped_early') or r['failure']}")
        run = CosimRun.of(r)
        rows.append({"case": kind, "scheme": REFERENCE, "H": H_ref, "rel_error": 0.0, "unstable": False,
                     "failure": "", "t_end": float(run.t[-1]), "sweeps": run.sweeps, "wall_time_s": run.wall_time_s})
        series[f"{kind}_reference_H{H_ref:g}"] = np.column_stack([run.t, run.deflection, run.speed, run.torque])
    for kind, H, H_ref, label, t in runs:
        r, ref = results[t.key], CosimRun.of(results[refs[kind, H_ref].key])
        if not r.get("completed"):  # the run could not start (an FMU failed to build, ...): a row with its cause
            rows.append({"case": kind, "scheme": label, "H": float(H), "unstable": True, "failure": r["failure"]})
            continue
        run = CosimRun.of(r)
        rows.append({"case": kind, "scheme": label, "H": float(H),
                     **compare(run, ref, r["length"], float(np.max(np.abs(ref.torque))))})
        series[f"{kind}_{label}_H{H:g}"] = np.column_stack([run.t, run.deflection, run.speed, run.torque])
    write_map(out_dir, rows, series)
    return rows
