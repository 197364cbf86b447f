"""The body image: everything the C runtime needs to create a body, as one versioned binary blob.

A standalone run hands it to `ffrf_body_create` in memory (runtime/native/binding.py); an FMU carries it
as its resource (fmu/native). One image, one runtime: the FMU steps the same code as the standalone run.

Layout (little-endian), read by body.c `ffrf_body_create`:

    header   magic b"FFRFBODY" | u32 version (FFRF_RUNTIME_VERSION) | u32 entry count
             | u64 payload bytes | u64 FNV-1a 64 checksum of the payload
    payload  per entry: name (24 bytes, NUL-padded) | kind u8 ('d' float64, 'q' int64) | ndim u8
             | 6 bytes padding | 5 x u64 dims (unused: 1) | the values, C order (8 bytes each)

Entries are the body's named arrays and scalars of runtime/native/body.h (`ffrf_data`, the initial
state, the integrator's settings); scalars are arrays of one value.
"""
from __future__ import annotations

import struct

import numpy as np

from ..damping import is_damped, per_mode_ratios

MAGIC = b"FFRFBODY"
VERSION = 4  # ffrf_runtime.h FFRF_RUNTIME_VERSION (2: the Newton keep rule's near_miss, near_contraction; 3: kept_accept and
# kept_radius in place of keep_contraction; 4: wide_miss, kept_age)
NAME_BYTES = 24
HEADER = struct.Struct("<8sIIQQ")
ENTRY = struct.Struct("<24sBB6x5Q")
MAX_DIMS = 5


_INT64, _FLOAT64 = np.dtype("<i8"), np.dtype("<f8")
_ONES = (1,) * MAX_DIMS
# a Python scalar's entry and value in one (a third of the entries; numpy's conversions cost 3 us each)
_SCALAR = {int: struct.Struct("<24sBB6x5Qq"), bool: struct.Struct("<24sBB6x5Qq"), float: struct.Struct("<24sBB6x5Qd")}


def pack(entries: dict[str, np.ndarray], checksum_of=None) -> bytes:
    """The image of named arrays (float64 or int64), in the given order. checksum_of: the function of the
    payload's checksum, `checksum` by default; binding.py passes the C runtime's (the same sum in C: the
    Python loop takes 0.2 us a word, 0.3-0.5 ms of a B1 body's set-up)."""
    parts = []
    for name, value in entries.items():
        key = name.encode()
        if len(key) >= NAME_BYTES:
            raise ValueError(f"image entry {name!r}: at most {NAME_BYTES - 1} name bytes")
        scalar = _SCALAR.get(type(value))
        if scalar is not None:  # of shape (1,), as ascontiguousarray makes a scalar below
            parts.append(scalar.pack(key, 100 if type(value) is float else 113, 1, *_ONES, value))
            continue
        a = np.asarray(value)
        if a.dtype.kind in "iub":
            a, kind = np.ascontiguousarray(a, dtype=_INT64), 113  # b"q"
        else:
            a, kind = np.ascontiguousarray(a, dtype=_FLOAT64), 100  # b"d"
        if a.ndim > MAX_DIMS:
            raise ValueError(f"image entry {name!r}: at most {MAX_DIMS} dimensions")
        parts.append(ENTRY.pack(key, kind, a.ndim, *a.shape, *_ONES[a.ndim:]))
        parts.append(a.data)
    payload = b"".join(parts)
    return HEADER.pack(MAGIC, VERSION, len(entries), len(payload), (checksum_of or checksum)(payload)) + payload


def checksum(payload: bytes) -> int:
    """FNV-1a 64 over the payload's 8-byte little-endian words (body.c `image_checksum`): one
    multiply per word keeps it cheap in both languages; any flipped bit changes it."""
    h, mask = 0xCBF29CE484222325, 0xFFFFFFFFFFFFFFFF
    for w in np.frombuffer(payload, dtype="<u8").tolist():
        h = ((h ^ w) * 0x100000001B3) & mask
    return h


def unpack(image: bytes) -> dict[str, np.ndarray]:
    """The named arrays of an image (for tests and tools); raises ValueError on a damaged image."""
    magic, version, count, size, check = HEADER.unpack_from(image, 0)
    if magic != MAGIC or version != VERSION:
        raise ValueError(f"not a body image of version {VERSION}")
    payload = image[HEADER.size : HEADER.size + size]
    if len(payload) != size or checksum(payload) != check:
        raise ValueError("body image damaged (size or checksum)")
    out, i = {}, 0
    for _ in range(count):
        name, kind, ndim, *dims = ENTRY.unpack_from(payload, i)
        i += ENTRY.size
        shape = tuple(dims[:ndim])
        n = int(np.prod(shape)) if shape else 1
        out[name.rstrip(b"\0").decode()] = np.frombuffer(payload, dtype="<f8" if kind == ord("d") else "<i8", count=n,
                                                        offset=i).reshape(shape)
        i += 8 * n
    return out


def body_entries(system, basis: bool = True) -> dict[str, np.ndarray]:
    """The named arrays of a BodySystem's image: its reduced data (the term set's), the integrator's maps
    and Newton policy, the ports, the compliances and the reference state (runtime/native/body.h).
    basis: the damping's modal basis (damping.py) in the image, so that an FMU's damping parameters act
    without an eigensolver; False leaves it out of an undamped body's image (a body that no one damps
    later, the standalone run's: an eigenproblem per superelement saved, the steps the same)."""
    L = system.layout
    E, n = L.n_se, L.n
    gyro = (1 if system.coriolis else 0) | (2 if system.inertia_coupling else 0)  # FFRF_CORIOLIS | FFRF_COUPLING
    ports = system.data.ports
    springs = [p for p in ports if p.name in system.compliant]
    node, mode, spring = system._port_codes
    am, af, gamma = system.coefficients
    damping = system.damping
    basis = system.damping_basis if basis or is_damped(damping) else None
    n_el = basis.n_elastic if basis is not None else 0
    e = {
        # reduced data (geradin 76, 53, 13) and the deformation-dependent inertia / membrane strain
        "gyro": gyro, "stiff": int(system.W1 is not None),
        "K": system.K, "M": system.M, "G": system.G if gyro else np.zeros((E, 3, 1, 1)),
        "W1": system.W1 if system.W1 is not None else np.zeros((E, 0, 3, 3)),
        "W2": system.W2 if system.W2 is not None else np.zeros((E, 0, 0, 3, 3)),
        "vk_a": system.vk_a if system.stiffening else np.zeros((E, 0, n)),
        "vk_B": system.vk_B if system.stiffening else np.zeros((E, 0, n, n)),
        "mass": system.mass, "J0": system.J0, "X_B": system.X_B, "se_nodes": system.se_nodes,
        # structural damping (runtime/damping.py): the elastic modes and the ratios / Rayleigh coefficients
        "damp_MPhi": basis.MPhi if basis is not None else np.zeros((E, n, 0)),
        "damp_omega": basis.omega if basis is not None else np.zeros((E, 0)),
        "damp_zeta": per_mode_ratios(damping, n_el) if damping is not None else np.zeros(n_el),
        "damp_ab": np.array([damping.alpha, damping.beta] if damping is not None else [0.0, 0.0]),
        # layout and integrator maps (runtime/layout.py, integrator.py `_build_newton`)
        "cfg_map": L.cfg_map, "vel_map": L.vel_map, "gravity": system.gravity,
        "rot_slots": L.rot_cols, "newton_idx": system._newton_idx, "newton_pos": system._newton_pos,
        "k3": 3 * len(system._world_free), "field_of": system._field_of,
        "theta_refresh": system.THETA_REFRESH, "kept_accept": system.KEPT_ACCEPT,
        "kept_radius": system.KEPT_RADIUS,
        "keep_miss": system.KEEP_MISS, "wide_miss": system.WIDE_MISS, "kept_age": system.KEPT_AGE, "near_miss": system.NEAR_MISS,
        "near_contraction": system.NEAR_CONTRACTION, "refresh_min": int(system.REFRESH_AFTER[0]),
        "refresh_max": int(system.REFRESH_AFTER[1]), "world_idx": system._world_idx.reshape(-1, 3),
        "lin_slots": L.lin_slots, "fixed_idx": system._fixed_idx, "motion_x": system._motion_x,
        "motion_x_slots": system._motion_x_slots, "motion_T_slots": system._motion_T_slots,
        "stage_mask": system._stage_mask, "motion_parts": system._motion_parts,
        # ports (runtime/input_rule.py port_codes) and compliant ports (runtime/coupling.py)
        "port_node": node, "port_mode": mode.reshape(-1, 2), "port_spring": spring,
        "spring_node": np.array([p.node for p in springs], dtype=np.int64),
        "spring_trans": np.array([p.translation == "compliant" for p in springs], dtype=np.int64),
        "spring_rot": np.array([p.rotation == "compliant" for p in springs], dtype=np.int64),
        "KC": np.array([system.compliance[p.name] for p in springs]).reshape(len(springs), 4, 3),
        # the integrator's settings (generalized-alpha, Newton)
        "tol": system.tol, "max_iter": int(system.max_iter), "rho_inf": system.rho_inf,
        "am": am, "af": af, "gamma": gamma,
        # the reference state (BodySystem.reset_reference)
        "xN": system.data.node_positions, "x0": np.array([se.x_cm for se in system.data.superelements]),
    }
    return e


def body_image(system, basis: bool = True, checksum_of=None) -> bytes:
    """The image of a BodySystem (its term set, stiffening, ports, compliances and settings; `body_entries`,
    `pack`)."""
    return pack(body_entries(system, basis), checksum_of)
