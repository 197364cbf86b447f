"""The co-simulation map's two coupled systems (cosim.py has the map): their FMUs, their runs under
ffrf_fmu.master and under libcosim, and the settings of both.

 motor: the beam FMU (the beam's free scene: hub rotation force-driven, translation motion-driven)
        joined at its hub port to the hub drive FMU (ffrf_fmu.examples: hub inertia, motor, PI speed
        controller on the Wu-Haug profile, torsional shaft to the beam root);
 split: the beam cut at its middle boundary node into two body FMUs (split.py), A (hub
        motion-driven by the Wu-Haug law, cut force-driven) and B (cut motion-driven, tip free).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ...fmu.variables import port_variables
from ...model import load_model
from ...runtime.outputs import tip_from_hub
from ..runners import transverse
from .benchmarks import B5, CoupledBeam

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


def _vec(prefix: str, port: str, fld: str) -> list[str]:
    return port_variables(f"{prefix}.{port}", fld)


def _rotz(phi: np.ndarray) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    R = np.zeros((len(phi), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def tip_deflection(R_hub: np.ndarray, r_hub: np.ndarray, r_tip: np.ndarray, X_tip: np.ndarray) -> np.ndarray:
    """Transverse elastic tip deflection (eq. 92) from the hub frame and the tip position histories."""
    d = tip_from_hub(R_hub, r_hub, r_tip, X_tip)
    return transverse(d, X_tip / np.linalg.norm(X_tip))


def hub_profile(model, beam: CoupledBeam) -> dict:
    """The parameters of the driven scene's hub spin-up (haug_spinup: omega, T)."""
    sc = model.scene(beam.driven_scene)
    drive = next((d for d in sc.drives if d.port == beam.hub and d.rotation), None)
    if drive is None or drive.rotation.angle.kind != "haug_spinup":
        raise ValueError(f"scene {sc.name}: the co-simulation map needs a haug_spinup rotation drive on port "
                         f"{beam.hub!r} (CosimSettings.beam)")
    return dict(drive.rotation.angle.params)


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
    beam: CoupledBeam = B5  # the beam model's scenes and ports the cases use (benchmarks.py)


#: the settings that define a run (the rest choose which runs the map makes): a task's options
RUN_SETTINGS = ("T", "duration", "split_T", "split_duration", "split_internal_is_H", "implicit_iterations",
                "implicit_tolerance", "drive", "reference_step", "beam_step", "beam")


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
        from ...fmu.builder import build_fmu
        from .split import split_models

        self.kind, self.settings = kind, settings
        b = self.beam = settings.beam
        fmu_dir = Path(fmu_dir)
        fmu_dir.mkdir(parents=True, exist_ok=True)
        ov = list(settings.overrides)
        model = load_model(model_path, ov)
        self.length = model.body.length
        self.X_tip = np.array([self.length, 0.0, 0.0])
        if kind == "motor":
            from ...examples import build_hub_drive

            self.fmus = {"beam": build_fmu(model_path, fmu_dir / "beam_hub_free.fmu", scene=b.free_scene,
                                                  overrides=[*ov, f"scenes.{b.free_scene}.duration={settings.duration!r}"]),
                         "drive": build_hub_drive(fmu_dir / "hub_drive.fmu")}
            self.order = {"fwd": ["beam", "drive"], "rev": ["drive", "beam"]}
            self.start_values = {**{f"drive.{k}": v for k, v in settings.drive.items()},
                                 "drive.profile.T": settings.T}
            omega = self._profile(model)["omega"]
            self.start_values["drive.profile.omega"] = omega
            self.duration = settings.duration
        elif kind == "split":
            halves = split_models(model_path, fmu_dir, ov, scene=b.driven_scene, ports=(b.hub, b.tip))
            self.fmus = {"A": build_fmu(halves[0], fmu_dir / "split_a.fmu"),
                         "B": build_fmu(halves[1], fmu_dir / "split_b.fmu")}
            sc = b.driven_scene
            ov = [*ov, f"scenes.{sc}.drives.{b.hub}.rotation.angle.T={settings.split_T!r}",
                  f"scenes.{sc}.duration={settings.split_duration!r}"]
            self.one = build_fmu(model_path, fmu_dir / "split_one_body.fmu", scene=sc, overrides=ov)
            self.order = {"fwd": ["A", "B"], "rev": ["B", "A"]}
            self.start_values = {}
            self.duration = settings.split_duration
            self.profile = {**self._profile(model), "T": settings.split_T}
        else:
            raise ValueError(f"unknown co-simulation case {kind!r}: motor or split")

    def _profile(self, model) -> dict:
        return hub_profile(model, self.beam)

    # ----------------------------------------------------------------------------- split helpers
    def _phi(self, t: np.ndarray) -> np.ndarray:
        from ...runtime.drives import evaluate

        return np.array([evaluate("haug_spinup", self.profile, float(x))[0] for x in t])

    def _hub_sources(self, prefix: str) -> Callable[[float], dict]:
        from ...runtime.drives import evaluate
        from ...runtime.rotation import expm

        names_R, names_w, names_dw = _vec(prefix, "hub", "R"), _vec(prefix, "hub", "w"), _vec(prefix, "hub", "dw")
        names_r, names_v = _vec(prefix, "hub", "r"), _vec(prefix, "hub", "v")

        def f(t):  # the drive with its acceleration: the body extrapolates it to second order (docs/cosim.md)
            phi, dphi, ddphi = evaluate("haug_spinup", self.profile, t)
            R = expm(np.array([0.0, 0.0, phi]))
            out = dict(zip(names_R, R.ravel()))
            out.update(zip(names_w, (0.0, 0.0, dphi)))
            out.update(zip(names_dw, (0.0, 0.0, ddphi)))
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
            interface_jacobian: bool = False, jacobian: str = "auto", accelerations: bool = False) -> CosimRun:
        """One co-simulation run of the case. accelerations: connect_ports(..., accelerations=True), the
        motion-driven side's extrapolation gets the force-driven side's P.a / P.dw (docs/cosim.md)."""
        from ...master import CoSimulation

        duration = self.duration if duration is None else duration
        t0 = time.perf_counter()
        if self.kind == "motor":
            rec = _vec("beam", self.beam.hub, "R") + _vec("beam", self.beam.tip, "r") + [f"beam.{self.beam.hub}.w[3]", "drive.drive.shaft_torque"]
            sv = {**self.start_values, "beam.solver.step": min(H, self.settings.beam_step)}
            with CoSimulation(self.fmus, step=H, scheme=scheme, extrapolation=extrapolation, order=self.order[order],
                              start_values=sv, **self._implicit(iterations),
                              interface_jacobian=interface_jacobian, jacobian=jacobian) as sim:
                sim.connect_ports("beam", self.beam.hub, "drive", "hub", accelerations=accelerations)  # the drive FMU's port is "hub"
                res = sim.run(duration, record=rec)
            c = res.columns
            R = np.stack([c[n] for n in _vec("beam", self.beam.hub, "R")], -1).reshape(-1, 3, 3)
            speed, torque = c[f"beam.{self.beam.hub}.w[3]"], c["drive.drive.shaft_torque"]
            tip = _vec("beam", self.beam.tip, "r")
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
                    sim.connect_ports("A", "cut", "B", "cut", accelerations=accelerations)
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
        from ...master.ssp import body_port_connections

        if self.kind == "motor":
            hub = self.beam.hub
            joined = lambda src, dst, fields: [(a, b, 1.0) for f in fields for a, b in zip(_vec(*src, f), _vec(*dst, f))]  # noqa: E731
            conns = joined(("drive", "hub"), ("beam", hub), ("r", "v")) + joined(("beam", hub), ("drive", "hub"), ("R", "w"))
            conns += [("drive.drive.shaft_torque", f"beam.{self.beam.hub}.t[3]", 1.0)]  # = -drive.hub.t[3]; t[1], t[2] are 0
            start = {**self.start_values, "beam.solver.step": min(H, self.settings.beam_step)}
            record = [*_vec("beam", self.beam.hub, "R"), *_vec("beam", self.beam.tip, "r"), f"beam.{self.beam.hub}.w[3]", "drive.drive.shaft_torque"]
            sources = None
        else:
            conns = [(c.src, c.dst, c.factor) for c in body_port_connections("A", "cut", "B", "cut", self.fmus)]
            start = {f"{n}.solver.step": H for n in ("A", "B")} if self.settings.split_internal_is_H else {}
            record = [*_vec("B", "tip", "r"), "A.cut.t[3]"]
            sources = self._hub_sources("A")
        t, cols, stopped, wall = libcosim_run(self.fmus, conns, start, H, duration, record, work_dir, sources)
        r_tip = np.stack([cols[n] for n in record if ".tip.r[" in n], -1).reshape(-1, 3)
        if self.kind == "motor":
            R = np.stack([cols[n] for n in _vec("beam", self.beam.hub, "R")], -1).reshape(-1, 3, 3)
            speed, torque = cols[f"beam.{self.beam.hub}.w[3]"], cols["drive.drive.shaft_torque"]
        else:
            R = _rotz(self._phi(t))
            speed, torque = np.full(len(t), np.nan), cols["A.cut.t[3]"]
        d = tip_deflection(R, np.zeros_like(r_tip), r_tip, self.X_tip) if len(t) else np.zeros(0)
        return CosimRun(t, d, speed, torque, stopped, wall)
