"""Witteveen & Pichler's printed tables (2019; docs/inertia-terms.md, "His tables beside ours") as data, and
our invariants of the bundled bodies in his units beside them (`ffrf-fmu info` prints them, `--json` key
`witteveen`).

His numbers, by body: Table 1 (section 4: extent, mass, CNM free modes, CIM interface modes), Table 2
(6.1.1: max |W1|, average |W1| of the nonzero entries, his "Euclidean norm" of W1 and of I0), Table 3
(6.2.1: max |W2|, max |W3|, their averages and norms), the Coriolis table of 7.3.2 (the ratios
|Qf^T W2 Qf_dot w| / |W1 Qf_dot w| and |w~ Qf^T W3 qf_dot| / |W1 Qf_dot w|) and its centrifugal table
(|W2 Qf| / |W1|). A value he did not print is None.

His units are t and mm; our bodies are in SI (kg, m). Mass-normalized modes scale as 1 / sqrt(mass), so
    I0 [t mm^2] = 1e3 I0 [kg m^2],   W1 [sqrt(t) mm] = sqrt(1e-3) 1e3 W1 [sqrt(kg) m],   W2, W3 unit-free
(the plate and conrod rows, rebuilt in t and mm, agree with this to the static solves' tolerance:
tests/test_shell_body.py, tests/test_conrod.py). His ratios depend on modal states Qf, Qf_dot that he
does not state; ours beside them are state-defined (invariants.indicators): `centrifugal_q_over_const`
|Kc q_s| / |f0| at the scene's static widening q_s, and `coriolis` 2 w |G(n) Omega^-1|.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

I0_TO_T_MM = 1e3  # kg m^2 -> t mm^2
W1_TO_T_MM = math.sqrt(1e-3) * 1e3  # sqrt(kg) m -> sqrt(t) mm


@dataclass(frozen=True)
class HisRow:
    """One body's row of his Tables 1-3 and of the two 7.3.2 tables (t, mm; None: not printed)."""
    name: str
    extent_mm: tuple[float, float, float]
    mass_kg: float
    cnm: int
    cim: int
    W1_max: float
    W1_average: float
    W1_norm: float
    I0_norm: float
    W2_max: float | None
    W3_max: float | None
    W2_norm: float | None
    W3_norm: float | None
    coriolis_W2: float | None  # |Qf^T W2 Qf_dot w| / |W1 Qf_dot w|
    coriolis_W3: float | None  # |w~ Qf^T W3 qf_dot| / |W1 Qf_dot w|
    centrifugal: float | None  # |W2 Qf| / |W1|


HIS_ROWS = {
    "conrod": HisRow("Conrod", (20, 210, 80), 0.9, 15, 12, 2.5, 0.09, 1.8, 3.3, 0.1, 0.05, 0.15, 0.09, 0.003, 3e-19, 0.0009),
    "car_body": HisRow("Car body", (3800, 1500, 1100), 270.0, 50, 24, 32.6, 35.6, 444.1, 343673.0, 0.99, 0.6, 1.9, 1.1,
                       0.04, 0.003, 0.005),
    "jeffcott_rotor": HisRow("Jeffcott rotor", (300, 300, 750), 7.4, 10, 12, 18.6, 0.66, 10.5, 118.2, 0.02, 0.03, 0.07,
                             0.04, 0.0005, 6e-5, 0.0005),
    "witteveen_plate": HisRow("Plate", (1000, 1000, 0.5), 3.9, 20, 24, 42.1, 1.58, 21.1, 65.74, 1.0, 0.6, 2.0, 1.2,
                              None, None, 0.07),
    "genstruct1": HisRow("GenStruct1", (330, 200, 8), 0.36, 20, 6, 3.2, 0.18, 2.2, 7.5, 1.0, 0.8, 2.0, 1.1, 0.2, 0.06, 0.2),
    "genstruct2": HisRow("GenStruct2", (330, 200, 8), 0.4, 20, 6, 8.5, 0.47, 2.3, 8.4, 1.0, 0.9, 1.9, 1.2, 0.03, 0.005,
                         0.02),
    "witteveen_beam": HisRow("Beam", (750, 20, 20), 1.8, 38, 12, 18.4, 0.13, 9.2, 85.7, 1.0, 1.0, 2.0, 1.4, 85.0, 0.06,
                             0.03),
}
HIS_ROWS["jeffcott_runup"] = HIS_ROWS["jeffcott_rotor"]  # the same rotor, split at the disc


@dataclass(frozen=True)
class Comparison:
    """Our invariants of a bundled body in his units beside his row (`ours` and `his` by quantity)."""
    body: str
    his_name: str
    ours: dict
    his: dict

    def as_dict(self) -> dict:
        return asdict(self)


def ours_in_his_units(superelement: dict) -> dict:
    """Our Table 2-3 quantities and the ratios of one superelement's indicators (invariants.indicators, SI)
    in t and mm (module doc); `W1_norm_half` is |W1| / 2, the reading of his "norm" that fits his rows
    (docs/inertia-terms.md, ambiguity 3)."""
    t = superelement["table"]
    return {
        "I0_norm": t["I0_norm"] * I0_TO_T_MM,
        "W1_max": t["W1_max"] * W1_TO_T_MM,
        "W1_norm": t["W1_norm"] * W1_TO_T_MM,
        "W1_norm_half": t["W1_norm"] * W1_TO_T_MM / 2,
        "W2_max": t["W2_max"], "W2_norm": t["W2_norm"], "W3_max": t["W3_max"], "W3_norm": t["W3_norm"],
        "coriolis": superelement.get("coriolis"),
        "centrifugal": superelement.get("centrifugal_q_over_const"),
        "softening": superelement.get("softening"),
    }


def his_row_for(body_name: str, inertia: dict) -> Comparison | None:
    """His row beside ours for a bundled body of his paper (by body name), else None. With several
    superelements, the one with the largest |I0| (a chain's parts are not his body; the test rows have one)."""
    row = HIS_ROWS.get(body_name)
    if row is None:
        return None
    se = max(inertia["superelements"], key=lambda s: s["table"]["I0_norm"])
    his = asdict(row)
    his.pop("name")
    return Comparison(body_name, row.name, ours_in_his_units(se), his)


def format_rows(c: Comparison) -> str:
    """The text `ffrf-fmu info` prints: ours | his per quantity, his units."""
    o, h = c.ours, c.his
    g = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
    pairs = [("|I0|", o["I0_norm"], h["I0_norm"]), ("max|W1|", o["W1_max"], h["W1_max"]),
             ("|W1| (/2)", o["W1_norm_half"], h["W1_norm"]), ("max|W2|", o["W2_max"], h["W2_max"]),
             ("|W2|", o["W2_norm"], h["W2_norm"]), ("max|W3|", o["W3_max"], h["W3_max"]), ("|W3|", o["W3_norm"], h["W3_norm"]),
             ("centrifugal", o["centrifugal"], h["centrifugal"]), ("Coriolis", o["coriolis"], h["coriolis_W2"])]
    return (f"  Witteveen's {c.his_name} (t, mm; ours | his; docs/inertia-terms.md): "
            + ", ".join(f"{k} {g(a)} | {g(b)}" for k, a, b in pairs)
            + "\n    (his |W1| read as W1/2; centrifugal: ours |Kc q_s|/|f0| at the scene's widening, his |W2 Qf|/|W1|; "
              "Coriolis: ours 2 w |G(n) Omega^-1|, his |Qf^T W2 Qf_dot w|/|W1 Qf_dot w|: states he does not give)")
