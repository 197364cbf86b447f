"""A small fixed-step co-simulation master over fmpy's FMU2Slave.

Modules, one idea each: `instance` (an FMU under fmpy: names, values, log, derivatives), `links`
(connections and body-port wiring), `schemes` (the master: Jacobi, Gauss-Seidel, extrapolation,
implicit coupling), `interface` (linearly implicit coupling with interface Jacobians).

    sim = CoSimulation({"A": "a.fmu", "B": "b.fmu"}, step=1e-3, scheme="gauss-seidel")
    sim.connect_ports("A", "cut", "B", "cut")        # body port to body port, both parts
    sim.connect("ctrl.torque", "A.hub.t[3]")         # any output to any input, held
    result = sim.run(stop_time=2.0, sources=lambda t: {"A.hub.R[1,1]": ...})

Names are "<instance>.<variable>". Each communication step [t_c, t_c + H]:

- `jacobi`: every FMU gets its inputs from values at t_c, then every FMU steps.
- `gauss-seidel`: the FMUs step one after the other in `order`; an FMU whose source has
  already stepped gets the source's fresh values at t_c + H, otherwise the values at t_c.

Two kinds of connection:
- `Signal`: dst <- gain * src; the receiver keeps the value over the step. Stale (source not yet
  stepped): the value at t_c, or with `extrapolation=True` the value at t_c + H/2 of the line
  through the source's values at t_c - H and t_c. Fresh: the value at t_c + H (with
  extrapolation, explicit coupling: the mean of the values at t_c and t_c + H).
- `Motion`: a frame with its rate, (r, v) or (R, w), for body FMUs, which extrapolate
  r_c + v_c (t - t_c) and expm((t - t_c) skew(w_c)) R_c (docs/fmu.md). Stale: the source's
  frame and rate at t_c. Fresh: (r_1 - H v_1, v_1) and (expm(-H w_1) R_1, w_1) from the
  source's frame and rate at t_c + H, so that the receiver's extrapolation ends exactly on the
  source's frame and rate. With accelerations (`connect_ports(..., accelerations=True)`: (a, dw)
  from a force-driven part's outputs) the receiver extrapolates to second order; stale: the
  source's a at t_c; fresh: (r_1 - v_1 H + a_1 H^2/2, v_1 - a_1 H, a_1) and
  (expm(-(w_1 H - dw_1 H^2/2)) R_1, w_1 - dw_1 H, dw_1), ending on the source's frame and rate again.

`iterations > 1` makes the coupling implicit: the FMU states are saved at t_c and the sweep is
repeated from them until the held inputs that came from stale sources equal what their sources
give at t_c + H (relative `tolerance`), with IQN-ILS acceleration. For two bodies joined at a
node this solves the same discrete equations as the one-body run (the node equilibrium at
t_c + H), which explicit coupling cannot: its one-step lag of the interface force makes the
split beam unstable (added-mass effect) whatever the step.

`interface_jacobian=True` is linearly implicit coupling with a coupling Jacobian from the FMUs'
directional derivatives or from finite differences (master/interface.py).

`body_port_links` wires two body ports (docs/fmu.md): the motion-driven side receives the frame of
the force-driven side; the force-driven side receives minus the reaction of the motion-driven
side (the force on one body is the opposite of the force on the other).
"""
from .instance import CoSimulationError, FmuInstance
from .links import Motion, Signal, body_port_links, port_causality
from .schemes import CoSimulation, Result

__all__ = ["CoSimulation", "CoSimulationError", "FmuInstance", "Motion", "Result", "Signal", "body_port_links",
           "port_causality"]


def __getattr__(name: str):
    """The signal connection was called `Held`; the name is refused so that "held" keeps one meaning
    (an input kept constant over a communication step); an ImportError, so that `from ... import` shows it."""
    if name == "Held":
        raise ImportError("ffrf_fmu.master.Held is now ffrf_fmu.master.Signal (dst <- gain * src, a signal "
                             "connection; its receiver holds the value over the step)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
