"""Directional derivatives provided by a body FMU (docs/fmu.md, "Directional derivatives"), in their two
meanings. FMI's (fmi2GetDirectionalDerivative): the partial derivatives of the outputs with respect to the
inputs at the communication point, zero (no direct feedthrough), checked against the outputs read with
each input moved, and refused in initialization mode. The last step's (ffrf2GetStepDerivative, not an FMI
function, what the interface-Jacobian master uses): declared in the modelDescription, equal to finite
differences of two FMU runs from a saved state, per instance, and harmless to the run.

The derivatives are those of the step as the FMU computes it (central differences of two re-runs of
the step inside the FMU, docs/fmu.md): finite differences of two FMU runs see the same map, up to
its round-off and truncation, and up to the FMU's Newton changing its iteration count within the
difference step (the map is smooth only between such changes: measured up to 4e-5 of a block).

What is checked: fmpy validate clean with the derivatives declared; the derivatives against
central differences of two FMU runs (doStep from a saved FMU state with the known input perturbed up
and down) within 1e-5 relative. "Relative" is per block of the Jacobian: output group (`port.field`,
each energy) x input group (`port.field`), the largest difference over the block against its largest
entry, so that a reaction in N and a rotation entry are each judged on their own scale, and an entry
that is tiny against its block (the hub force from a tip moment about the beam axis, 1e-2 of the
block) is judged at the precision both sides can give it: a reaction carries ~1e-9 N of round-off.
"""
from __future__ import annotations

import ctypes as C

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from ffrf_fmu.fmu.builder import BuildError, build_fmu, read_fmu_config
from ffrf_fmu.fmu.variables import DIRECTIONAL_DERIVATIVES
from ffrf_fmu.master import FmuInstance
from ffrf_fmu.master.instance import STEP_DERIVATIVE
from ffrf_fmu.runtime.rotation import expm, skew
from test_fmu import _inputs_at, _started

H = 0.02  # two internal steps of the scene's 10 ms: the derivative is propagated over both
LOADS = {"tip.f[1]": 1.0, "tip.f[3]": 2.0, "tip.t[1]": 0.1}


@pytest.fixture(scope="module", params=["native", "python"])
def fmu(request, small, small_fmu):
    """The small beam's FMU of each runtime (the derivatives are the same rule in C and in Python)."""
    if request.param == "python":
        return small_fmu
    return build_fmu(small, small.parent / "small_spin_native.fmu", scene="spin")


def _run(inst, inputs, n):
    """n communication steps of H with the scene's hub motion and LOADS on the tip."""
    for k in range(n):
        _inputs_at(inst, inputs(k * H))
        inst.set(list(LOADS), list(LOADS.values()))
        inst.fmu.doStep(k * H, H)
    _inputs_at(inst, inputs(n * H))
    inst.set(list(LOADS), list(LOADS.values()))
    return n * H


def _step(inst, unknowns, knowns, seed):
    """The derivatives of the last step (ffrf2GetStepDerivative, docs/fmu.md) by value references, raising
    fmpy's FMICallException on a status other than OK, as fmpy's getDirectionalDerivative does."""
    f = getattr(inst.fmu.dll, STEP_DERIVATIVE)
    f.argtypes = [C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_uint), C.c_size_t, C.POINTER(C.c_double),
                  C.POINTER(C.c_double)]
    out = (C.c_double * len(unknowns))()
    status = f(inst.fmu.component, (C.c_uint * len(unknowns))(*unknowns), len(unknowns), (C.c_uint * len(knowns))(*knowns),
               len(knowns), (C.c_double * len(seed))(*seed), out)
    if status != 0:
        raise FMICallException(STEP_DERIVATIVE, status)
    return list(out)


def _groups(names):
    out: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        out.setdefault(n.split("[")[0], []).append(i)
    return out


def test_model_description_declares_derivatives_and_fmpy_validates_clean(fmu):
    md = read_model_description(fmu)
    assert md.coSimulation.providesDirectionalDerivative
    assert validate_fmu(str(fmu)) == []
    outputs = [u for u in md.outputs]
    assert len(outputs) == sum(v.causality == "output" for v in md.modelVariables)
    for u in outputs:  # no direct feedthrough (tests/test_model_structure.py); the derivatives are the step map's
        assert u.dependencies == []
    assert DIRECTIONAL_DERIVATIVES in md.description
    from ffrf_fmu.fmu.run import is_native

    assert is_native(fmu) or read_fmu_config(fmu)["directional_derivatives"] is True


def test_without_the_native_loader_no_derivatives_are_declared(small, tmp_path, monkeypatch):
    """No C compiler: the pythonfmu build is an error (it made an FMU only Python hosts load, silently); asked
    for without the native loader, pythonfmu's binary alone has no fmi2GetDirectionalDerivative,
    so the modelDescription declares none, and the outputs no dependencies (no direct feedthrough at
    the communication point)."""
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(BuildError, match="native loader cannot be built"):  # never silently
        build_fmu(small, tmp_path / "plain.fmu", scene="spin", runtime="python")
    path = build_fmu(small, tmp_path / "plain.fmu", scene="spin", runtime="python", native_loader=False)
    md = read_model_description(path)
    assert not md.coSimulation.providesDirectionalDerivative
    assert all(u.dependencies == [] for u in md.outputs)
    assert DIRECTIONAL_DERIVATIVES not in md.description
    assert validate_fmu(str(path)) == []


def _fd_runs(inst, state, t, known, delta, outs, R_axis=None):
    """Central difference of two FMU runs from `state`: the known input up and down by delta (a
    rotation input along expm(+-delta axis) R, which stays a rotation)."""
    sides = []
    base = inst.get(known)
    for sign in (1.0, -1.0):
        inst.fmu.setFMUstate(state)
        if R_axis is not None:
            R = base.reshape(3, 3)
            inst.set(known, (expm(sign * delta * R_axis) @ R).ravel())
        else:
            inst.set(known, base + sign * delta)
        inst.fmu.doStep(t, H)
        sides.append(inst.get(outs))
    inst.set(known, base)
    return (sides[0] - sides[1]) / (2.0 * delta)


def test_directional_derivatives_equal_finite_differences_of_two_fmu_runs(small, fmu):
    """Every input of a spinning, translating, tip-loaded beam (hub motion-driven, tip force-driven),
    seeded one at a time (rotations along their three tangent directions), all Real outputs."""
    inst, inputs, _ = _started(fmu, "spin", small)
    try:
        md = inst.md
        outs = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
        out_vr = [inst.variable(n).valueReference for n in outs]
        t = _run(inst, inputs, 5)
        state = inst.fmu.getFMUstate()
        cases = []
        for name in inst.names("input"):
            field = name.split(".")[1].split("[")[0]
            if field == "R":
                continue
            # FD steps per kind (central, two runs), not the FMU's own: loads 0.03 N or N.m (the kinetic
            # energy's truncation error is 2e-5 of its block at 0.1, 2e-6 at 0.03), motions 5e-6 m or
            # rad of displacement over H
            delta = {"f": 3e-2, "t": 3e-2, "r": 5e-6, "v": 5e-6 / H, "w": 5e-6 / H,
                     "a": 1e-5 / H**2, "dw": 1e-5 / H**2}[field]
            cases.append(([name], [1.0], delta, None))
        Rn = [f"hub.R[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
        for k in range(3):
            cases.append((Rn, None, 5e-6, np.eye(3)[k]))
        D, FD, seeds_of = [], [], []
        for known, seed, delta, axis in cases:
            inst.fmu.setFMUstate(state)
            inst.fmu.doStep(t, H)
            if axis is not None:  # the tangent direction skew(axis) R, as a seed on the 9 entries
                seed = (skew(axis) @ inst.get(known).reshape(3, 3)).ravel()
            D.append(_step(inst, out_vr, [inst.variable(n).valueReference for n in known], seed))
            FD.append(_fd_runs(inst, state, t, known, delta, outs, axis))
            seeds_of.append(known[0].split("[")[0])
        D, FD = np.array(D).T, np.array(FD).T  # outputs x seeds
        worst, entry = 0.0, 0.0
        for g, rows in _groups(outs).items():
            for s in dict.fromkeys(seeds_of):
                cols = [j for j, x in enumerate(seeds_of) if x == s]
                fd, d = FD[np.ix_(rows, cols)], D[np.ix_(rows, cols)]
                scale = np.max(np.abs(fd))
                if scale == 0.0:
                    assert np.max(np.abs(d)) == 0.0, (g, s)
                    continue
                err = np.max(np.abs(d - fd)) / scale
                assert err < 1e-5, (g, s, err, d, fd)
                worst = max(worst, err)
                big = np.abs(fd) > 1e-3 * scale  # entries that are not tiny against their block, each on its own
                entry = max(entry, float(np.max(np.abs(d - fd)[big] / np.abs(fd)[big])))
        assert 0.0 < worst  # the comparison compared something
        # with the FMU's own input step the two runs are the FMU's internal ones: equal to round-off
        # (the seeds, the state restore and the value references all take the same path)
        inst.fmu.setFMUstate(state)
        inst.fmu.doStep(t, H)
        d = _step(inst, out_vr, [inst.variable("tip.f[3]").valueReference], [1.0])
        own = _fd_runs(inst, state, t, ["tip.f[3]"], 1e-2 * LOADS["tip.f[3]"], outs)
        assert np.max(np.abs(np.array(d) - own)) <= 1e-12 * np.max(np.abs(own))
        print(f"\n{D.shape[1]} seeds x {len(outs)} outputs: largest relative difference per block {worst:.2e}, "
              f"per entry (entries above 1e-3 of their block) {entry:.2e}")
        inst.fmu.freeFMUstate(state)
    finally:
        inst.close()


def test_two_instances_keep_their_derivatives_apart(small, fmu):
    """Interleaved steps and derivative requests of two instances give each the derivatives it has
    alone (bit for bit): the request travels inside the instance, nothing is shared."""
    def derivative(inst):
        outs = [inst.variable(n).valueReference for n in ("tip.r[3]", "tip.w[1]", "hub.f[3]")]
        return _step(inst, outs, [inst.variable("tip.f[3]").valueReference], [1.0])

    alone, _, _ = _started(fmu, "spin", small)
    a, inputs, _ = _started(fmu, "spin", small)
    b, _, _ = _started(fmu, "spin", small)
    try:
        _run(alone, inputs, 3)
        expected = derivative(alone)
        _run(a, inputs, 3)
        LOADS["tip.f[3]"] = -5.0  # b runs another load
        try:
            _run(b, inputs, 3)
        finally:
            LOADS["tip.f[3]"] = 2.0
        other = derivative(b)
        got = derivative(a)
        assert got == expected and other != expected
    finally:
        for inst in (alone, a, b):
            inst.close()


def test_derivative_requests_fail_clearly_and_leave_the_run_unchanged(small, fmu):
    inst, inputs, _ = _started(fmu, "spin", small)
    ref, _, _ = _started(fmu, "spin", small)
    vr = inst.variable
    try:
        with pytest.raises(FMICallException) as exc:  # no step yet: nothing to differentiate
            _step(inst, [vr("tip.r[1]").valueReference], [vr("tip.f[1]").valueReference], [1.0])
        assert exc.value.status == 3 and "no communication step" in inst.last_message()
        _run(inst, inputs, 2)
        _run(ref, inputs, 2)
        with pytest.raises(FMICallException):  # a known that is not an input
            _step(inst, [vr("tip.r[1]").valueReference], [vr("tip.r[2]").valueReference], [1.0])
        assert "not input" in inst.last_message()
        with pytest.raises(FMICallException):  # an unknown value reference
            _step(inst, [9999], [vr("tip.f[1]").valueReference], [1.0])
        d = _step(inst, [vr("tip.r[3]").valueReference], [vr("tip.f[3]").valueReference], [1.0])
        assert d[0] > 0.0  # pushing the tip up moves it up
        # the requests changed nothing: the next step equals the one of an instance never asked
        for k in (2, 3):
            for x in (inst, ref):
                x.fmu.doStep(k * H, H)
                _inputs_at(x, inputs((k + 1) * H))
                x.set(list(LOADS), list(LOADS.values()))
        names = inst.names("output")
        assert np.array_equal(inst.get(names), ref.get(names))
    finally:
        inst.close()
        ref.close()


def test_fmi_meaning_is_the_partial_derivative_at_the_communication_point(small, fmu):
    """fmi2GetDirectionalDerivative gives what FMI 2.0 defines: d(outputs)/d(inputs) at the communication point,
    with the state fixed. Every Real input moved by +-1e-3 (relative, at least 1e-3) and every Real output read
    before the next doStep: the central differences are zero, and so is every derivative the FMU gives (one
    call, all inputs seeded at once and each alone). In initialization mode the call is refused, naming why."""
    inst = FmuInstance("point", fmu)
    try:
        inst.fmu.setupExperiment(startTime=0.0)
        inst.fmu.enterInitializationMode()
        vr = inst.variable
        with pytest.raises(FMICallException) as exc:
            inst.fmu.getDirectionalDerivative([vr("tip.r[1]").valueReference], [vr("tip.f[1]").valueReference], [1.0])
        assert exc.value.status == 3 and "initialization mode" in inst.last_message()
        inst.fmu.exitInitializationMode()
        for k in range(3):
            inst.fmu.doStep(k * H, H)
        outs = [v.name for v in inst.md.modelVariables if v.causality == "output" and v.type == "Real"]
        ins = [v.name for v in inst.md.modelVariables if v.causality == "input" and v.type == "Real"]
        out_vr, in_vr = [vr(n).valueReference for n in outs], [vr(n).valueReference for n in ins]
        base = inst.get(ins)
        for j, name in enumerate(ins):
            delta = 1e-3 * max(1.0, abs(base[j]))
            sides = []
            for sign in (1.0, -1.0):
                inst.set([name], [base[j] + sign * delta])
                sides.append(inst.get(outs))
            inst.set([name], [base[j]])
            assert np.array_equal((sides[0] - sides[1]) / (2.0 * delta), np.zeros(len(outs))), name
            assert inst.fmu.getDirectionalDerivative(out_vr, [in_vr[j]], [1.0]) == [0.0] * len(outs), name
        assert inst.fmu.getDirectionalDerivative(out_vr, in_vr, list(np.linspace(1.0, 2.0, len(in_vr)))) == [0.0] * len(outs)
        with pytest.raises(FMICallException):  # a known that is not an input: refused as for the step's
            inst.fmu.getDirectionalDerivative(out_vr[:1], out_vr[:1], [1.0])
        assert "not input" in inst.last_message()
        # the step's derivatives of the same FMU are not zero (what the interface-Jacobian master reads)
        assert abs(_step(inst, [vr("tip.r[3]").valueReference], [vr("tip.f[3]").valueReference], [1.0])[0]) > 1e-6
    finally:
        inst.close()
