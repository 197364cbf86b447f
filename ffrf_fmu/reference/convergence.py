"""Convergence study of the full-order reference on B1 (Haug's rotating beam, benchmarks.md).

    python -m ffrf_fmu.reference.convergence [--quick] [--elements 4,8,16,32] [--steps 0.01,0.005,0.002]

Prints a table: elements, step, max |transverse tip deflection from hub| (eq. 92), its relative
difference to the finest run, minimum axial tip displacement, wall time, Newton iterations per
step; then the effect of the rotary inertia (m22 = m33 = 22.7e-6, our default, vs the printed
22.7e-3) at the finest mesh and step of the table.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from ..model import Body, Drive, Initial, Port, RotationDrive, Scene, Section, TimeFunction
from .solver import simulate_reference, tip_from_hub

PUBLISHED = {"ODIN 16 el.": 0.5333, "Boer et al. 4 el.": 0.5388, "ODIN 4 el.": 0.5257}


def b1_body(m_rot: float = 22.7e-6, superelements: int = 1) -> Body:
    sec = Section(EA=5.03e6, GJ=435.0, EI2=566.0, EI3=566.0, m=0.201, m22=m_rot, m33=m_rot, GA2=1.94e6, GA3=1.94e6)
    ports = (Port("hub", 0, "motion", "motion"), Port("tip", superelements, "force", "force"))
    return Body("haug_beam", 8.0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), sec, superelements, 4, 6, ports)


def b1_scene(omega: float = 4.0, T: float = 15.0, duration: float = 20.0, step: float = 0.002,
             rho_inf: float = 0.8) -> Scene:
    angle = TimeFunction("haug_spinup", (("T", T), ("omega", omega)))
    drive = Drive("hub", rotation=RotationDrive((0.0, 0.0, 1.0), angle))
    return Scene("b1", duration, step, rho_inf, "linear", (0.0, 0.0, 0.0), (drive,), (), Initial(),
                 metrics="haug", outputs=("tip_from_hub",))


def b1_run(n_elements: int, step: float, m_rot: float = 22.7e-6, duration: float = 20.0, **kw):
    res = simulate_reference(b1_body(m_rot), b1_scene(duration=duration), n_elements=n_elements, step=step, **kw)
    d = tip_from_hub(res)
    return res, d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--elements", default="4,8,16,32")
    ap.add_argument("--steps", default="0.02,0.01,0.005,0.002,0.001")
    ap.add_argument("--quick", action="store_true", help="elements 4,8,16 and steps 0.01,0.002")
    a = ap.parse_args(argv)
    els = [4, 8, 16] if a.quick else [int(x) for x in a.elements.split(",")]
    steps = [0.01, 0.002] if a.quick else [float(x) for x in a.steps.split(",")]
    rows = []
    print(f"{'elements':>8} {'step [s]':>9} {'max defl [m]':>13} {'axial min [m]':>14} {'wall [s]':>9} "
          f"{'cpu [s]':>8} {'newton/step':>11}")
    for ne in els:
        for h in steps:
            res, d = b1_run(ne, h)
            row = (ne, h, float(np.abs(d[:, 1]).max()), float(d[:, 0].min()), res.wall_time_s,
                   res.info["cpu_time_s"], res.newton_iterations_mean)
            rows.append(row)
            print(f"{row[0]:>8d} {row[1]:>9.4g} {row[2]:>13.6f} {row[3]:>14.6f} {row[4]:>9.2f} {row[5]:>8.2f} "
                  f"{row[6]:>11.2f}", flush=True)
    best = rows[-1]
    print(f"\nrelative to the finest run ({best[0]} elements, h = {best[1]:g} s: {best[2]:.6f} m):")
    for r in rows:
        print(f"{r[0]:>8d} {r[1]:>9.4g} {100 * (r[2] / best[2] - 1):>+9.3f} %")
    for k, v in PUBLISHED.items():
        print(f"  vs {k} {v}: {100 * (best[2] / v - 1):+.2f} %")
    res, d = b1_run(best[0], best[1], m_rot=22.7e-3)
    md = float(np.abs(d[:, 1]).max())
    print(f"\nrotary inertia m22 = m33 = 22.7e-3 (printed) instead of 22.7e-6: max deflection {md:.6f} m "
          f"({100 * (md / best[2] - 1):+.3f} %), {best[0]} elements, h = {best[1]:g} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
