"""resources/body.bin of a native body FMU: what the body-independent binary (fmu/native/*.c) reads.

It holds the variable table of fmu/variables.py (names, types, causality, start, min/max), the maps from
variables to the runtime's point values (runtime/input_rule.py COLUMNS) and output row (BodySystem.output_row,
then the probes of eq. 92), the parameters' value references, one runtime image
(runtime/native/image.py) per term set the FMU offers (the body steps in the same C runtime as a
standalone run), and, for a scene that starts at its static equilibrium or steady spin, the start state of
each term set made at build (runtime/start.py; sections start0..2: the state's code in START_STATES, the
gravity it holds for, the START_FIELDS).

Layout (little-endian; resource.c reads it, the one other description of it):

    header   magic b"FFRFFMU\\0" | u32 FORMAT_VERSION | u32 runtime version (FFRF_RUNTIME_VERSION)
             | u64 payload bytes | u64 FNV-1a 64 checksum of the stored payload | u64 scrambling seed
    payload  sections: tag (8 bytes, NUL-padded) | u64 bytes | data padded to 8 bytes; stored XORed with
             a splitmix64 key stream from the seed, one 64-bit word at a time.

The scrambling keeps the reduced matrices out of plain sight: no file of the FMU, no string in it and no
symbol of its binary shows K, M or G. It is not encryption (the seed is in the header and the code that
undoes it in the binary): docs/fmu.md says what a determined partner can still recover.
"""
from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass

import numpy as np

from ...model import INITIAL_STATES
from ...runtime import input_rule
from ...runtime.start import START_FIELDS
from ...runtime.terms import TERM_SETS
from ...runtime.outputs import output_sources
from ..variables import Variable

MAGIC = b"FFRFFMU\0"
FORMAT_VERSION = 3  # resource.h FMU_FORMAT_VERSION (2: the modal outputs; 3: solver.max_newton_iterations)
HEADER = struct.Struct("<8sIIQQQ")
PART_CODES = input_rule.PART_CODES
# what a unit change of an input moves over a communication step (model.h DKIND_*, derivatives.py)
DKIND = {"f": 0, "t": 0, "r": 1, "R": 1, "v": 2, "w": 2, "a": 3, "dw": 3}
MAX_PORTS = 64  # initialize.c names at most this many ports
START_STATES = INITIAL_STATES  # a start section's state code: its index here (model.c start_state STATES)


@dataclass(frozen=True)
class ResourceContent:
    """What body.bin holds, before packing (named, for the tests)."""

    guid: str
    about: str
    variables: list[Variable]
    ports: list  # runtime.data.PortData
    probes: list[str]
    node_positions: np.ndarray
    origin: np.ndarray
    images: dict[str, bytes]  # term set name -> runtime image
    start: dict | None = None  # builder.start_states: the state the FMU initializes to (None: from rest)


def _index(variables: list[Variable]) -> dict[tuple[str, str], list[int]]:
    index: dict[tuple[str, str], list[int]] = {}
    for i, v in enumerate(variables):
        key = (v.port, v.field) if v.port else (v.kind, v.field)
        index.setdefault(key, []).append(i)
    return index


def point_map(variables, ports) -> np.ndarray:
    """[n_ports][30] value reference read into each point-value column (core.py `_point_map`), -1 where none."""
    index, cols = _index(variables), input_rule.COLUMNS
    out = np.full((len(ports), input_rule.WIDTH), -1, dtype=np.int32)
    for j, p in enumerate(ports):
        fields = (("r", "v", "a") if p.translation != "force" else ("f",)) + \
                 (("R", "w", "dw") if p.rotation != "force" else ("t",))
        for f in fields:
            out[j, cols[f]] = index[(p.name, f)]
    return out


def output_map(variables, ports, probes) -> tuple[np.ndarray, np.ndarray]:
    """(value references, positions in [output row, probes, eta, eta rates]) of every output
    (fmu/variables.py output_sources, the pythonfmu slave's map too)."""
    dst, src = output_sources(variables, ports, probes)
    return np.array(dst, dtype=np.int32), np.array(src, dtype=np.int32)


def _section(tag: str, data: bytes) -> bytes:
    pad = (-len(data)) % 8
    return tag.encode().ljust(8, b"\0") + struct.pack("<Q", len(data)) + data + b"\0" * pad


def _i32(a) -> bytes:
    return np.ascontiguousarray(a, dtype="<i4").tobytes()


def _f64(a) -> bytes:
    return np.ascontiguousarray(a, dtype="<f8").tobytes()


def payload(c: ResourceContent) -> bytes:
    """The plain payload (sections) of body.bin."""
    if len(c.ports) > MAX_PORTS:
        raise ValueError(f"a native FMU has at most {MAX_PORTS} ports, this body {len(c.ports)}")
    variables, ports = c.variables, c.ports
    index = _index(variables)
    names, offsets = bytearray(), {}

    def name_at(text: str) -> int:
        if text not in offsets:
            offsets[text] = len(names)
            names.extend(text.encode("utf-8") + b"\0")
        return offsets[text]

    vars_blob = bytearray()
    for v in variables:
        flags = (1 if v.min is not None else 0) | (2 if v.max is not None else 0)
        dkind = DKIND.get(v.field, 0) if v.causality == "input" else 0
        vars_blob += struct.pack("<iiiiii3d", 0 if v.type == "Real" else 1,
                                 {"input": 0, "output": 1, "parameter": 2}[v.causality], dkind, flags, name_at(v.name), 0,
                                 float(v.start if v.start is not None else 0.0),
                                 float(v.min if v.min is not None else 0.0), float(v.max if v.max is not None else 0.0))
    ports_blob = b"".join(struct.pack("<iiii", int(p.node), PART_CODES[p.translation], PART_CODES[p.rotation],
                                      name_at(p.name)) for p in ports)
    out_vr, out_src = output_map(variables, ports, c.probes)
    row_of = {p.name: j for j, p in enumerate(ports)}
    by_name = {p.name: p for p in ports}
    seen, frame, dX = [], [], []
    for name in c.probes:
        s, _, f = name.partition("_from_")
        seen.append(row_of[s])
        frame.append(row_of[f])
        dX.append(c.node_positions[by_name[s].node] - c.node_positions[by_name[f].node])
    par = lambda key: index[("parameter", key)]  # noqa: E731
    params = [par("step")[0], par("rho_inf")[0], par("terms")[0], index[("solver", "newton_iterations")][0],
              *par("gravity"), *par("initial_velocity"), *par("initial_angular_velocity"), par("max_newton_iterations")[0]]
    disp = np.full((len(ports), 3), -1, dtype=np.int32)
    coupling = np.full((len(ports), 12), -1, dtype=np.int32)
    for j, p in enumerate(ports):
        if (p.name, "port_displacement") in index:
            disp[j] = index[(p.name, "port_displacement")]
        for k, suffix in enumerate(("k", "c", "k_rot", "c_rot")):
            if (p.name, "coupling." + suffix) in index:
                coupling[j, 3 * k : 3 * k + 3] = index[(p.name, "coupling." + suffix)]
    # structural damping: [vr of damping.alpha, of damping.beta, k, vr of the k ratios] (k = 1: one for every mode)
    ratios = index[("parameter", "damping_ratio")]
    damping = [par("damping_alpha")[0], par("damping_beta")[0], len(ratios), *ratios]
    counts = [len(variables), len(ports), len(out_vr), len(c.probes), len(index.get(("modal", "eta"), ()))]
    sections = [
        _section("guid", c.guid.encode() + b"\0"),
        _section("about", c.about.encode("utf-8")[:150] + b"\0"),
        _section("counts", _i32(counts)),
        _section("vars", bytes(vars_blob)),
        _section("ports", ports_blob),
        _section("pointvr", _i32(point_map(variables, ports))),
        _section("outvr", _i32(out_vr)),
        _section("outsrc", _i32(out_src)),
        _section("pseen", _i32(seen)),
        _section("pframe", _i32(frame)),
        _section("pdX", _f64(np.array(dX, dtype=float).reshape(-1, 3))),
        _section("params", _i32(params)),
        _section("disp", _i32(disp)),
        _section("coupling", _i32(coupling)),
        _section("damping", _i32(damping)),
        _section("origin", _f64(c.origin)),
        _section("nodes", _f64(c.node_positions)),  # reference node positions (the datasheet shows the ports' too)
    ]
    for name, image in c.images.items():
        sections.append(_section(f"image{TERM_SETS.index(name)}", image))
    if c.start is not None:  # per term set: state code, the gravity it holds for, the START_FIELDS (initialize.c)
        code = START_STATES.index(c.start["state"])
        for name, arrays in c.start["terms"].items():
            if name in c.images:
                flat = [np.ravel(arrays[k]) for k in START_FIELDS]
                sections.append(_section(f"start{TERM_SETS.index(name)}",
                                         _f64(np.concatenate([[code], c.start["gravity"], *flat]))))
    sections.insert(3, _section("names", bytes(names)))
    return b"".join(sections)


_GOLDEN, _M1, _M2 = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)


def key_stream(seed: int, words: int) -> np.ndarray:
    """splitmix64 outputs for states seed + k golden, k = 1..words (resource.c `splitmix64`)."""
    with np.errstate(over="ignore"):
        z = np.uint64(seed) + np.arange(1, words + 1, dtype=np.uint64) * _GOLDEN
        z = (z ^ (z >> np.uint64(30))) * _M1
        z = (z ^ (z >> np.uint64(27))) * _M2
        return z ^ (z >> np.uint64(31))


def checksum(data: bytes) -> int:
    """FNV-1a 64 over 8-byte little-endian words (resource.c `fnv1a_words`, image.py `checksum`)."""
    h, mask = 0xCBF29CE484222325, 0xFFFFFFFFFFFFFFFF
    for w in np.frombuffer(data, dtype="<u8").tolist():
        h = ((h ^ w) * 0x100000001B3) & mask
    return h


def pack(c: ResourceContent, runtime_version: int) -> bytes:
    """body.bin of `c`: header, then the scrambled payload."""
    plain = payload(c)
    seed = int.from_bytes(hashlib.sha256(plain).digest()[:8], "little")
    stored = (np.frombuffer(plain, dtype="<u8") ^ key_stream(seed, len(plain) // 8)).astype("<u8").tobytes()
    return HEADER.pack(MAGIC, FORMAT_VERSION, runtime_version, len(stored), checksum(stored), seed) + stored


def unpack_payload(blob: bytes) -> dict[str, bytes]:
    """The sections of a body.bin (tests and tools); ValueError on a damaged file."""
    magic, fmt, _, size, check, seed = HEADER.unpack_from(blob, 0)
    stored = blob[HEADER.size : HEADER.size + size]
    if magic != MAGIC or fmt != FORMAT_VERSION or len(stored) != size or checksum(stored) != check:
        raise ValueError("not an intact body.bin of this format")
    plain = (np.frombuffer(stored, dtype="<u8") ^ key_stream(seed, size // 8)).astype("<u8").tobytes()
    out, i = {}, 0
    while i + 16 <= len(plain):
        tag, n = plain[i : i + 8].rstrip(b"\0").decode(), struct.unpack_from("<Q", plain, i + 8)[0]
        out[tag] = plain[i + 16 : i + 16 + n]
        i += 16 + n + (-n) % 8
    return out


def read_body(blob: bytes):
    """The ports and reference node positions of a body.bin as a BodyData without superelements (what
    simulate.scene_inputs reads; the reduced matrices stay in the runtime images)."""
    from ...runtime.data import BodyData, PortData

    sec = unpack_payload(blob)
    names = sec["names"]
    text = lambda off: names[off : names.index(b"\0", off)].decode("utf-8")  # noqa: E731
    codes = {v: k for k, v in PART_CODES.items()}
    ports = tuple(PortData(text(name), int(node), codes[t], codes[r])
                  for node, t, r, name in np.frombuffer(sec["ports"], dtype="<i4").reshape(-1, 4).tolist())
    about = sec["about"].rstrip(b"\0").decode("utf-8")
    name = about.split(" ", 2)[1] if about.startswith("body ") else "body"
    return BodyData(name, (), np.frombuffer(sec["nodes"], dtype="<f8").reshape(-1, 3).copy(), ports)


def images(blob: bytes) -> dict[str, bytes]:
    """The runtime image of each term set in a body.bin."""
    sec = unpack_payload(blob)
    return {t: sec[f"image{k}"] for k, t in enumerate(TERM_SETS) if f"image{k}" in sec}
