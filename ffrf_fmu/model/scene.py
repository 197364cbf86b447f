"""[scenes.NAME]: a scene's step, terms, drives and loads, initial state, metrics and reference, read and
checked against the body's ports; scene_body applies a scene's causality overrides."""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Sequence

from ..checked_toml import REQUIRED, ModelError, Reader, join, nearest, nonnegative, positive
from ..runtime.drives import KINDS as TIME_FUNCTION_KINDS
from ..runtime.terms import FULL_TERMS, TERM_SETS
from .keys import CAUSALITY_KEYS, DRIVE_KEYS, INITIAL_KEYS, LOAD_KEYS, METRICS_KEYS, REFERENCE_KEYS, ROTATION_DRIVE_KEYS, SCENE_KEYS, TIME_FUNCTION_DEFAULTS, TRANSLATION_DRIVE_KEYS, UNBALANCE_KEYS
from .schema import Body, Drive, INITIAL_STATES, Initial, Load, METRIC_KINDS, Metrics, OLD_METRIC_NAMES, PART_CAUSALITIES, PART_INDEX, ReferenceOptions, RotationDrive, Scene, TimeFunction, TranslationDrive, Unbalance


def _parse_time_function(r: Reader, t: dict, path: str, key: str) -> TimeFunction:
    p, v = join(path, key), t[key]
    if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
        return TimeFunction("constant", (("value", float(v)),))  # a plain number is a constant
    kinds = ", ".join(TIME_FUNCTION_KINDS)
    if not isinstance(v, dict):
        r.expected(p, f"a number or an inline table {{ kind = ..., <parameters> }} (kinds: {kinds})", v)
    kind = r.string(v, p, "kind", f"one of {kinds}")
    if kind not in TIME_FUNCTION_KINDS:
        near = nearest(kind, TIME_FUNCTION_KINDS)
        r.fail(join(p, "kind"), f"expected one of {kinds}, got {kind!r}" + (f"; did you mean {near!r}?" if near else ""))
    names, defaults = TIME_FUNCTION_KINDS[kind], TIME_FUNCTION_DEFAULTS.get(kind, {})
    what = f"a number (parameters of {kind}: {', '.join(names)})"
    r.table(v, p, {"kind": "a time-function kind", **{n: what for n in names}},
            required=[n for n in names if n not in defaults])
    params = {n: r.real(v, p, n, what, defaults.get(n, REQUIRED)) for n in names}
    if kind == "haug_spinup" and params["T"] <= 0.0:
        r.expected(join(p, "T"), "a positive spin-up time [s]", params["T"])
    if kind == "bump" and params["duration"] <= 0.0:
        r.expected(join(p, "duration"), "a positive bump duration [s]", params["duration"])
    if kind == "window" and params["t_end"] <= params["t_start"]:
        r.expected(join(p, "t_end"), f"a time after t_start = {params['t_start']}", params["t_end"])
    return TimeFunction(kind, tuple(sorted(params.items())))


def _parse_scene(r: Reader, body: Body, name: str, t: Any) -> Scene:
    sp = join("scenes", name)
    r.table(t, sp, SCENE_KEYS, required=("duration", "step"))
    ports = {p.name: p for p in body.ports}

    # causality first: drives and loads are checked against the scene's effective causality
    causality, effective = [], {p.name: (p.translation, p.rotation) for p in body.ports}
    cp = join(sp, "causality")
    for pname, c in r.table(t.get("causality", {}), cp, None).items():
        path = join(cp, pname)
        r.port_name(ports, path, pname)
        r.table(c, path, CAUSALITY_KEYS)
        tr = r.string(c, path, "translation", CAUSALITY_KEYS["translation"], ports[pname].translation, PART_CAUSALITIES)
        rot = r.string(c, path, "rotation", CAUSALITY_KEYS["rotation"], ports[pname].rotation, PART_CAUSALITIES)
        causality.append((pname, tr, rot))
        effective[pname] = (tr, rot)

    def require_part(path: str, pname: str, part: str, want: str, why: str):
        have = effective[pname][PART_INDEX[part]]
        if have != want and not (want == "motion" and have == "compliant"):  # a drive moves the spring's end
            r.fail(path, f"expected a {want}-driven {part}: port {pname!r} {part} is {have}-driven in this scene "
                   f"({why})")

    drives = []
    dp = join(sp, "drives")
    for pname, d in r.table(t.get("drives", {}), dp, None).items():
        path = join(dp, pname)
        r.port_name(ports, path, pname)
        r.table(d, path, DRIVE_KEYS)

        def part_drive(part, keys, cls, unit_vector, law):
            """The drive of one part: a unit vector and a time function, the part motion-driven."""
            if part not in d:
                return None
            pp = join(path, part)
            require_part(pp, pname, part, "motion", "only a motion-driven part can be prescribed")
            pt = r.table(d[part], pp, keys, required=(unit_vector, law))
            return cls(r.vec3(pt, pp, unit_vector, keys[unit_vector], unit=True), _parse_time_function(r, pt, pp, law))

        drives.append(Drive(pname, part_drive("rotation", ROTATION_DRIVE_KEYS, RotationDrive, "axis", "angle"),
                            part_drive("translation", TRANSLATION_DRIVE_KEYS, TranslationDrive, "direction",
                                       "displacement")))

    loads = []
    lv = t.get("loads", [])
    if not isinstance(lv, list):
        r.expected(join(sp, "loads"), SCENE_KEYS["loads"], lv)
    for i, lt in enumerate(lv):
        lp = join(join(sp, "loads"), i)
        r.table(lt, lp, LOAD_KEYS, required=("port",))
        pname = r.port_name(ports, join(lp, "port"), lt["port"])
        force = r.vec3(lt, lp, "force", LOAD_KEYS["force"], (0.0, 0.0, 0.0))
        moment = r.vec3(lt, lp, "moment", LOAD_KEYS["moment"], (0.0, 0.0, 0.0))
        why = "its reaction is an output; a load needs a force-driven part"
        if any(force):
            require_part(join(lp, "force"), pname, "translation", "force", why)
        if any(moment):
            require_part(join(lp, "moment"), pname, "rotation", "force", why)
        t0 = r.real(lt, lp, "t_start", LOAD_KEYS["t_start"], 0.0)
        t1 = r.real(lt, lp, "t_end", LOAD_KEYS["t_end"], math.inf, ok=lambda x: x > t0)
        loads.append(Load(pname, force, moment, t0, t1))

    unbalances = []
    uv = t.get("unbalances", [])
    if not isinstance(uv, list):
        r.expected(join(sp, "unbalances"), SCENE_KEYS["unbalances"], uv)
    drive_of = {d.port: d for d in drives}
    for i, ut in enumerate(uv):
        up = join(join(sp, "unbalances"), i)
        r.table(ut, up, UNBALANCE_KEYS, required=("port", "mass_eccentricity", "drive"))
        pname = r.port_name(ports, join(up, "port"), ut["port"])
        require_part(join(up, "port"), pname, "translation", "force", "an unbalance is a load on the body")
        me = r.real(ut, up, "mass_eccentricity", UNBALANCE_KEYS["mass_eccentricity"], ok=positive)
        dname = r.port_name(ports, join(up, "drive"), ut["drive"])
        if dname not in drive_of or drive_of[dname].rotation is None:
            r.fail(join(up, "drive"), f"expected a port with a rotation drive in this scene, got {dname!r}")
        ref = r.vec3(ut, up, "reference", UNBALANCE_KEYS["reference"], (0.0, 1.0, 0.0))
        axis = drive_of[dname].rotation.axis
        normal = [ref[k] - sum(a * b for a, b in zip(ref, axis)) * axis[k] for k in range(3)]
        if math.sqrt(sum(x * x for x in normal)) < 1e-9 * max(1e-300, math.sqrt(sum(x * x for x in ref))):
            r.fail(join(up, "reference"), f"expected {UNBALANCE_KEYS['reference']}, got {list(ref)} along the "
                   f"spin axis {list(axis)}")
        phase = r.real(ut, up, "phase", UNBALANCE_KEYS["phase"], 0.0)
        unbalances.append(Unbalance(pname, me, dname, ref, phase))

    ip = join(sp, "initial")
    it = r.table(t.get("initial", {}), ip, INITIAL_KEYS)
    displacements = []
    pdp = join(ip, "port_displacements")
    for pname in r.table(it.get("port_displacements", {}), pdp, None):
        path = join(pdp, pname)
        r.port_name(ports, path, pname)
        require_part(path, pname, "translation", "force", "a motion-driven port starts at its reference position")
        displacements.append((pname, r.vec3(it["port_displacements"], pdp, pname, "3 numbers [m]")))
    initial = Initial(
        r.vec3(it, ip, "velocity", INITIAL_KEYS["velocity"], (0.0, 0.0, 0.0)),
        r.vec3(it, ip, "angular_velocity", INITIAL_KEYS["angular_velocity"], (0.0, 0.0, 0.0)),
        tuple(displacements),
        it.get("state", "rest"),
    )
    if initial.state not in INITIAL_STATES:
        r.expected(join(ip, "state"), INITIAL_KEYS["state"], initial.state)
    if initial.state != "rest" and (displacements or any(initial.velocity) or any(initial.angular_velocity)):
        r.fail(join(ip, "state"), f"state {initial.state!r} sets the body's deformation and velocities itself: "
               "no port_displacements, velocity or angular_velocity with it")
    if initial.state != "rest" and any("compliant" in parts for parts in effective.values()):
        r.fail(join(ip, "state"), f"state {initial.state!r} is not available with compliant ports (compliant in this "
               f"scene: {sorted(p for p, parts in effective.items() if 'compliant' in parts)})")
    if initial.state == "steady_spin":
        try:
            steady_spin_drive(name, drives)
        except ValueError as e:
            r.fail(join(ip, "state"), str(e))

    duration = r.real(t, sp, "duration", SCENE_KEYS["duration"], ok=positive)
    cap = r.integer(t, sp, "max_newton_iterations", SCENE_KEYS["max_newton_iterations"], 0)
    if cap > 2**31 - 1:  # an FMU's Integer parameter (int32)
        r.expected(join(sp, "max_newton_iterations"), SCENE_KEYS["max_newton_iterations"] + ", at most 2^31 - 1", cap)
    outputs = t.get("outputs", [])
    if not isinstance(outputs, list) or not all(isinstance(o, str) for o in outputs):
        r.expected(join(sp, "outputs"), SCENE_KEYS["outputs"], outputs)
    for o in outputs:  # probes (eq. 92): "<port>_from_<port>", the first port seen from the second's frame
        seen, sep, frame = o.partition("_from_")
        if not sep or seen not in ports or frame not in ports or seen == frame:
            r.fail(join(sp, "outputs"), f"expected probe names '<port>_from_<port>' of two ports of the body "
                   f"({', '.join(ports)}), got {o!r}")
    return Scene(
        name=name,
        duration=duration,
        step=r.real(t, sp, "step", SCENE_KEYS["step"], ok=lambda x: 0.0 < x <= duration),
        rho_inf=r.real(t, sp, "rho_inf", SCENE_KEYS["rho_inf"], 0.8, ok=lambda x: 0.0 <= x <= 1.0),
        terms=r.string(t, sp, "terms", SCENE_KEYS["terms"], "linear", TERM_SETS),
        max_newton_iterations=cap,
        gravity=r.vec3(t, sp, "gravity", SCENE_KEYS["gravity"], (0.0, 0.0, 0.0)),
        drives=tuple(drives),
        loads=tuple(loads),
        initial=initial,
        causality=tuple(causality),
        metrics=_metrics(r, t.get("metrics", ""), join(sp, "metrics")),
        outputs=tuple(outputs),
        stiffening=r.boolean(t, sp, "stiffening", SCENE_KEYS["stiffening"], False),
        full_terms=_full_terms(r, t, sp),
        reference=_reference(r, t, sp),
        unbalances=tuple(unbalances),
    )


def steady_spin_drive(scene_name: str, drives: Sequence[Drive], t0: float = 0.0) -> tuple[Drive, float]:
    """The rotation drive a scene with initial state 'steady_spin' spins with, and its rate at t0 [rad/s]:
    the scene's first rotation drive, which must spin steadily there (a rate, no angular acceleration).
    ValueError naming the cause otherwise (the parser reports it at the scene's initial.state)."""
    from ..runtime.drives import evaluate

    rotating = [d for d in drives if d.rotation is not None]
    if not rotating:
        raise ValueError(f"scene {scene_name!r}: initial state 'steady_spin' needs a rotation drive")
    d = rotating[0]
    _, rate, acc = evaluate(d.rotation.angle.kind, dict(d.rotation.angle.params), t0)
    if rate == 0.0 or acc != 0.0:
        raise ValueError(f"scene {scene_name!r}: initial state 'steady_spin' needs the drive {d.port}.rotation to "
                         f"spin steadily at t = {t0:g} (rate {rate:g} rad/s, acceleration {acc:g} rad/s^2): e.g. a "
                         "ramp that started before t = 0")
    return d, float(rate)


def _reference(r: Reader, t: dict, sp: str) -> ReferenceOptions:
    if "reference" not in t:
        return ReferenceOptions()
    path = join(sp, "reference")
    rt = r.table(t["reference"], path, REFERENCE_KEYS)
    return ReferenceOptions(r.integer(rt, path, "elements", REFERENCE_KEYS["elements"], None, low=1),
                            r.real(rt, path, "step", REFERENCE_KEYS["step"], None, ok=positive))


def _metrics(r: Reader, v: Any, path: str) -> Metrics:
    """[scenes.NAME.metrics]: a table, or a kind alone (its primary metric: the first of the kind's
    when that is the tip deflection, else none)."""
    if isinstance(v, str) and v in OLD_METRIC_NAMES:
        r.fail(path, f"{v!r} was a benchmark's name; write the table [{path}] with kind = "
                     f"{OLD_METRIC_NAMES[v]!r} and the benchmark's windows and bands (docs/model-format.md)")
    if isinstance(v, str):
        if v and v not in METRIC_KINDS:
            r.expected(path, SCENE_KEYS["metrics"], v)
        return Metrics(v, "tip_deflection_max_m" if v == "tip_deflection" else "")
    t = r.table(v, path, METRICS_KEYS, required=("kind",))
    kind = r.string(t, path, "kind", METRICS_KEYS["kind"], choices=tuple(METRIC_KINDS))
    band = None
    if "band_hz" in t:
        b = t["band_hz"]
        if not (isinstance(b, list) and len(b) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                            for x in b) and 0 < b[0] < b[1] and math.isfinite(b[1])):
            r.expected(join(path, "band_hz"), METRICS_KEYS["band_hz"], b)
        band = (float(b[0]), float(b[1]))
    m = Metrics(kind, "", band, r.real(t, path, "min_window_s", METRICS_KEYS["min_window_s"], 0.0, ok=nonnegative),
                r.real(t, path, "coast_end_s", METRICS_KEYS["coast_end_s"], None, ok=positive)
                if "coast_end_s" in t else None)
    primary = r.string(t, path, "primary", METRICS_KEYS["primary"], "", m.names() + ("",))
    return dataclasses.replace(m, primary=primary)


def _full_terms(r: Reader, t: dict, sp: str) -> tuple[str, ...]:
    v = t.get("full_terms", list(FULL_TERMS))
    if not isinstance(v, list) or not all(isinstance(x, str) and x in FULL_TERMS for x in v) or len(set(v)) != len(v):
        r.expected(join(sp, "full_terms"), SCENE_KEYS["full_terms"], v)
    return tuple(v)


def scene_body(body: Body, scene: Scene) -> Body:
    """The body with the scene's causality overrides on its ports: the one place they are applied
    (the reduction, the standalone run, the FMU builder and the reference take the body it returns)."""
    over = {name: (tr, rot) for name, tr, rot in scene.causality}
    unknown = set(over) - {p.name for p in body.ports}
    if unknown:
        raise ModelError(f"{body.source}: scene {scene.name!r} sets the causality of unknown port(s) {sorted(unknown)}")
    ports = tuple(dataclasses.replace(p, translation=over[p.name][0], rotation=over[p.name][1]) if p.name in over else p
                  for p in body.ports)
    return dataclasses.replace(body, ports=ports)


def reduction_options(scene: Scene) -> dict:
    """reduce_body's options for a scene: stiffening (scene key) and the inertia data of `full`."""
    return {"stiffening": scene.stiffening, "inertia": scene.terms == "full"}
