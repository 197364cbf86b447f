"""Which term set: ONE rule for `info` and `advise` (docs/inertia-terms.md, "Choosing the term set").

Witteveen's indicators (invariants.py) say which terms are large at a nominal deflection; whether they
change what a run computes depends on the loads and the chain. This rule therefore measures each term's
effect where a driven spin makes it steady: the relative equilibrium of the reduced body at the scene's
largest drive rate (linear.steady_spin: Newton on the runtime equations, no reference, no time run), once
per term set and once per switch of `full` alone. Gravity along the spin axis is steady in the spinning
frame and part of that equilibrium (the sag of a rotor spun about a vertical axis: models/sagging_rotor.toml);
gravity across the axis turns in the spinning frame, a periodic load, and is left out.
"""
from __future__ import annotations

import numpy as np

from .model import Body, Scene
from .spin import spin_drive_rotation

INFO_TOLERANCE = 0.01  # `info` states the rule's pick at this tolerance (advise takes the user's)
TERM_SHARE = 0.5  # a term set may leave at most this share of the tolerance to the terms it lacks
# per-step cost of each term set against `linear` at the same chain (numpy path; benchmarks/term_cost.py,
# docs/inertia-terms.md): the cheapest set within TERM_SHARE x tolerance of `full` wins
TERM_SETS_BY_COST = ("linear", "gyroscopic", "full")
SWITCH_ALONE = ("inertia_W1", "inertia_W2", "inertia_coupling", "coriolis")
# linear's steady displacements below this fraction of full's: linear leaves the body (all but) undeformed (a solid held on
# the spin axis by one frame has no load inside its superelement without W1), and the changes are relative to full's
LINEAR_AT_REST = 1e-3


def steady_term_effects(body: Body, scene: Scene, *, stiffening: bool = False) -> dict:
    """The effect of each term set and of each switch of `full` alone on the steady spin of `body` at
    the scene's largest drive rate (under the gravity along the spin axis, module doc): the boundary nodes'
    displacements u in the spinning frame (all
    relative to their reference positions), compared with `linear` and with `full` as
        change[set] = max |u_set - u_linear| / max |u_linear|,  to_full[set] = max |u_set - u_full| / max |u_linear|.
    status "ok", or why nothing was evaluated (no driven spin; a drive not about an axis through its own
    port; no steady state: the spin is beyond what the superelements hold)."""
    from .linear import steady_spin
    from .reduction import reduce_body
    from .spin_supports import supported_measure

    driven = spin_drive_rotation(body, scene)
    if driven is not None and driven[1] == "compliant":  # spun through a drive spring on compliant supports: the whirl
        how = supported_measure(body, scene, stiffening=stiffening)
        return how if "status" in how else measured_term_effects(**how, stiffening=stiffening)
    if driven is None:
        return {"status": "no driven spin in the scene: nothing steady to evaluate the terms on",
                "free_axial_rotation": free_axial_rotation(body, scene)}
    spin = driven[0]
    rate, axis, port = spin.peak, spin.axis, spin.port
    data = reduce_body(body, stiffening=stiffening, inertia=True).data
    node = data.port(port).node
    x_port = data.node_positions[node]
    if np.linalg.norm(np.cross(axis, x_port)) > 1e-9 * body.length:  # steady_spin spins about the origin
        return {"status": f"drive {port}.rotation: its axis does not pass through the world origin"}
    if any(p.translation != "motion" and p.rotation == "motion" for p in data.ports if p.node == node):
        return {"status": f"drive {port}.rotation on a free translation: no relative equilibrium"}
    g = np.asarray(scene.gravity, dtype=float)
    g_axis = float(g @ axis) * axis  # the steady part of gravity in the spinning frame (module doc)
    return measured_term_effects(
        data, lambda system: steady_spin(system, rate, axis).xN - data.node_positions, rate=rate, axis=axis,
        stiffening=stiffening, measure=f"steady spin at {rate:.3g} rad/s", failure="steady state", gravity=g_axis)


def measured_term_effects(data, displacements, *, rate: float, axis, stiffening: bool, measure: str, failure: str,
                          critical=None, **system) -> dict:
    """steady_term_effects' result from `displacements(system)`, the boundary nodes' displacements u (rows) of the
    steady state it measures on a runtime.body.BodySystem(data, terms, full_terms, **system) of each of term_runs():
    status "ok" with change and to_full (relative to linear's largest |u|, or full's when linear's is at most
    LINEAR_AT_REST of it) and `measure` (the text naming what was measured); else status names the run with no
    `failure` ("steady state") or a body the steady state does not deform. critical(system), when given, is
    evaluated after each term set's own run (not the switches') and reported as `critical_speed` per set."""
    from .runtime.body import BodySystem

    u, crit = {}, {}
    for label, terms, ft in term_runs():
        s = BodySystem(data, terms=terms, full_terms=ft, **system)
        try:
            u[label] = displacements(s)
            if critical is not None and label == terms:  # the sets (the switches' lie between theirs): reported, not ruled on
                crit[label] = critical(s)
        except (RuntimeError, np.linalg.LinAlgError) as e:
            return {"status": f"no {failure} at {rate:.3g} rad/s with {label} ({e})"}
    scale = np.linalg.norm(u["linear"], axis=1).max()
    scale_of = "linear"
    full_scale = np.linalg.norm(u["full"], axis=1).max()
    if scale <= LINEAR_AT_REST * full_scale:  # one superelement held on the axis: linear has no load inside it
        scale, scale_of = full_scale, "full"  # (GenStruct: only W1's constant centrifugal load widens it)
    if scale == 0.0:
        return {"status": "the steady spin does not deform the body"}
    rel = lambda a, b: float(np.linalg.norm(a - b, axis=1).max() / scale)  # noqa: E731
    out = {
        "status": "ok", "spin_rate": float(rate), "spin_axis": [float(x) for x in axis], "stiffening": stiffening,
        "superelements": len(data.superelements), "displacement_m": float(scale), "scale_of": scale_of,
        "measure": measure,
        "change": {k: rel(v, u["linear"]) for k, v in u.items()},
        "to_full": {k: rel(v, u["full"]) for k, v in u.items()},
    }
    if critical is not None:
        out["critical_speed"] = crit
    return out


def term_runs() -> list[tuple[str, str, tuple[str, ...]]]:
    """(label, term set, full_terms) of each measurement: every set, each switch of `full` alone, and `full`
    without each switch (choose_full_terms)."""
    from .runtime.terms import FULL_TERMS

    runs = [(name, name, FULL_TERMS) for name in TERM_SETS_BY_COST]
    runs += [(f"full[{s}]", "full", (s,)) for s in SWITCH_ALONE]
    return runs + [(f"full-{s}", "full", tuple(x for x in FULL_TERMS if x != s)) for s in SWITCH_ALONE]


def free_axial_rotation(body: Body, scene: Scene) -> dict | None:
    """The body's rotation about its own axis when no port holds it (every port's rotation is force-driven:
    a spherical joint, free ends) and the scene sets the body moving (loads, gravity, initial velocity or
    deformation, drives), else None. That rotation is a rigid-body motion whose only inertia is the polar
    one, J_p = m11 L, a small fraction of the transverse J_t = m L^3 / 12 on a beam. The elastic motion's
    angular momentum about the axis (a bending vibration in two planes whirls) is balanced against J_p
    alone, and only the inertia coupling S(q) (eq. 55) puts it into the frame's angular momentum: `linear`
    drops it and the body spins about its axis by that momentum / J_p (B2, one superelement: a mean axial
    spin of -0.0066 rad/s after the tip load, where the full-order beam and S(q) keep it at 0 as Euler's
    equations of a symmetric body do; docs/accuracy.md)."""
    if body.solid is not None or any(p.rotation != "force" for p in body.ports):
        return None  # a solid has no beam axis whose polar inertia is small
    ini = scene.initial
    moving = (scene.loads or scene.unbalances or scene.drives or any(scene.gravity) or any(ini.velocity) or any(ini.angular_velocity)
              or ini.port_displacements)
    if not moving:
        return None
    sec = body.section
    m11 = sec.m11 if sec.m11 is not None else sec.m22 + sec.m33
    L = body.length
    return {"polar_inertia": m11 * L, "transverse_inertia": sec.m * L**3 / 12.0,
            "ratio": m11 * L / (sec.m * L**3 / 12.0)}


def choose_term_set(effects: dict, tolerance: float) -> tuple[str, str]:
    """THE term-set rule (info and advise): (term set, reason) from `steady_term_effects`.
    `linear` when the complete set `full` changes the steady response by at most TERM_SHARE x tolerance;
    else the cheapest of TERM_SETS_BY_COST whose response is within TERM_SHARE x tolerance of full's.
    Without a steady driven spin there is nothing to measure the terms on: `linear`, the CM frames carry
    the rigid-body inertia exactly, and Witteveen's flags are reported as flags (measured: gyroscopic and
    full were no closer to the full-order beam on B1 and coned_beam, docs/inertia-terms.md)."""
    budget = TERM_SHARE * tolerance
    free = effects.get("free_axial_rotation")
    if effects.get("status") != "ok" and free:
        return "gyroscopic", (
            f"{effects.get('status')}; but no port holds the body's rotation about its own axis and the scene "
            f"moves the body: that rotation's only inertia is the polar one, J_p = {free['polar_inertia']:.3g} "
            f"({free['ratio']:.2g} x the transverse J_t), which the elastic motion's angular momentum about the "
            "axis drives unless the inertia coupling S(q) (eq. 55) is in the equations: gyroscopic, the cheapest "
            "set with it (term_rule.free_axial_rotation; B2: linear spins the body, docs/accuracy.md)")
    if effects.get("status") != "ok":
        return "linear", (f"{effects.get('status')}; linear: the CM frames carry the rigid-body inertia exactly, "
                          "and no term set was measured closer to the full-order beam without a steady spin "
                          "(docs/inertia-terms.md)")
    ch, tf = effects["change"], effects["to_full"]
    parts = ", ".join(f"{s} {ch[f'full[{s}]']:.2%}" for s in SWITCH_ALONE)
    what = (f"{effects['measure']} "
            f"({effects['superelements']} SE, stiffening "
            f"{'on' if effects['stiffening'] else 'off'}): full changes the boundary displacements by {ch['full']:.2%} "
            f"of linear's (each switch alone: {parts}; gyroscopic {ch['gyroscopic']:.2%})")
    if ch["full"] <= budget:
        return "linear", f"{what} <= {TERM_SHARE:g} x tolerance = {budget:.2%}: the linear terms suffice"
    pick = next(s for s in TERM_SETS_BY_COST if tf[s] <= budget)
    return pick, (f"{what} > {TERM_SHARE:g} x tolerance = {budget:.2%}; {pick} is the cheapest set within "
                  f"{budget:.2%} of full ({', '.join(f'{s} {tf[s]:.2%}' for s in TERM_SETS_BY_COST)} from full)")


def choose_full_terms(effects: dict, tolerance: float) -> tuple[tuple[str, ...], str]:
    """Which switches of `full` (FULL_TERMS) a body needs, from `steady_term_effects`: a switch is kept when
    leaving it out alone moves the steady displacements by more than TERM_SHARE x tolerance / len(SWITCH_ALONE)
    (`to_full["full-<switch>"]`); the switches left out share the budget, and their effects add to first order
    (each is small against the response). Witteveen's 7.3.3: W1's constant centrifugal load widens the body;
    W2's deformation-dependent part matters only for a structure soft against that widening (his GenStruct1).
    All switches when nothing was measured (no steady spin)."""
    if effects.get("status") != "ok" or "full-inertia_W1" not in effects.get("to_full", {}):
        return tuple(SWITCH_ALONE), "no steady spin measured: all switches of full"
    share = TERM_SHARE * tolerance / len(SWITCH_ALONE)
    tf = effects["to_full"]
    keep = tuple(s for s in SWITCH_ALONE if tf[f"full-{s}"] > share)
    parts = ", ".join(f"without {s} {tf[f'full-{s}']:.3%}" for s in SWITCH_ALONE)
    return keep, (f"{effects['measure']}, each switch of full left out alone ({parts} of "
                  f"{effects['scale_of']}'s displacements): kept where > TERM_SHARE x tolerance / {len(SWITCH_ALONE)} = "
                  f"{share:.3%}: {', '.join(keep) or 'none'}")
