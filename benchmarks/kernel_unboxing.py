#!/usr/bin/env python3
"""Benchmark: what passing a kernel's constants costs per call, by container (issue 10 item 2).

    python benchmarks/kernel_unboxing.py [--arrays 80]

A compiled kernel call unboxes every argument; runtime/kernel.py `run_held` takes ~80 arrays in nested
tuples (the constants, the state, the spring and input buffers, the energy data). Toy functions of the
same argument shapes, each called through its dispatcher 20000 times (best of 5), in a fresh module
with cache=True, and each run twice in fresh processes to see whether numba's disk cache serves it
(a kernel that misses the cache compiles again in every process and every FMU instantiation: 83 s for
the real kernel, docs/benchmarks.md):
  tuples     the arrays in 7 nested tuples (what `run_held` takes)
  structref  one numba StructRef holding the arrays (fields read inside)
  jitclass   one jitclass instance holding the arrays
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

MODULE = '''
import numba
import numpy as np
from numba.core import types
from numba.experimental import jitclass, structref

N = {n}
FIELDS = [f"a{{i}}" for i in range(N)]


@structref.register
class ConstsType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Consts(structref.StructRefProxy):
    pass


structref.define_proxy(Consts, ConstsType, FIELDS)

ns = {{}}
exec("def __init__(self, " + ", ".join(FIELDS) + "):\\n" + "".join(f"    self.{{f}} = {{f}}\\n" for f in FIELDS), ns)
JC = jitclass([(f, types.float64[::1]) for f in FIELDS])(type("JC", (), {{"__init__": ns["__init__"]}}))


@numba.njit(cache=True)
def f_tuples(c, s, sp, inp, ed, w, rest, n):
    return c[0][0] + s[0][0] + rest[-1][0] + n


@numba.njit(cache=True)
def f_structref(c, n):
    return c.a0[0] + c.a{last}[0] + n


@numba.njit(cache=True)
def f_jitclass(c, n):
    return c.a0[0] + c.a{last}[0] + n
'''

PROBE = '''
import sys, time
import numpy as np
sys.path.insert(0, {d!r})
import unboxing_probe as m
arrs = [np.zeros(10) for _ in range(m.N)]
cuts = [0, 33, 46, 55, 60, 71, 75, m.N]
nested = tuple(tuple(arrs[a:b]) for a, b in zip(cuts, cuts[1:]))


def per_call(fn, args):
    t0 = time.perf_counter()
    for _ in range(20000):
        fn(*args)
    return (time.perf_counter() - t0) / 20000


cases = {{"tuples": (m.f_tuples, (*nested, 1)), "structref": (m.f_structref, (m.Consts(*arrs), 1)),
          "jitclass": (m.f_jitclass, (m.JC(*arrs), 1))}}
for name, (fn, args) in cases.items():
    t0 = time.perf_counter()
    fn(*args)
    first = time.perf_counter() - t0
    best = min(per_call(fn, args) for _ in range(5))
    hit = bool(fn.stats.cache_hits)
    print(f"{{name}} {{1e6 * best:.2f}} {{first:.3f}} {{int(hit)}}")
'''


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arrays", type=int, default=80)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "unboxing_probe.py").write_text(MODULE.format(n=args.arrays, last=args.arrays - 1))
        runs = [subprocess.run([sys.executable, "-c", textwrap.dedent(PROBE.format(d=d))], capture_output=True, text=True,
                               check=True).stdout.split("\n") for _ in range(2)]
    print(f"{args.arrays} arrays per call; us per call (best of 5 x 20000), first call [s] and disk-cache hit, "
          "first process / second process")
    for first, second in zip(runs[0], runs[1]):
        if first:
            (name, us1, c1, h1), (_, us2, c2, h2) = first.split(), second.split()
            print(f"  {name:10s} {float(us1):6.2f} / {float(us2):6.2f} us   first call {float(c1):6.3f} / {float(c2):6.3f} s   "
                  f"cache hit {bool(int(h1))} / {bool(int(h2))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
