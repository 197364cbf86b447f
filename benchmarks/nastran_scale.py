"""Cost of reading and assembling a Nastran deck of shells or solids (docs/nastran.md, "Speed"): a
generated deck of n x n CQUAD4 (PSHELL) or n x n x n CHEXA (PSOLID) on a unit square / cube, coupled
mass (PARAM COUPMASS 1), read by read_nastran; CPU seconds of the whole (pyNastran's reading included).

    python benchmarks/nastran_scale.py                 # CQUAD4 n = 60, CHEXA n = 15
    python benchmarks/nastran_scale.py --shell 100 --solid 20
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from ffrf_fmu.solid.nastran import read_nastran


def deck(n: int, kind: str) -> str:
    lines = ["SOL 103", "CEND", "BEGIN BULK", "PARAM,COUPMASS,1", "MAT1,1,2.0e11,,0.3,7800.0", "PSOLID,1,1",
             "PSHELL,2,1,0.01,1,,1"]
    layers = n + 1 if kind == "solid" else 1

    def g(i, j, k):
        return 1 + i + (n + 1) * (j + (n + 1) * k)

    for k in range(layers):
        lines += [f"GRID,{g(i, j, k)},,{i / n!r},{j / n!r},{k / n!r}" for j in range(n + 1) for i in range(n + 1)]
    e = 0
    for j in range(n):
        for i in range(n):
            if kind == "shell":
                e += 1
                lines.append(f"CQUAD4,{e},2,{g(i, j, 0)},{g(i + 1, j, 0)},{g(i + 1, j + 1, 0)},{g(i, j + 1, 0)}")
                continue
            for k in range(n):
                e += 1
                c = [g(i, j, k), g(i + 1, j, k), g(i + 1, j + 1, k), g(i, j + 1, k), g(i, j, k + 1), g(i + 1, j, k + 1),
                     g(i + 1, j + 1, k + 1), g(i, j + 1, k + 1)]
                lines.append(f"CHEXA,{e},1,{','.join(map(str, c[:6]))},\n,{c[6]},{c[7]}")
    return "\n".join(lines + ["ENDDATA"]) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shell", type=int, default=60)
    ap.add_argument("--solid", type=int, default=15)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for kind, n in (("shell", args.shell), ("solid", args.solid)):
            path = Path(tmp) / f"{kind}.bdf"
            path.write_text(deck(n, kind))
            t = time.process_time()
            fe = read_nastran(path)
            cpu = time.process_time() - t
            count = n * n if kind == "shell" else n**3
            print(f"{count:7d} {'CQUAD4' if kind == 'shell' else 'CHEXA'}  {fe.K.shape[0]:8d} dofs  {cpu:6.2f} s CPU")


if __name__ == "__main__":
    main()
