"""Our scenes on Exudyn's 3D geometrically exact beam: a full-order nonlinear peer in C++.

    simulate(body, scene, n_elements, step) -> PeerResult (port histories like the reference's)

Model (Exudyn >= 1.12; ObjectBeamGeometricallyExact, Exudyn's "Beam3D"):
- n_elements two-node shear-deformable Simo-Reissner elements of equal length along the body's
  axis, section stiffness C = diag(EA, GA2, GA3, GJ, EI2, EI3), mass per length m, sectional
  inertia diag(m11, m22, m33) (m11 None -> m22 + m33) -- the same section data as our FE beam and
  the in-house reference (ffrf_fmu.reference). The element needs GA2/GA3 (no Euler-Bernoulli
  limit): a section without them is refused.
- Nodes: NodeRigidBodyEP (position + Euler parameters), reference orientation = the section
  frame of the reference's convention (axis 1 along the beam, axis 2 = normalize(e_z x axis 1)).
  Not NodeRigidBodyRotVecLG (Exudyn's Lie-group nodes): with Exudyn 1.13.6 every variant we tried
  (Lie-group nodes everywhere or all but the driven one; lieGroupSimplifiedKinematicRelations and
  lieGroupAddTangentOperator on and off; modified and full Newton; dense and sparse solvers)
  stops in the first Newton iteration of B1's spin-up (the residual grows 10^2 x and then stays),
  while the same beam with Lie-group nodes under a dead tip load runs. With Euler-parameter nodes
  Exudyn's generalized-alpha is the index-3 Arnold-Bruls scheme on the coordinate vector, with the
  same rho_inf; the step-size error it adds is measured by the sweep like ours.
- Motion-driven ports: an ObjectJointGeneric between the ground and the port node, locking the
  driven parts (translation, rotation); a drive enters as the joint's offset function
  (translation offset u(t) e in world axes; rotation offset phi(t) about the joint's z axis, which
  rotationMarker0/1 turn onto the drive's axis). Haug's spin-up (drives.py, "haug_spinup") is a
  symbolic user function evaluated in C++ (no Python call per residual); other time functions run
  as a Python callback (slower: the timings then include Python).
- Integrator: generalized-alpha, spectralRadius = scene.rho_inf, constant step (adaptiveStep off:
  a failing Newton is a failed run, as ours), sparse LU (EigenSparse: 1.8x faster than the dense
  solver at 16 elements, the same results to 1e-11), one thread (parallel.numberOfThreads = 1):
  one core against one core.
- Newton (NEWTON, NEWTON_REL_TOL, NEWTON_ABS_TOL): Exudyn's fastest setting that keeps B1's maximum
  tip deflection within 3e-6 (relative) of full Newton at 1e-8, measured on 8 s of B1 at 4 el./20 ms,
  16 el./10 ms, 8 el./2 ms: modified Newton with a fresh Jacobian every step (Exudyn's predictor
  leaves residuals of ~150 N on the spinning beam, and a Jacobian kept over steps no longer points
  the right way: 6-8 iterations per step; fresh each step: 2.5-4.7), relative tolerance 1e-7,
  absolute 1e-6 N. 1.3-2.3x faster than full Newton, 1.1-1.6x faster than Exudyn's default
  modified Newton. Exudyn's default tolerances (1e-8 relative, 1e-10 absolute) are below the
  round-off floor of the residual of this stiff beam (EA = 5e6 N): Newton stalls and fails.

Outputs: per port r, R (relative to the reference orientation: R(0) = I, as the reference's
ports), v, w (world) at every step, recorded by Exudyn sensors (C++). Port forces are not
recorded. Loads, gravity and initial velocities/displacements are not supported (B1 has none):
NotImplementedError names what a scene asks for.
"""
from __future__ import annotations

import dataclasses
import math
import os
import time

import numpy as np

from ..model import Body, Scene
from ..runtime import drives
from ..runtime.outputs import port_variables
from ..runtime.steps import divides, whole_steps

NEWTON_REL_TOL = 1e-7  # see the module docstring: measured, not Exudyn's defaults
NEWTON_ABS_TOL = 1e-6
NEWTON = "modified-per-step"  # "modified" | "modified-per-step" (a fresh Jacobian every step) | "full"


@dataclasses.dataclass(frozen=True, eq=False)
class PeerResult:
    t: np.ndarray  # (nt,) recorded times (every step, from t = 0)
    ports: dict  # port -> {"r": (nt,3), "R": (nt,3,3), "v": (nt,3), "w": (nt,3)}
    wall_time_s: float  # SolveDynamic only (no model set-up)
    cpu_time_s: float
    completed: bool
    failure: str | None
    newton_iterations_mean: float
    jacobians: int
    info: dict


def section_frame(direction) -> np.ndarray:
    """Columns: section axes 1, 2, 3 in world axes (the reference's convention)."""
    a1 = np.asarray(direction, dtype=float)
    a1 = a1 / np.linalg.norm(a1)
    ez = np.array([0.0, 0.0, 1.0]) if abs(a1[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a2 = np.cross(ez, a1)
    a2 /= np.linalg.norm(a2)
    return np.column_stack([a1, a2, np.cross(a1, a2)])


def _frame_with_z(axis) -> np.ndarray:
    """A rotation matrix whose third column is the unit drive axis."""
    z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _unsupported(scene: Scene) -> list[str]:
    out = []
    if scene.loads:
        out.append("loads")
    if any(scene.gravity):
        out.append("gravity")
    ini = scene.initial
    if any(ini.velocity) or any(ini.angular_velocity) or ini.port_displacements:
        out.append("initial velocities/displacements")
    return out


def _symbolic_haug(omega: float, T: float):
    """phi(t) of drives.evaluate('haug_spinup') as an Exudyn offset user function for symbolic use."""
    import exudyn as exu

    esym = exu.symbolic
    two_pi = 2.0 * math.pi

    def offset(mbs, t, itemNumber, p):
        tau = t / T
        spinup = omega * T * (tau * tau / 2.0 + (esym.cos(two_pi * tau) - 1.0) / two_pi**2)
        return [0, 0, 0, 0, 0, esym.IfThenElse(t < T, spinup, omega * T * (tau - 0.5))]

    return offset


def _python_offset(drive):
    """Offset user function (Python callback) of a drive: translation in world axes, rotation angle."""
    tr, rot = drive.translation, drive.rotation
    e = np.asarray(tr.direction, float) / np.linalg.norm(tr.direction) if tr else np.zeros(3)

    def offset(mbs, t, itemNumber, p):
        u = drives.evaluate(tr.displacement.kind, dict(tr.displacement.params), t)[0] if tr else 0.0
        phi = drives.evaluate(rot.angle.kind, dict(rot.angle.params), t)[0] if rot else 0.0
        return [*(u * e), 0.0, 0.0, phi]

    return offset


def build(body: Body, scene: Scene, n_elements: int):
    """The Exudyn system of `body` in `scene`: (SystemContainer, MainSystem, port node numbers,
    keep-alive list of symbolic functions). Raises ValueError/NotImplementedError with the cause."""
    import exudyn as exu
    from exudyn.itemInterface import (GenericJoint, MarkerBodyRigid, MarkerNodeRigid, NodeRigidBodyEP,
                                      ObjectBeamGeometricallyExact, ObjectGround)
    from exudyn.rigidBodyUtilities import RotationMatrix2EulerParameters

    from exudyn.advancedUtilities import CreateSymbolicUserFunction

    missing = _unsupported(scene)
    if missing:
        raise NotImplementedError(f"exudyn peer: scene {scene.name!r} has {', '.join(missing)}; "
                                  "the peer runs drive-only scenes (B1)")
    sec = body.section
    if sec.GA2 is None or sec.GA3 is None:
        raise ValueError("exudyn peer: ObjectBeamGeometricallyExact is shear deformable; the section needs GA2 and GA3")
    ne, n_se = int(n_elements), body.superelements
    off_mesh = [p.name for p in body.ports if p.node * ne % n_se]
    if ne < 1 or off_mesh:
        raise ValueError(f"exudyn peer: {ne} elements put no node at port(s) {', '.join(off_mesh)} "
                         f"(boundary nodes of {n_se} superelements): use a multiple of {n_se}")
    bs = exu.BeamSection()
    bs.stiffnessMatrix = np.diag([sec.EA, sec.GA2, sec.GA3, sec.GJ, sec.EI2, sec.EI3])
    bs.massPerLength = sec.m
    bs.inertia = np.diag([sec.m11 if sec.m11 is not None else sec.m22 + sec.m33, sec.m22, sec.m33])

    R0 = section_frame(body.direction)
    axis = R0[:, 0]
    x0 = np.asarray(body.origin, float)
    le = body.length / ne
    ep0 = list(RotationMatrix2EulerParameters(R0))
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    nodes = [mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(x0 + k * le * axis) + ep0)) for k in range(ne + 1)]
    for k in range(ne):
        mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[nodes[k], nodes[k + 1]], length=le, sectionData=bs))
    ground = mbs.AddObject(ObjectGround())
    drive_of = {d.port: d for d in scene.drives}
    port_nodes, keep = {}, []
    for p in body.ports:
        node = nodes[p.node * ne // n_se]
        port_nodes[p.name] = node
        locked = [int(p.translation == "motion")] * 3 + [int(p.rotation == "motion")] * 3
        if not any(locked):
            continue
        drive = drive_of.get(p.name)
        Q = _frame_with_z(drive.rotation.axis) if drive and drive.rotation else np.eye(3)
        m0 = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=list(x0 + p.node * body.length / n_se * axis)))
        m1 = mbs.AddMarker(MarkerNodeRigid(nodeNumber=node))
        joint = mbs.AddObject(GenericJoint(markerNumbers=[m0, m1], constrainedAxes=locked, rotationMarker0=Q,
                                           rotationMarker1=R0.T @ Q))
        if drive is None:
            continue
        rot = drive.rotation
        if drive.translation is None and rot is not None and rot.angle.kind == "haug_spinup":
            prm = dict(rot.angle.params)
            fn = CreateSymbolicUserFunction(mbs, _symbolic_haug(prm["omega"], prm["T"]), "offsetUserFunction", joint)
            keep.append(fn)  # the expression tree must outlive the run (Exudyn's note)
        else:
            fn = _python_offset(drive)
        mbs.SetObjectParameter(joint, "offsetUserFunction", fn)
    return SC, mbs, port_nodes, keep


def simulate(body: Body, scene: Scene, n_elements: int, step: float | None = None, *,
             rel_tol: float = NEWTON_REL_TOL, abs_tol: float = NEWTON_ABS_TOL,
             newton: str = NEWTON) -> PeerResult:
    """Run `scene` (its duration and rho_inf; `step` or the scene's) on n_elements Exudyn beams."""
    import exudyn as exu
    from exudyn.itemInterface import SensorNode

    h = float(step or scene.step)
    n_steps = whole_steps(scene.duration, h).n
    if not divides(scene.duration, h):
        raise ValueError(f"exudyn peer: step {h:g} s does not divide the duration {scene.duration:g} s")
    SC, mbs, port_nodes, keep = build(body, scene, n_elements)
    ovt = exu.OutputVariableType
    fields = {"r": ovt.Position, "R": ovt.RotationMatrix, "v": ovt.Velocity, "w": ovt.AngularVelocity}
    sensors = {(p, f): mbs.AddSensor(SensorNode(nodeNumber=n, storeInternal=True, outputVariableType=o))
               for p, n in port_nodes.items() for f, o in fields.items()}
    mbs.Assemble()

    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.numberOfSteps, ti.endTime = n_steps, scene.duration
    ti.generalizedAlpha.spectralRadius = scene.rho_inf
    ti.newton.useModifiedNewton = newton != "full"
    ti.newton.modifiedNewtonJacUpdatePerStep = newton == "modified-per-step"
    ti.newton.relativeTolerance, ti.newton.absoluteTolerance = rel_tol, abs_tol
    ti.adaptiveStep = False
    ti.verboseMode = int(os.environ.get("FFRF_EXUDYN_VERBOSE", "0"))
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = h
    ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    ss.parallel.numberOfThreads = 1

    failure = None
    w0, c0 = time.perf_counter(), time.process_time()
    try:
        mbs.SolveDynamic(ss, storeSolver=True, showHints=False)
    except Exception as e:  # noqa: BLE001 - Exudyn's SolverError: a failed run is a result
        failure = f"{type(e).__name__}: {e}"
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    del keep
    solver = mbs.sys.get("dynamicSolver")
    it = solver.it if solver is not None else None
    R0 = section_frame(body.direction)
    ports, t = {}, None
    for p in port_nodes:
        ports[p] = {}
        for f in fields:
            data = np.asarray(mbs.GetSensorStoredData(sensors[(p, f)]))
            t = data[:, 0]
            vals = data[:, 1:]
            # RotationMatrix sensors are row-major; report R relative to the reference orientation
            ports[p][f] = vals.reshape(-1, 3, 3) @ R0.T if f == "R" else vals
    steps_done = max(len(t) - 1, 1)
    completed = failure is None and abs(t[-1] - scene.duration) <= 1e-9 * scene.duration
    if failure is None and not completed:
        failure = f"stopped at t = {t[-1]:.6g} s"
    return PeerResult(
        t=t, ports=ports, wall_time_s=wall, cpu_time_s=cpu, completed=completed, failure=failure,
        newton_iterations_mean=(it.newtonStepsCount / steps_done) if it is not None else math.nan,
        jacobians=int(it.newtonJacobiCount) if it is not None else -1,
        info={"n_elements": int(n_elements), "step": h, "rho_inf": scene.rho_inf, "rel_tol": rel_tol,
              "abs_tol": abs_tol, "newton": newton, "exudyn": exu.__version__, "nodes": "NodeRigidBodyEP",
              "solver": "generalized-alpha (index 3), modified Newton, EigenSparse, 1 thread"})


def columns(result: PeerResult) -> dict[str, np.ndarray]:
    """Port histories as result columns named like the FMU variables (simulate.SimulationResult)."""
    out = {}
    for p, flds in result.ports.items():
        for f, arr in flds.items():
            out |= dict(zip(port_variables(p, f), arr.reshape(len(arr), -1).T))
    return out


def run_configuration(model_path: str, scene_name: str | None, base_overrides, values: dict) -> dict:
    """One peer run as a chart row source (runners.run_configuration's dict): values {"elements", "step"}
    (texts or numbers; step default: the scene's). Runs in a chart worker; never raises."""
    import traceback

    from .. import simulate as sim
    from ..model import load_model, scene_body
    from ..reduction import reduce_scene_body

    out = {"values": dict(values), "runner": "exudyn", "completed": False, "failure": None}
    try:
        model = load_model(model_path, list(base_overrides))
        sc = model.scene(scene_name)
        n_el = int(values["elements"])
        h = float(values.get("step") or sc.step)
        out["resolved"] = {"elements": n_el, "step": h}
        res = simulate(scene_body(model.body, sc), sc, n_el, h)
        result = sim.SimulationResult(res.t, columns(res), {}, reduce_scene_body(model.body, sc).data)
        out |= {"wall_time_s": res.wall_time_s, "cpu_time_s": res.cpu_time_s, "completed": res.completed,
                "failure": res.failure, "t_end_s": float(res.t[-1]),
                "newton_iterations_mean": res.newton_iterations_mean, "metrics": sim.metrics(result, sc),
                "t": np.asarray(res.t), "d": sim.tip_trajectory(result, sc)}
    except Exception as e:  # noqa: BLE001 - a configuration that cannot run is a chart row, not a crash
        out["failure"] = f"{type(e).__name__}: {e}"
        out["traceback"] = traceback.format_exc(limit=4)
    return out
