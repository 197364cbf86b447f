"""Witteveen's generic structures GenStruct1 and GenStruct2 (his Table 1: extent 330 x 200 x 8 mm,
0.36 / 0.4 kg, 20 free modes, 6 interface modes) as quadratic-tet meshes. His are not published; ours
(mm, in the XY plane, thickness 8 along Z, the hub at the origin; docs/inertia-terms.md, "GenStruct1
and GenStruct2"):

  frame      a rectangular ring 330 x 200 outside, bars F = 14 wide; GenStruct1: both short sides
             cut through at y = 0 by a 4 mm slot
  hub        a disc of radius 15 at the centre
  y-arms     a bar 10 wide along Y from the hub to the middle of both long sides
  x-arms     GenStruct2 only: a bar 6.6 wide along X from the hub to the middle of both short sides

Spun about Z through the hub, GenStruct1's long sides are 165 mm cantilevers from the y-arms (the
slots free their ends), bent outwards in their plane by the centrifugal load: a structure soft against
centrifugal widening. GenStruct2's closed short sides tie the ends of the two long sides together
(tension, not bending), and its x-arms hold the short sides: the same frame without that sensitivity
(and heavier by the arms, as his 0.4 kg against 0.36 kg).
Written in metres as genstruct1.msh, genstruct2.msh (tet10, gmsh 2.2 ASCII).
Run: python models/data/genstruct/make_genstruct.py [out_dir]
"""
import sys
from pathlib import Path

from ffrf_fmu.solid.mesh import gmsh_model, write_tet10

LX, LY, T = 330.0, 200.0, 8.0  # extent [mm]
F = 14.0          # frame bar width
R_HUB = 15.0      # hub radius
W_Y = 10.0        # y-arm width
W_X = 6.6         # x-arm width (GenStruct2)
SLOT = 4.0        # GenStruct1: the gap cut through each short side at y = 0
H = 7.0           # element size


def build(out: Path, braced: bool) -> None:
    occ = gmsh_model("genstruct2" if braced else "genstruct1")
    z0 = -T / 2
    outer = occ.addBox(-LX / 2, -LY / 2, z0, LX, LY, T)
    inner = occ.addBox(-LX / 2 + F, -LY / 2 + F, z0 - 1, LX - 2 * F, LY - 2 * F, T + 2)
    cut = [(3, inner)]
    if not braced:  # the slots: each long side with its two half short sides is a C on its y-arm
        cut += [(3, occ.addBox(sx * LX / 2 - (F + 1) * (sx > 0), -SLOT / 2, z0 - 1, F + 1, SLOT, T + 2)) for sx in (-1, 1)]
    frame, _ = occ.cut([(3, outer)], cut)
    parts = [(3, occ.addCylinder(0, 0, z0, 0, 0, T, R_HUB)),
             (3, occ.addBox(-W_Y / 2, -LY / 2 + F / 2, z0, W_Y, LY - F, T))]
    if braced:
        parts.append((3, occ.addBox(-LX / 2 + F / 2, -W_X / 2, z0, LX - F, W_X, T)))
    occ.fuse(frame, parts)
    write_tet10(out, "genstruct", H)


if __name__ == "__main__":
    d = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent
    build(d / "genstruct1.msh", braced=False)
    build(d / "genstruct2.msh", braced=True)
