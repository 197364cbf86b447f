"""A generic car body of flat shells (models/car_body.toml; docs/inertia-terms.md, "The car body"):
Witteveen's car body is confidential (his Table 1: 3.8 x 1.5 x 1.1 m, 270 kg, 50 free modes, 4 interface
frames), so this one is ours: the surface of a 3.8 x 1.5 x 1.1 m box on a 0.1 m grid of quads, with

    floor        z = 0            3.0 mm, sills (the 0.2 m strips along both sides) 6 mm
    roof         z = 1.1 m        2.5 mm, roof rails (0.1 m strips along both sides) 6 mm
    sides        y = 0, 1.5 m     2.5 mm below the belt line z = 0.6 m (doors closed, as panels);
                                  above it window openings up to z = 1.0 m between the pillars, A
                                  (x 0-0.1 m), B (x 1.8-1.9 m) and C (x 3.7-3.8 m), and the header rail
                                  above them (z 1.0-1.1 m), 6 mm
    bulkheads    x = 0, 3.8 m     3.0 mm below the belt line; above it the windscreen and the rear
                                  window are open, framed by the A and C pillars' 0.1 m strips and the
                                  header (6 mm)

The thicknesses are those of equivalent flat plates: a car's panels are curved and beaded, its pillars,
sills and rails closed sections, which flat quads on a grid cannot draw; a flat 0.8 mm roof of this
size would flap at 2 Hz. Steel stiffness, E = 2.1e11 Pa, nu = 0.3; the density is chosen so that the
body weighs 270 kg (the equivalent plates are thicker than the sheet, so it is below steel's), printed
by this script.
Written: car_body.vtu (ASCII; quads, cell data `thickness` [m]). Run: python make_car_body.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

SIZE = (3.8, 1.5, 1.1)  # m
H = 0.1  # grid spacing [m]
BELT = 0.6  # belt line [m]
HEADER = 1.0  # the window openings end here [m]
PILLARS = ((0.0, 0.1), (1.8, 1.9), (3.7, 3.8))  # x ranges of the A, B, C pillars [m]
T_STRUCT = 0.006  # pillars, sills, roof rails, headers [m] (equivalent plates of closed sections)
STEEL_RHO = 7850.0
MASS = 270.0  # kg


def cells():
    """[(corner grid points (4, 3) ints, thickness)] of every quad of the body."""
    n = [round(s / H) for s in SIZE]
    out = []

    def face(axis, level, thick):
        a, b = [k for k in range(3) if k != axis]
        for i in range(n[a]):
            for j in range(n[b]):
                centre = np.zeros(3)
                centre[axis], centre[a], centre[b] = level * SIZE[axis], (i + 0.5) * H, (j + 0.5) * H
                t = thick(centre)
                if t is None:
                    continue
                pts = []
                for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    p = [0, 0, 0]
                    p[axis], p[a], p[b] = level * n[axis], i + di, j + dj
                    pts.append(p)
                out.append((np.array(pts), t))

    in_pillar = lambda x: any(lo <= x <= hi for lo, hi in PILLARS)  # noqa: E731
    face(2, 0, lambda c: T_STRUCT if (c[1] < 0.2 or c[1] > SIZE[1] - 0.2) else 0.003)  # floor, sills
    face(2, 1, lambda c: T_STRUCT if (c[1] < 0.1 or c[1] > SIZE[1] - 0.1) else 0.0025)  # roof, rails
    frame = lambda c: c[2] > HEADER  # noqa: E731  the header rails above the openings close the window frames
    side = lambda c: 0.0025 if c[2] < BELT else (T_STRUCT if in_pillar(c[0]) or frame(c) else None)  # noqa: E731
    face(1, 0, side)
    face(1, 1, side)
    bulk = lambda c: 0.003 if c[2] < BELT else (T_STRUCT if (c[1] < 0.1 or c[1] > SIZE[1] - 0.1 or frame(c))  # noqa: E731
                                                 else None)
    face(0, 0, bulk)
    face(0, 1, bulk)
    return out


def mesh():
    """(nodes (n, 3) [m], quads (e, 4), thickness (e,) [m]) with the grid points shared between faces."""
    quads, thickness, index = [], [], {}
    for pts, t in cells():
        quads.append([index.setdefault(tuple(p), len(index)) for p in pts])
        thickness.append(t)
    nodes = np.array(sorted(index, key=index.get), dtype=float) * H
    return nodes, np.array(quads), np.array(thickness)


def density(nodes, quads, thickness) -> float:
    """The density [kg/m^3] that makes the body weigh MASS (the quads are flat squares of H x H)."""
    area = np.full(len(quads), H * H)
    return MASS / float(area @ thickness)


def main():
    import meshio

    nodes, quads, thickness = mesh()
    rho = density(nodes, quads, thickness)
    here = Path(__file__).resolve().parent
    meshio.write(here / "car_body.vtu", meshio.Mesh(nodes, [("quad", quads)], cell_data={"thickness": [thickness]}),
                 binary=False)
    structure = STEEL_RHO * H * H * float(thickness.sum())
    print(f"{len(nodes)} nodes, {len(quads)} quads; the structure at {STEEL_RHO:g} kg/m^3 weighs {structure:.1f} kg; "
          f"density for {MASS:g} kg: {rho:.1f} kg/m^3")


if __name__ == "__main__":
    main()
