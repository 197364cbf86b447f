"""The native FMU (ffrf_fmu/fmu/native): a black box in C over the C runtime, nothing installed beside it.

What is checked here and not by the fault table (tests/test_fmu_faults.py runs that on both runtimes):
the FMU's contents (no Python, no .npz, no readable matrices, only fmi2 exports), fmpy's validation,
the GUID, every resource-location form, calls in the wrong state, two instances, reset, state round
trips and damaged serialized states, and the directional derivatives against two runs of the FMU.
The binary is called through ctypes in this process (tests/test_native_host.py runs it in a C host).
"""
from __future__ import annotations

import ctypes as C
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu

from ffrf_fmu.fmu.builder import build_fmu

OK, WARNING, DISCARD, ERROR = 0, 1, 2, 3
SCENES = """
[scenes.still]
duration = 0.2
step = 0.01
"""

LOGGER = C.CFUNCTYPE(None, C.c_void_p, C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.c_char_p)


class Callbacks(C.Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", C.c_void_p), ("freeMemory", C.c_void_p),
                ("stepFinished", C.c_void_p), ("componentEnvironment", C.c_void_p)]


class Fmu:
    """The FMU's binary loaded with ctypes: fmi2 calls by name, the messages logged per call."""

    def __init__(self, unzipped: Path, md):
        self.md, self.dir = md, unzipped
        self.lib = C.CDLL(str(unzipped / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"))
        self.log: list[tuple[int, str, str]] = []
        self._logger = LOGGER(lambda env, name, status, cat, fmt, msg: self.log.append(
            (status, (cat or b"").decode(), (msg or b"").decode())))
        self.cb = Callbacks(self._logger, None, None, None, None)
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.lib.fmi2Instantiate.restype = C.c_void_p
        self.lib.fmi2Instantiate.argtypes = [C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.c_void_p, C.c_int, C.c_int]
        for name in ("fmi2FreeInstance", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
                     "fmi2Reset"):
            getattr(self.lib, name).argtypes = [C.c_void_p]
        self.lib.fmi2SetupExperiment.argtypes = [C.c_void_p, C.c_int, C.c_double, C.c_double, C.c_int, C.c_double]
        self.lib.fmi2DoStep.argtypes = [C.c_void_p, C.c_double, C.c_double, C.c_int]
        for name in ("fmi2GetReal", "fmi2SetReal"):
            getattr(self.lib, name).argtypes = [C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_double)]
        for name in ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate"):
            getattr(self.lib, name).argtypes = [C.c_void_p, C.c_void_p]
        self.lib.fmi2SetFMUstate.argtypes = [C.c_void_p, C.c_void_p]
        self.lib.fmi2SerializedFMUstateSize.argtypes = [C.c_void_p, C.c_void_p, C.POINTER(C.c_size_t)]
        self.lib.fmi2SerializeFMUstate.argtypes = [C.c_void_p, C.c_void_p, C.c_char_p, C.c_size_t]
        self.lib.fmi2DeSerializeFMUstate.argtypes = [C.c_void_p, C.c_char_p, C.c_size_t, C.POINTER(C.c_void_p)]
        for name in ("fmi2GetDirectionalDerivative", "ffrf2GetStepDerivative"):
            getattr(self.lib, name).argtypes = [C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_uint),
                                                C.c_size_t, C.POINTER(C.c_double), C.POINTER(C.c_double)]

    def uri(self) -> str:
        return (self.dir / "resources").as_uri()

    def instantiate(self, uri: str | None | bool = True, guid: str | None = None, name: str = "body"):
        """uri: True for the FMU's own resources, None for a NULL location, else the text given."""
        location = self.uri() if uri is True else uri
        return self.lib.fmi2Instantiate(name.encode(), 1, (guid or self.md.guid).encode(),
                                        None if location is None else location.encode(), C.byref(self.cb), 0, 1)

    def start(self, c, values=None, stop=None):
        assert self.lib.fmi2SetupExperiment(c, 0, 0.0, 0.0, stop is not None, stop or 0.0) == OK
        assert self.lib.fmi2EnterInitializationMode(c) == OK
        if values:
            assert self.set(c, values) == OK
        return self.lib.fmi2ExitInitializationMode(c)

    def set(self, c, values: dict) -> int:
        vrs = (C.c_uint * len(values))(*[self.vr[n] for n in values])
        return self.lib.fmi2SetReal(c, vrs, len(values), (C.c_double * len(values))(*values.values()))

    def get(self, c, names) -> np.ndarray:
        vrs = (C.c_uint * len(names))(*[self.vr[n] for n in names])
        out = (C.c_double * len(names))()
        assert self.lib.fmi2GetReal(c, vrs, len(names), out) == OK, self.log[-3:]
        return np.array(out[:])

    def derivative(self, c, unknowns, knowns, seeds, step=True):
        """step: the derivatives of the last step (ffrf2GetStepDerivative), else FMI's (fmi2GetDirectionalDerivative)."""
        u = (C.c_uint * len(unknowns))(*[self.vr[n] for n in unknowns])
        k = (C.c_uint * len(knowns))(*[self.vr[n] for n in knowns])
        out = (C.c_double * len(unknowns))()
        call = self.lib.ffrf2GetStepDerivative if step else self.lib.fmi2GetDirectionalDerivative
        status = call(c, u, len(unknowns), k, len(knowns), (C.c_double * len(seeds))(*seeds), out)
        return status, np.array(out[:])


@pytest.fixture(scope="module")
def model(tmp_path_factory, beam_toml):
    path = tmp_path_factory.mktemp("native") / "native_beam.toml"
    path.write_text(beam_toml(SCENES, name="native_beam"))
    return path


@pytest.fixture(scope="module")
def fmu_path(model):
    return build_fmu(model, model.parent / "still.fmu", scene="still", platforms=("linux64",))


@pytest.fixture(scope="module")
def fmu(fmu_path, tmp_path_factory):
    d = Path(extract(str(fmu_path), str(tmp_path_factory.mktemp("unzipped"))))
    return Fmu(d, read_model_description(str(fmu_path)))


OUT = ["tip.r[1]", "tip.r[2]", "tip.r[3]", "tip.v[3]", "hub.f[3]", "hub.t[2]", "energy.strain", "energy.work_external"]


def _run(fmu, c, steps, H=0.01, k0=0, load=None):
    """steps doSteps of H from step k0 (t_c = k H: the same times whatever k0), the load set for each."""
    for k in range(k0, k0 + steps):
        if load is not None:
            assert fmu.set(c, {"tip.f[3]": load(k * H)}) == OK
        assert fmu.lib.fmi2DoStep(c, k * H, H, 1) == OK, fmu.log[-3:]
    return fmu.get(c, OUT)


def test_the_fmu_holds_no_python_no_npz_and_no_readable_matrices(fmu_path, model):
    """A black box: modelDescription, the scrambled body.bin, the datasheet and binaries only; the bytes of
    K's and M's rows appear nowhere in the FMU (stored or compressed), and the binary exports fmi2* and
    ffrf2GetStepDerivative only."""
    from ffrf_fmu.model import load_model
    from ffrf_fmu.reduction import reduce_scene_body

    with zipfile.ZipFile(fmu_path) as z:
        names = z.namelist()
        blobs = [z.read(n) for n in names]
    assert sorted({n.split("/")[0] for n in names}) == ["binaries", "documentation", "modelDescription.xml", "resources"]
    assert not [n for n in names if n.endswith((".py", ".npz", ".toml", ".c", ".h", ".txt"))], names
    assert [n for n in names if n.endswith(".json")] == ["documentation/build.json"]
    mdl = load_model(model)
    body = reduce_scene_body(mdl.body, mdl.scene("still")).data
    raw = open(fmu_path, "rb").read()
    for se in body.superelements:
        for key in ("K", "M"):
            row = np.ascontiguousarray(getattr(se, key))[-1, -4:].tobytes()  # a row's last 4 entries, 32 bytes
            assert row not in raw and all(row not in b for b in blobs), key
    html = next(b for n, b in zip(names, blobs) if n == "documentation/index.html").decode()
    assert "Mass properties" in html and "Free-free frequencies" in html and "hub" in html
    so = next(n for n in names if n.endswith(".so"))
    nm = shutil.which("nm")
    if nm:
        with zipfile.ZipFile(fmu_path) as z, open(fmu_path.with_suffix(".so"), "wb") as f:
            f.write(z.read(so))
        lines = subprocess.run([nm, "-D", "--defined-only", str(fmu_path.with_suffix(".so"))], capture_output=True,
                               text=True, check=True).stdout.splitlines()
        exported = [ln.split()[-1] for ln in lines if ln.split()[-2] in "TDBR"]
        # fmi2* and the one documented non-FMI function (docs/fmu.md, "Directional derivatives")
        assert exported and all(s.startswith("fmi2") or s == "ffrf2GetStepDerivative" for s in exported), exported
        assert "ffrf2GetStepDerivative" in exported


def test_fmpy_validates_the_fmu_clean(fmu_path):
    assert validate_fmu(str(fmu_path)) == []


def test_wrong_guid_is_an_error_at_instantiation(fmu):
    fmu.log.clear()
    assert fmu.instantiate(guid="{00000000-0000-0000-0000-000000000000}") is None
    (status, cat, msg), = fmu.log
    assert status == ERROR and "wrong GUID {00000000-0000-0000-0000-000000000000}" in msg and fmu.md.guid in msg


@pytest.mark.parametrize("form", ["file:///", "file:/", "file://localhost/", "escaped", "plain"])
def test_every_local_resource_uri_form_is_accepted(fmu, tmp_path, form):
    """file:///abs, file:/abs, file://localhost/abs, percent-escapes (a folder name with a space and a %),
    and a plain absolute path: the FMU instantiates and runs."""
    res = fmu.dir / "resources"
    if form == "escaped":
        odd = tmp_path / "my resources 100%"
        shutil.copytree(res, odd)
        uri = odd.as_uri()
        assert "%20" in uri and "%25" in uri
    else:
        uri = {"file:///": f"file://{res}", "file:/": f"file:{res}", "file://localhost/": f"file://localhost{res}",
               "plain": str(res)}[form]
    c = fmu.instantiate(uri)
    assert c, fmu.log[-2:]
    try:
        assert fmu.start(c, {"tip.f[3]": 1.0}) == OK
        assert _run(fmu, c, 2)[2] > 0.0
    finally:
        fmu.lib.fmi2FreeInstance(c)


@pytest.mark.parametrize("uri, cause", [
    (None, "no resource location given"),
    ("", "no resource location given"),
    ("file:///nonexistent/resources", "the resources folder is missing or unreadable"),
    ("file://otherhost/x/resources", "names host otherhost: only local files"),
    ("http://example.com/resources", "only file URIs are supported"),
    ("file:relative/resources", "is not an absolute file URI"),
    ("file:///tmp/%zz", "bad percent-escape"),
])
def test_bad_resource_locations_are_refused_with_a_message(fmu, uri, cause):
    fmu.log.clear()
    assert fmu.instantiate(uri) is None
    (status, _, msg), = fmu.log
    assert status == ERROR and cause in msg, msg


def test_a_damaged_resource_is_refused_with_a_message(fmu, tmp_path):
    res = tmp_path / "res"
    shutil.copytree(fmu.dir / "resources", res)
    blob = bytearray((res / "body.bin").read_bytes())
    blob[len(blob) // 2] ^= 1
    (res / "body.bin").write_bytes(bytes(blob))
    fmu.log.clear()
    assert fmu.instantiate(res.as_uri()) is None
    assert "is damaged (checksum mismatch)" in fmu.log[-1][2]


@pytest.mark.parametrize("call", ["doStep_before_init", "setup_after_init", "get_before_init", "doStep_after_terminate",
                                  "enter_twice", "derivative_before_step"])
def test_calls_in_the_wrong_state_are_errors(fmu, call):
    c = fmu.instantiate()
    L = fmu.lib
    try:
        if call == "doStep_before_init":
            assert L.fmi2DoStep(c, 0.0, 0.01, 1) == ERROR
        elif call == "get_before_init":
            vr = (C.c_uint * 1)(fmu.vr["tip.r[1]"])
            assert L.fmi2GetReal(c, vr, 1, (C.c_double * 1)()) == ERROR
            assert "fmi2GetReal is not allowed when the FMU is instantiated" in fmu.log[-1][2]
        else:
            assert fmu.start(c) == OK
            if call == "setup_after_init":
                assert L.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == ERROR
            elif call == "enter_twice":
                assert L.fmi2EnterInitializationMode(c) == ERROR
            elif call == "derivative_before_step":
                assert fmu.derivative(c, ["tip.r[3]"], ["tip.f[3]"], [1.0])[0] == ERROR
                assert "no communication step to differentiate" in fmu.log[-1][2]
            else:
                assert L.fmi2DoStep(c, 0.0, 0.01, 1) == OK
                assert L.fmi2Terminate(c) == OK
                for _ in range(2):
                    assert L.fmi2DoStep(c, 0.01, 0.01, 1) == ERROR
                    assert "fmi2DoStep after fmi2Terminate" in fmu.log[-1][2]
        assert fmu.log[-1][0] == ERROR and fmu.log[-1][1] == "logStatusError"
    finally:
        L.fmi2FreeInstance(c)


def test_debug_logging_switches_the_declared_categories_by_name(fmu):
    """fmi2SetDebugLogging (FMI 2.0.4 section 2.1.5): the categories named, all of them for none; an undeclared
    name is an error naming it and changes nothing. The names are those modelDescription.xml declares."""
    from ffrf_fmu.fmu.native import LOG_CATEGORIES

    assert [c.name for c in fmu.md.logCategories] == list(LOG_CATEGORIES)
    L = fmu.lib
    L.fmi2SetDebugLogging.argtypes = [C.c_void_p, C.c_int, C.c_size_t, C.POINTER(C.c_char_p)]

    def switch(c, on, names):
        return L.fmi2SetDebugLogging(c, on, len(names), (C.c_char_p * max(len(names), 1))(*[n.encode() for n in names]))

    def refused_call_logs(c):  # a call in the wrong state: fmi2Error, logged under logStatusError if that is on
        fmu.log.clear()
        assert L.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == ERROR
        return [m for m in fmu.log if m[0] == ERROR]

    c = fmu.instantiate()
    try:
        assert fmu.start(c) == OK
        assert refused_call_logs(c)  # at instantiation the status categories are on
        assert switch(c, 0, ["logStatusError"]) == OK
        assert refused_call_logs(c) == []
        assert switch(c, 0, ["logAll", "logStatusWarning"]) == OK and refused_call_logs(c) == []
        assert switch(c, 1, []) == OK  # no names: every category
        assert refused_call_logs(c)[0][1] == "logStatusError"
        fmu.log.clear()
        assert switch(c, 0, ["logStatusError", "logStatusNonsense"]) == ERROR
        assert 'unknown log category "logStatusNonsense"' in fmu.log[-1][2]
        assert all(name in fmu.log[-1][2] for name in LOG_CATEGORIES)
        assert refused_call_logs(c)  # nothing changed: errors still logged
        assert switch(c, 0, []) == OK and refused_call_logs(c) == []
    finally:
        L.fmi2FreeInstance(c)


def test_two_instances_reset_and_state_round_trips_are_bit_identical(fmu):
    """Two instances stepped in turn give one instance's numbers; fmi2Reset gives a fresh run; a state
    saved at 0.05 s and set after 0.1 s (directly, and through its serialized bytes into another instance)
    gives the same continuation bit for bit."""
    L = fmu.lib
    load = lambda t: np.sin(20.0 * t)  # noqa: E731
    ref_c = fmu.instantiate(name="ref")
    assert fmu.start(ref_c) == OK
    ref = _run(fmu, ref_c, 10, load=load)
    a, b = fmu.instantiate(name="a"), fmu.instantiate(name="b")
    try:
        for c in (a, b):
            assert fmu.start(c) == OK
        for k in range(10):
            for c in (a, b):
                _run(fmu, c, 1, k0=k, load=load)
        assert np.array_equal(fmu.get(a, OUT), ref) and np.array_equal(fmu.get(b, OUT), ref)
        assert L.fmi2Reset(a) == OK
        assert fmu.start(a) == OK
        assert np.array_equal(_run(fmu, a, 10, load=load), ref)
        # state round trips
        assert L.fmi2Reset(a) == OK and fmu.start(a) == OK
        _run(fmu, a, 5, load=load)
        state = C.c_void_p()
        assert L.fmi2GetFMUstate(a, C.byref(state)) == OK
        _run(fmu, a, 5, k0=5, load=load)
        assert L.fmi2SetFMUstate(a, state) == OK
        assert np.array_equal(_run(fmu, a, 5, k0=5, load=load), ref)
        size = C.c_size_t()
        assert L.fmi2SerializedFMUstateSize(a, state, C.byref(size)) == OK
        buf = C.create_string_buffer(size.value)
        assert L.fmi2SerializeFMUstate(a, state, buf, size) == OK
        other = C.c_void_p()
        assert L.fmi2Reset(b) == OK  # b, freshly reset, takes the serialized state of a
        assert L.fmi2DeSerializeFMUstate(b, buf, size, C.byref(other)) == OK
        assert L.fmi2SetFMUstate(b, other) == OK
        assert np.array_equal(_run(fmu, b, 5, k0=5, load=load), ref)
        # a damaged serialized state is refused when read, naming why
        raw = bytearray(buf.raw)
        raw[len(raw) - 3] ^= 0x40
        bad = C.c_void_p()
        assert L.fmi2DeSerializeFMUstate(b, bytes(raw), size, C.byref(bad)) == ERROR
        assert "checksum mismatch" in fmu.log[-1][2]
        assert L.fmi2DeSerializeFMUstate(b, buf.raw[:-8], size.value - 8, C.byref(bad)) == ERROR
        assert "wrong size" in fmu.log[-1][2]
        for s in (state, other):
            L.fmi2FreeFMUstate(a, C.byref(s))
    finally:
        for c in (a, b, ref_c):
            L.fmi2FreeInstance(c)


def test_directional_derivatives_equal_central_differences_of_two_runs(fmu):
    """Both meanings (docs/fmu.md, "Directional derivatives"). FMI's, fmi2GetDirectionalDerivative: the partial
    derivatives of the outputs with respect to the inputs at the communication point, against central
    differences of the outputs read with the input moved by +-0.01 N before any doStep: both zero; refused in
    initialization mode, naming why. The step's, ffrf2GetStepDerivative: d(outputs at t_c + H)/d(tip.f[3]) of the
    last step, against two runs of that step from a saved state with the load changed by +-0.01 N (the FMU's
    own step, relative 1e-2: derivatives.py DERIVATIVE_STEPS): equal to 1e-7 of the largest derivative (what
    differs is the order of the same floating-point sums)."""
    L = fmu.lib
    c = fmu.instantiate()
    try:
        assert L.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == OK and L.fmi2EnterInitializationMode(c) == OK
        assert fmu.derivative(c, OUT, ["tip.f[3]"], [1.0], step=False)[0] == ERROR
        assert "initialization mode: the partial derivatives of the initial unknowns are not provided" in fmu.log[-1][2]
        L.fmi2FreeInstance(c)
        c = fmu.instantiate()
        assert fmu.start(c, {"tip.f[3]": 1.0}) == OK
        _run(fmu, c, 3)
        state = C.c_void_p()
        assert L.fmi2GetFMUstate(c, C.byref(state)) == OK
        sides = []
        for f in (1.01, 0.99):
            assert L.fmi2SetFMUstate(c, state) == OK
            assert fmu.set(c, {"tip.f[3]": f}) == OK
            sides.append(_run(fmu, c, 1, k0=3))
        fd = (sides[0] - sides[1]) / 0.02
        assert L.fmi2SetFMUstate(c, state) == OK
        assert fmu.set(c, {"tip.f[3]": 1.0}) == OK
        end = _run(fmu, c, 1, k0=3)
        status, d = fmu.derivative(c, OUT, ["tip.f[3]"], [1.0])
        assert status == OK, fmu.log[-2:]
        assert d[2] > 0.0  # pushing the tip up moves it up
        # FMI's meaning at this communication point: the outputs do not move with the input (no feedthrough)
        at_point = []
        for f in (1.01, 0.99):
            assert fmu.set(c, {"tip.f[3]": f}) == OK
            at_point.append(fmu.get(c, OUT))
        assert fmu.set(c, {"tip.f[3]": 1.0}) == OK
        status, d0 = fmu.derivative(c, OUT, ["tip.f[3]"], [1.0], step=False)
        assert status == OK and np.array_equal(d0, np.zeros(len(OUT)))
        assert np.array_equal((at_point[0] - at_point[1]) / 0.02, d0)
        assert np.allclose(d, fd, rtol=0, atol=1e-7 * np.max(np.abs(fd)))
        assert np.array_equal(fmu.get(c, OUT), end)  # the derivative left the FMU where it was
        # refused requests, each with its cause
        assert fmu.derivative(c, OUT, ["tip.r[1]"], [1.0])[0] == ERROR
        assert "tip.r[1] not input(s)" in fmu.log[-1][2]
        assert fmu.derivative(c, ["solver.newton_iterations"], ["tip.f[3]"], [1.0])[0] == ERROR
        assert "not Real output(s)" in fmu.log[-1][2]
        assert fmu.derivative(c, OUT, ["tip.f[3]"], [float("nan")])[0] == ERROR
        L.fmi2FreeFMUstate(c, C.byref(state))
    finally:
        L.fmi2FreeInstance(c)


def test_the_fmu_is_the_c_runtime_driven_by_its_input_rule_bit_for_bit(fmu):
    """The standalone C runtime (runtime/native/binding.py, the library a standalone run steps in) created
    from the FMU's own image and started from the FMU's initial state, stepped at H = h with the FMU's
    input rule (point values of runtime/input_rule.py, one `advance` of kind EXTRAPOLATED per communication step): every
    output of 20 steps under a varying tip load equals the FMU's, bit for bit. The FMI layer adds nothing
    to the numbers."""
    from ffrf_fmu.fmu.native.resource import images
    from ffrf_fmu.runtime import input_rule
    from ffrf_fmu.runtime.native.binding import EXTRAPOLATED, NativeBody
    from ffrf_fmu.runtime.outputs import OUTPUT_WIDTH

    L = fmu.lib
    c = fmu.instantiate()
    try:
        assert fmu.start(c) == OK
        state = C.c_void_p()
        assert L.fmi2GetFMUstate(c, C.byref(state)) == OK
        size = C.c_size_t()
        assert L.fmi2SerializedFMUstateSize(c, state, C.byref(size)) == OK
        buf = C.create_string_buffer(size.value)
        assert L.fmi2SerializeFMUstate(c, state, buf, size) == OK
        L.fmi2FreeFMUstate(c, C.byref(state))
        n_body = int.from_bytes(buf.raw[16:24], "little")  # model.c: the serialized state's layout
        body = NativeBody(images((fmu.dir / "resources" / "body.bin").read_bytes())["linear"])
        body.set_state(np.frombuffer(buf.raw[len(buf.raw) - 8 * n_body:], dtype="<f8"))
        ports = [("hub", "motion", "motion"), ("tip", "force", "force")]
        names = [v.name for v in fmu.md.modelVariables if v.causality == "output" and v.type == "Real"]
        point = body.array("point_values").reshape(len(ports), input_rule.WIDTH)
        W = OUTPUT_WIDTH  # the runtime's row: every port's OUTPUT_FIELDS, the energies, the iterations
        row = np.empty(W * len(ports) + 5)
        cols = {"r": (0, 3), "R": (3, 12), "v": (12, 15), "w": (15, 18), "f": (18, 21), "t": (21, 24), "a": (24, 27),
                "dw": (27, 30)}
        H = 0.01
        for k in range(20):
            f = (0.3 * np.sin(7.0 * k * H), 0.0, 2.0 * np.cos(5.0 * k * H))
            assert fmu.set(c, {f"tip.f[{i + 1}]": f[i] for i in range(3)}) == OK
            assert L.fmi2DoStep(c, k * H, H, 1) == OK
            point[...] = 0.0  # hub at rest at its reference frame (the FMU's start values), the tip load held
            point[0, input_rule.COLUMNS["R"]] = np.eye(3).ravel()
            point[1, input_rule.COLUMNS["f"]] = f
            done, status, _ = body.advance(EXTRAPOLATED, 1, H, k * H, row, None)
            assert (done, status) == (1, 0)
            got = fmu.get(c, names)
            eta, yd = body.array("eta"), body.array("yd")
            n_se = len({n.split("[")[1].split(",")[0] for n in names if n.startswith("modal.")})
            nm, cfg = eta.size // n_se, body.array("cfg_map").reshape(n_se, -1)
            for name, value in zip(names, got):
                if name.startswith("modal."):  # the body's eta and their rates (cfg_map columns 6 .. 6 + nm)
                    e, i = (int(x) - 1 for x in name.split("[")[1][:-1].split(","))
                    want = eta[e * nm + i] if name.startswith("modal.eta[") else yd[cfg[e, 6 + i]]
                    assert value == want, (k, name, value, want)
                    continue
                if name.startswith("energy."):
                    j = W * len(ports) + ("kinetic_rigid", "kinetic_elastic", "strain", "work_external").index(name[7:])
                else:
                    p, field, idx = name.split(".")[0], name.split(".")[1].split("[")[0], name.split("[")[1][:-1]
                    j0, j1 = cols[field]
                    ix = [int(i) - 1 for i in idx.split(",")]
                    j = W * [q[0] for q in ports].index(p) + j0 + (3 * ix[0] + ix[1] if len(ix) == 2 else ix[0])
                assert value == row[j], (k, name, value, row[j])
        assert np.abs(fmu.get(c, ["tip.r[3]"])).max() > 1e-4  # the load moved the tip: the comparison means something
        assert "modal.eta[1,1]" in names and np.abs(body.array("eta")).max() > 1e-6  # the modes compared moved
        assert "tip.a[3]" in names and "tip.dw[2]" in names and np.abs(fmu.get(c, ["tip.a[3]"])).max() > 1e-3
    finally:
        L.fmi2FreeInstance(c)


def test_instances_in_threads_run_apart(fmu):
    """Two instances stepped at once from two threads (ctypes releases the GIL: the C code runs in parallel)
    give the numbers of one instance run alone: no state is shared between instances."""
    import threading

    load = lambda t: np.cos(30.0 * t)  # noqa: E731
    ref_c = fmu.instantiate(name="alone")
    assert fmu.start(ref_c) == OK
    ref = _run(fmu, ref_c, 20, load=load)
    fmu.lib.fmi2FreeInstance(ref_c)
    results, errors = {}, []

    def worker(k):
        try:
            c = fmu.instantiate(name=f"thread{k}")
            assert fmu.start(c) == OK
            results[k] = _run(fmu, c, 20, load=load)
            fmu.lib.fmi2FreeInstance(c)
        except Exception as e:  # noqa: BLE001 - reported by the main thread
            errors.append(e)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert all(np.array_equal(results[k], ref) for k in range(2))
