"""Witteveen's connecting rod (Table 1: extent 20 x 210 x 80 mm, 0.9 kg) as a quadratic-tet mesh.

Geometry (mm, the length along Y, the eye axes along X, thickness 20 along X):
  big eye    centre (0, 0, 0),   outer radius 40, bore radius 25
  small eye  centre (0, 155, 0), outer radius 15, bore radius 8
  shank      plain rectangular, 20 (X) x 22 (Z), from the big eye to the small eye
Extent: X 20, Y -40 .. 170 (210), Z -40 .. 40 (80). Written in metres to conrod.msh (tet10, gmsh 2.2
ASCII). Run: python models/data/conrod/make_conrod.py [out.msh]
"""
import sys
from pathlib import Path

from ffrf_fmu.solid.mesh import gmsh_model, write_tet10

T = 20.0          # thickness along X
R_BIG, r_BIG = 40.0, 25.0
R_SMALL, r_SMALL = 15.0, 8.0
L_EYES = 155.0    # centre distance
W_SHANK = 22.0    # shank width along Z
H = 7.0           # element size


def build(out: Path) -> None:
    occ = gmsh_model("conrod")
    x0 = -T / 2
    big = occ.addCylinder(x0, 0, 0, T, 0, 0, R_BIG)
    small = occ.addCylinder(x0, L_EYES, 0, T, 0, 0, R_SMALL)
    shank = occ.addBox(x0, 0.0, -W_SHANK / 2, T, L_EYES, W_SHANK)
    body, _ = occ.fuse([(3, big)], [(3, small), (3, shank)])
    hb = occ.addCylinder(x0 - 1, 0, 0, T + 2, 0, 0, r_BIG)
    hs = occ.addCylinder(x0 - 1, L_EYES, 0, T + 2, 0, 0, r_SMALL)
    occ.cut(body, [(3, hb), (3, hs)])
    write_tet10(out, "conrod", H)


if __name__ == "__main__":
    build(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("conrod.msh"))
