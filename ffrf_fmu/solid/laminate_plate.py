"""A laminated rectangular plate as a Nastran deck (GRID, CQUAD4, PCOMP, MAT8/MAT1) and the exact
Navier frequencies of a simply supported cross-ply plate (classical laminate theory and first-order
shear deformation): the references of the laminate checks (docs/shells.md, "Laminates").

Navier (Reddy, Mechanics of Laminated Composite Plates and Shells, 2nd ed. 2004, eqs. 5.3.12 (CLT)
and 6.3.x (FSDT)): a plate a x b of a laminate with D16 = D26 = 0 and B = 0 (symmetric cross-ply),
simply supported on all four edges (w = 0 and the tangential fibre rotation 0: "hard" support),
has the modes w = W sin(m pi x / a) sin(n pi y / b). CLT, without rotary inertia:
    omega_mn = pi^2 / a^2 sqrt((D11 m^4 + 2 (D12 + 2 D66) m^2 n^2 r^2 + D22 n^4 r^4) / m0),  r = a / b;
FSDT, with the fibre rotations phi_x = X cos(alpha x) sin(beta y), phi_y = Y sin(alpha x) cos(beta y),
alpha = m pi / a, beta = n pi / b, the lowest root of the 3 x 3 eigenproblem
    [[A55 alpha^2 + A44 beta^2, A55 alpha, A44 beta],
     [A55 alpha, D11 alpha^2 + D66 beta^2 + A55, (D12 + D66) alpha beta],
     [A44 beta, (D12 + D66) alpha beta, D66 alpha^2 + D22 beta^2 + A44]] = omega^2 diag(m0, m2, m2),
A55 = H_xx, A44 = H_yy the transverse shear of shell_section.py (with its k = 5/6).
"""
from __future__ import annotations

import numpy as np

from .shell_section import PlateSection


def navier_clt(sec: PlateSection, a: float, b: float, m: int, n: int) -> float:
    """omega_mn [rad/s] of classical laminate theory (module doc)."""
    D, m0 = sec.Cb, sec.inertia[0]
    r = a / b
    k = D[0, 0] * m**4 + 2 * (D[0, 1] + 2 * D[2, 2]) * m**2 * n**2 * r**2 + D[1, 1] * n**4 * r**4
    return float(np.pi**2 / a**2 * np.sqrt(k / m0))


def navier_fsdt(sec: PlateSection, a: float, b: float, m: int, n: int) -> float:
    """omega_mn [rad/s] of first-order shear deformation with rotary inertia (module doc)."""
    from scipy.linalg import eigh

    D, H = sec.Cb, sec.Cs
    m0, _, m2 = sec.inertia
    al, be = m * np.pi / a, n * np.pi / b
    A55, A44 = H[0, 0], H[1, 1]
    K = np.array([[A55 * al**2 + A44 * be**2, A55 * al, A44 * be],
                  [A55 * al, D[0, 0] * al**2 + D[2, 2] * be**2 + A55, (D[0, 1] + D[2, 2]) * al * be],
                  [A44 * be, (D[0, 1] + D[2, 2]) * al * be, D[2, 2] * al**2 + D[1, 1] * be**2 + A44]])
    return float(np.sqrt(eigh(K, np.diag([m0, m2, m2]), eigvals_only=True)[0]))


def navier_table(sec: PlateSection, a: float, b: float, count: int, theory=navier_fsdt, top: int = 8):
    """The lowest `count` omega [rad/s] over m, n = 1..top, sorted."""
    w = sorted(theory(sec, a, b, m, n) for m in range(1, top + 1) for n in range(1, top + 1))
    return np.array(w[:count])


def plate_deck(a: float, b: float, nx: int, ny: int, pcomp: list[str], materials: list[str],
               theta: float | None = None, spc: str = "none", coupmass: int = 1, extra=()) -> str:
    """A Nastran deck of an a x b plate in the basic x-y plane, nx x ny CQUAD4 (GRID ids row by row
    from 1), property 1 the PCOMP lines `pcomp`, the material cards `materials`, each CQUAD4's THETA
    field `theta` (blank if None), PARAM COUPMASS; spc "none" (free-free) or "hard" (simple support:
    w = 0 and the tangential rotation 0 on every edge, u = v = 0 there: SPC1 set 1)."""
    x, y = np.meshgrid(np.linspace(0, a, nx + 1), np.linspace(0, b, ny + 1), indexing="xy")
    lines = ["SOL 103", "CEND"] + (["SPC = 1"] if spc == "hard" else []) + ["BEGIN BULK",
                                                                           f"PARAM,COUPMASS,{coupmass}"]
    lines += list(pcomp) + list(materials) + list(extra)
    lines += [f"GRID,{k + 1},,{float(xx)!r},{float(yy)!r},0.0" for k, (xx, yy) in enumerate(zip(x.ravel(), y.ravel()))]
    th = "" if theta is None else f",{float(theta)!r}"
    for j in range(ny):
        for i in range(nx):
            g = j * (nx + 1) + i + 1
            lines.append(f"CQUAD4,{j * nx + i + 1},1,{g},{g + 1},{g + nx + 2},{g + nx + 1}{th}")
    if spc == "hard":
        comps = {}
        for j in range(ny + 1):
            for i in range(nx + 1):
                c = set()
                if i in (0, nx):
                    c |= set("1234")  # w = 0, phi_y = -rx = 0 along x = 0, a
                if j in (0, ny):
                    c |= set("1235")  # w = 0, phi_x = ry = 0 along y = 0, b
                if c:
                    comps.setdefault("".join(sorted(c)), []).append(j * (nx + 1) + i + 1)
        for c, grids in comps.items():
            for s in range(0, len(grids), 6):
                lines.append(f"SPC1,1,{c}," + ",".join(str(g) for g in grids[s : s + 6]))
    elif spc != "none":
        raise ValueError(f"spc {spc!r}: expected 'none' or 'hard'")
    return "\n".join(lines + ["ENDDATA"]) + "\n"
