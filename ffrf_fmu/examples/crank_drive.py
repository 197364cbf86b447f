"""The conrod in a crank drive (models/conrod_crank.toml; docs/inertia-terms.md, "The conrod in a crank
drive"): the conrod FMU between a rigid crank at an imposed speed (`crank_pin_slave.py`) and a piston
with the gas force (`piston_slave.py`), as an SSP system for every engine, and its monolithic reference.

The system (world axes; mechanism plane Y-Z, crank axis X through (0, -r, 0), cylinder axis Y):
- crank pin -> big eye (translation motion-driven, rotation free): r, v, a of the pin;
- piston <-> small eye: the small eye is `compliant` (pin spring k [N/m] in world axes: along Y the
  gudgeon pin to the piston mass, across it the piston's guide; rotational k_rot about the nodal Y, Z
  axes: the pin holds the conrod in its plane); its far end is the piston's pin frame (r, v, a, R, w,
  dw), and the spring's force on the conrod goes to the piston (which feels minus it). The spring is
  integrated implicitly inside the conrod FMU (docs/cosim.md, "Compliant coupling"); it lags only on
  the piston, one communication step, so a Jacobi engine is stable while sqrt(k / m_p) H stays below
  ~1 (the rule's omega_c H = 0.5; here 22361 rad/s x 1e-5 s = 0.22).

Deformation at mid-shank (`deformation`): from the world positions of the big eye's frame P_b (the
crank pin), the small eye's node frame P_s and the mid-shank averaging frame P_m (the least-squares rigid
fit of the shank nodes between y = 85 and 95 mm), with the chord e = (P_s - P_b) / |P_s - P_b| and its
in-plane normal n = X x e:
    axial   = (P_m - P_b) . e - Y_MID          stretch of the conrod from the big eye to mid-shank
    bending = (P_m - P_b) . n                  deflection of mid-shank from the chord through the eyes
both zero in the reference configuration (Y_MID = 0.090 m).

Monolithic reference: `crank_monolithic.py`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import build_script_fmu

HERE = Path(__file__).resolve().parent
MODEL = HERE.parents[1] / "models" / "conrod_crank.toml"
CRANK_SOURCE = HERE / "crank_pin_slave.py"
PISTON_SOURCE = HERE / "piston_slave.py"
Y_MID = 0.090  # m: the mid-shank frame's reference position on the conrod axis (models/conrod_crank.toml)
L_EYES = 0.155  # m: eye centre distance


@dataclass(frozen=True)
class CrankDrive:
    """Parameters of the crank drive (the partners' FMU parameters of the same names)."""

    r: float = 0.01  # crank radius [m]
    omega: float = 5000.0  # crank speed after the run-up [rad/s] (795.8 Hz)
    T: float = 2.5e-3  # run-up time [s] (omega T / 2 = 6.25 rad: one revolution)
    m_p: float = 0.2  # piston mass [kg]
    F_max: float = 2.0e4  # peak gas force [N]
    width: float = math.pi / 3  # crank angle of the gas force pulse after top dead centre [rad]

    def crank_parameters(self) -> dict[str, float]:
        return {"crank.r": self.r, "crank.omega": self.omega, "crank.T": self.T}

    def piston_parameters(self) -> dict[str, float]:
        return {"piston.m": self.m_p, "crank.omega": self.omega, "crank.T": self.T, "gas.F_max": self.F_max,
                "gas.width": self.width}


@dataclass(frozen=True)
class CrankRun:
    """A run of the crank drive: per sample time t, crank angle [rad], the mid-shank deformation
    (axial, bending [m], module doc), the piston's displacement [m] and the pin spring's force on the
    conrod along the cylinder axis [N]; stopped: "" or why it ended early; wall: seconds."""

    t: np.ndarray
    angle: np.ndarray
    axial: np.ndarray
    bending: np.ndarray
    piston: np.ndarray
    pin_force: np.ndarray
    stopped: str = ""
    wall: float = 0.0


def build_crank(dest) -> Path:
    """The crank FMU (crank_pin_slave.py) into `dest` (a .fmu file or a directory)."""
    return build_script_fmu(CRANK_SOURCE, "CrankPin", "crank_pin", dest)


def build_piston(dest) -> Path:
    """The piston FMU (piston_slave.py) into `dest` (a .fmu file or a directory)."""
    return build_script_fmu(PISTON_SOURCE, "Piston", "piston", dest)


def _laws():
    """The partners' own laws (the slave scripts' functions, imported from their files)."""
    import importlib.util

    mods = []
    for src in (CRANK_SOURCE, PISTON_SOURCE):
        spec = importlib.util.spec_from_file_location(f"_ffrf_law_{src.stem}", src)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        mods.append(mod)
    return mods


def deformation(P_b, P_s, P_m) -> tuple[np.ndarray, np.ndarray]:
    """(axial, bending) at mid-shank from the frames' world positions (k, 3) (module doc)."""
    P_b, P_s, P_m = (np.atleast_2d(np.asarray(p, float)) for p in (P_b, P_s, P_m))
    e = P_s - P_b
    e /= np.linalg.norm(e, axis=1)[:, None]
    n = np.stack([np.zeros(len(e)), -e[:, 2], e[:, 1]], axis=1)  # X x e
    d = P_m - P_b
    return np.einsum("ij,ij->i", d, e) - Y_MID, np.einsum("ij,ij->i", d, n)


# ------------------------------------------------------------------------------------ the FMU system
@dataclass(frozen=True)
class CrankFmus:
    """The three FMU files of the system: the conrod (ffrf-fmu build of models/conrod_crank.toml),
    the crank and the piston."""

    conrod: Path
    crank: Path
    piston: Path

    def components(self) -> dict[str, str]:
        return {"conrod": str(self.conrod), "crank": str(self.crank), "piston": str(self.piston)}


def build(fmu_dir, model_path=MODEL, overrides=(), body=None) -> CrankFmus:
    """Build the conrod (native; from `body`, its reduced BodyData, when given: what fmu.build_fmu does
    after its reduction), crank and piston (pythonfmu) FMUs into fmu_dir."""
    from ..fmu.builder import build_fmu

    fmu_dir = Path(fmu_dir)
    fmu_dir.mkdir(parents=True, exist_ok=True)
    if body is None:
        conrod = build_fmu(model_path, fmu_dir / "conrod.fmu", scene="crank", overrides=list(overrides))
    else:
        from ..fmu.builder import SceneParameters, start_states
        from ..fmu.native import build_native_fmu
        from ..model import load_model

        model = load_model(model_path, list(overrides))
        sc = model.scene("crank")
        conrod = build_native_fmu(body, fmu_dir / "conrod.fmu", SceneParameters.of_scene(sc), origin=model.body.origin,
                                  start=start_states(body, sc, model.body.origin))
    return CrankFmus(Path(conrod), build_crank(fmu_dir / "crank_pin.fmu"), build_piston(fmu_dir / "piston.fmu"))


def reduced_body(model_path=MODEL, overrides=()):
    """The reduced BodyData of the model's first scene (what `build` and `monolithic` use)."""
    from ..model import load_model
    from ..reduction import reduce_scene_body

    model = load_model(model_path, list(overrides))
    return reduce_scene_body(model.body, model.scene()).data


def _vec(name: str) -> list[str]:
    return [f"{name}[{i}]" for i in (1, 2, 3)]


def _mat(name: str) -> list[str]:
    return [f"{name}[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]


#: probes of the conrod FMU (eq. 92: positions in the big eye's frame) from which `deformation` is taken
PROBES = ("conrod.probe.small_eye_from_big_eye", "conrod.probe.mid_shank_from_big_eye")
RECORD = [*_vec(PROBES[0]), *_vec(PROBES[1]), "crank.crank.angle", "piston.piston.x", "conrod.small_eye.f[2]"]


def connections() -> list[tuple[str, str, float]]:
    """(source, sink, gain): crank pin -> big eye (r, v, a); piston pin frame -> the small eye spring's
    far end (r, v, a, R, w, dw); the spring's force on the conrod -> the piston."""
    c = [(a, b, 1.0) for f in ("r", "v", "a") for a, b in zip(_vec(f"crank.pin.{f}"), _vec(f"conrod.big_eye.{f}"))]
    c += [(a, b, 1.0) for f in ("r", "v", "a", "w", "dw") for a, b in zip(_vec(f"piston.pin.{f}"), _vec(f"conrod.small_eye.{f}"))]
    c += [(a, b, 1.0) for a, b in zip(_mat("piston.pin.R"), _mat("conrod.small_eye.R"))]
    c += [(a, b, 1.0) for a, b in zip(_vec("conrod.small_eye.f"), _vec("piston.pin.f"))]
    return c


def parameters(drive: CrankDrive, H: float) -> dict[str, float]:
    """Start values: the partners' parameters and the conrod's internal step = H (docs/cosim.md: the
    body's internal step equal to the communication step)."""
    return {**{f"crank.{k}": v for k, v in drive.crank_parameters().items()},
            **{f"piston.{k}": v for k, v in drive.piston_parameters().items()}, "conrod.solver.step": H}


def system(fmus: CrankFmus, drive: CrankDrive, H: float, duration: float):
    """The crank drive as an SSP system (master/ssp.py)."""
    from ..master.ssp import Connection, System

    return System("crank_drive", fmus.components(), tuple(Connection(*c) for c in connections()),
                  parameters(drive, H), H, 0.0, duration)


def from_columns(t, cols, stopped: str = "", wall: float = 0.0) -> CrankRun:
    """A CrankRun from recorded RECORD columns (any engine)."""
    # a probe is R_B^T (r_A - r_B) - (X_A - X_B) (docs/fmu.md): add the frames' reference offsets
    P_s = np.stack([cols[n] for n in _vec(PROBES[0])], axis=1) + [0.0, L_EYES, 0.0]
    P_m = np.stack([cols[n] for n in _vec(PROBES[1])], axis=1) + [0.0, Y_MID, 0.0]
    ax, be = deformation(np.zeros_like(P_s), P_s, P_m)
    return CrankRun(np.asarray(t, float), np.asarray(cols["crank.crank.angle"]), ax, be,
                    np.asarray(cols["piston.piston.x"]), np.asarray(cols["conrod.small_eye.f[2]"]), stopped, wall)


def run_package(path, engine: str) -> CrankRun:
    """Run an SSP package of the crank drive under `engine` ("master", "libcosim", "ecos")."""
    from ..master.ssp import run_ssp

    r = run_ssp(path, engine, RECORD)
    return from_columns(r.t, r.columns, r.stopped, r.wall)


@dataclass(frozen=True)
class Deviation:
    """max |run - reference| over the run, over the reference's peak, of the axial and bending
    deformation, on the run's sample times (the reference sampled at the same times)."""

    axial: float
    bending: float


def deviation(run: CrankRun, ref: CrankRun) -> Deviation:
    """The run against the reference (Deviation); the reference is interpolated to the run's times."""
    out = []
    for name in ("axial", "bending"):
        x, xr = getattr(run, name), np.interp(run.t, ref.t, getattr(ref, name))
        out.append(float(np.max(np.abs(x - xr)) / np.max(np.abs(getattr(ref, name)))))
    return Deviation(*out)


# ------------------------------------------------------------------------------ frequencies in the drive
@dataclass(frozen=True)
class DriveMode:
    """A natural mode of the conrod in the drive at rest: frequency [Hz] and the largest displacement
    of the mid-shank frame along X, Y, Z and of the piston, each over the mode's largest coordinate."""

    frequency_hz: float
    mid_shank: tuple[float, float, float]
    piston: float


def drive_modes(body, drive: CrankDrive, model_path=MODEL, overrides=(), count: int = 6) -> list[DriveMode]:
    """Natural modes of the linearized drive at rest (linear.chain_matrices: the reduced body in
    physical coordinates): the big eye's translation held (the crank pin), the small-eye spring of the
    model file to the piston mass m_p along Y and to the guide across it, the pin's rotational
    stiffness; rigid modes (< 0.01 Hz) left out."""
    import scipy.linalg as sla

    from ..linear import _free, chain_matrices, motion_fixed_dofs
    from ..model import load_model

    K, M, nd = chain_matrices(body)
    port = {p.name: p for p in load_model(model_path, list(overrides)).body.ports}
    coupling = dict(port["small_eye"].coupling)
    k, k_rot = np.asarray(coupling["stiffness"], float), np.asarray(coupling["rotational_stiffness"], float)
    n = K.shape[0]
    Kd, Md = np.zeros((n + 1, n + 1)), np.zeros((n + 1, n + 1))
    Kd[:n, :n], Md[:n, :n], Md[n, n] = K, M, drive.m_p
    node = {q.name: q.node for q in body.ports}
    s = nd[node["small_eye"]]
    for i in range(3):
        Kd[s[i], s[i]] += k[i]
        Kd[s[3 + i], s[3 + i]] += k_rot[i]
    Kd[n, n] += k[1]
    Kd[s[1], n] -= k[1]
    Kd[n, s[1]] -= k[1]
    free = _free(n + 1, motion_fixed_dofs(body))
    w2, V = sla.eigh(Kd[np.ix_(free, free)], Md[np.ix_(free, free)])
    out, mid = [], nd[node["mid_shank"]]
    for j in np.argsort(w2):
        f = float(np.sqrt(abs(w2[j])) / (2 * np.pi))
        if f < 0.01:
            continue
        v = np.zeros(n + 1)
        v[free] = V[:, j]
        v /= np.abs(v).max()
        out.append(DriveMode(f, tuple(float(x) for x in v[mid[:3]]), float(v[n])))
        if len(out) == count:
            break
    return out
