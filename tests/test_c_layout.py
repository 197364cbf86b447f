"""The C files call one another in one direction (a DAG, as the Python stages import): a file that
calls a function of another is never called back by it, for the runtime (ffrf_fmu/runtime/native) and
the FMU's own C (ffrf_fmu/fmu/native), and every call and every include of the folder's own headers
runs down the layers of docs/architecture.md. The check reads the files as text: external definitions
`type name(args) {` at the start of a line, and calls `name(` in the other files."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "ffrf_fmu"
# the layers bottom up (docs/architecture.md, "The C runtime in layers"); files of one layer call each other not
LAYERS = {
    "runtime/native": [["so3.c"], ["lu.c"], ["superelement.c"], ["factor.c"], ["step.c"], ["accel.c"], ["advance.c"],
                       ["body.c"], ["initial.c"]],
    "fmu/native": [["resource.c"], ["initialize.c"], ["model.c"], ["fmi2Functions.c", "fmi3Functions.c"]],
}
INCLUDE = re.compile(r'^#include "(\w+)\.h"', re.M)
DEFINITION = re.compile(r"^(?!static\b)[A-Za-z_][\w \*]*?\b(\w+)\s*\([^;{]*\)\s*\{", re.M)


def call_graph(folder: Path) -> set:
    files = {f.name: f.read_text() for f in sorted(folder.glob("*.c"))}
    defined = {m.group(1): name for name, text in files.items() for m in DEFINITION.finditer(text)}
    return {(caller, owner) for caller, text in files.items() for fn, owner in defined.items()
            if owner != caller and re.search(rf"\b{fn}\s*\(", text)}


def circles(edges: set) -> list:
    graph = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
    found, state = [], {}

    def visit(node, path):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                found.append(path[path.index(nxt):] + [nxt] if nxt in path else [node, nxt])
            elif not state.get(nxt):
                visit(nxt, path + [nxt])
        state[node] = 2

    for n in sorted(graph):
        if not state.get(n):
            visit(n, [n])
    return found


@pytest.mark.parametrize("folder", ["runtime/native", "fmu/native"])
def test_c_files_call_in_one_direction(folder):
    edges = call_graph(ROOT / folder)
    assert edges, f"{folder}: no calls between its files found (the check would pass vacuously)"
    assert circles(edges) == []


@pytest.mark.parametrize("folder", sorted(LAYERS))
def test_c_files_call_and_include_down_the_layers(folder):
    rank = {name: k for k, layer in enumerate(LAYERS[folder]) for name in layer}
    files = sorted(f.name for f in (ROOT / folder).glob("*.c"))
    assert sorted(rank) == files, f"{folder}: every C file has its layer"
    up = [(a, b) for a, b in call_graph(ROOT / folder) if rank[a] <= rank[b]]
    assert up == [], f"{folder}: calls that do not run down the layers"
    for name in files:
        for inc in INCLUDE.findall((ROOT / folder / name).read_text()):
            if f"{inc}.c" in rank:
                assert rank[f"{inc}.c"] <= rank[name], f"{folder}/{name} includes {inc}.h, a layer above it"


def test_the_check_finds_a_circle(tmp_path):
    (tmp_path / "a.c").write_text("int fa(int x) {\n    return fb(x);\n}\n")
    (tmp_path / "b.c").write_text("int fb(int x) {\n    return x ? fa(x - 1) : 0;\n}\n")
    assert circles(call_graph(tmp_path)) == [["a.c", "b.c", "a.c"]]
