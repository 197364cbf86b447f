"""The indicators the advisor reads (advise.py), none of which needs a reference run: the spin
against the first bending frequency (Southwell), the excitation band of the drives and loads, the
integrator's period error (generalized-alpha amplification), the free-free frequencies of one
superelement of a chain, and the step that divides a duration."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..model import Body
from ..runtime.steps import divides, whole_steps

_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # numpy 2 renamed trapz


def southwell_coefficient(n: int = 20001) -> float:
    """S1 = int_0^L (L^2 - x^2)/2 w'^2 dx / int_0^L w^2 dx for the first Euler-Bernoulli cantilever
    mode w (L = 1): omega^2 = omega_0^2 + S1 Omega^2 for a beam spun about its root, bending out of
    the plane of rotation (Southwell; 1.1933); in the plane of rotation the centrifugal load turns
    with the deflection and takes 1 off: S1 - 1 = 0.193."""
    x = np.linspace(0.0, 1.0, n)
    w, dw = _cantilever_mode(x)
    return float(_trapezoid((1.0 - x**2) / 2.0 * dw**2, x) / _trapezoid(w**2, x))


def _cantilever_mode(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    bl = 1.8751040687119611
    s = (math.cosh(bl) + math.cos(bl)) / (math.sinh(bl) + math.sin(bl))
    w = np.cosh(bl * x) - np.cos(bl * x) - s * (np.sinh(bl * x) - np.sin(bl * x))
    dw = bl * (np.sinh(bl * x) + np.sin(bl * x) - s * (np.cosh(bl * x) - np.cos(bl * x)))
    return w, dw


def amplification(wh: float, rho_inf: float) -> complex:
    """Principal root of the first-order generalized-alpha method (runtime/integrator.py) on
    y' = i omega y: per step, z ~ exp(i omega h)."""
    am = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf))
    af = 1.0 / (1.0 + rho_inf)
    g = 0.5 + am - af
    lam = 1j * wh
    # am a1 + (1 - am) a0 = af lam y1 + (1 - af) lam y0,  y1 = y0 + (1 - g) a0 + g a1   (h = 1)
    lhs = np.array([[1.0, -g], [-af * lam, am]])
    rhs = np.array([[1.0, 1.0 - g], [(1.0 - af) * lam, -(1.0 - am)]])
    z = np.linalg.eigvals(np.linalg.solve(lhs, rhs))
    return complex(z[np.argmin(np.abs(z - np.exp(lam)))])


def period_error(wh: float, rho_inf: float) -> float:
    """Relative period (frequency) error of the integrator at omega h (negative: too slow)."""
    return float(np.angle(amplification(wh, rho_inf)) / wh - 1.0)


def largest_step(omega: float, rho_inf: float, max_error: float) -> float:
    """Largest h with |period_error(omega h)| <= max_error (bisection on omega h in (0, 1.5])."""
    lo, hi = 1e-6, 1.5
    if abs(period_error(hi, rho_inf)) <= max_error:
        return hi / omega
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if abs(period_error(mid, rho_inf)) <= max_error else (lo, mid)
    return lo / omega


def _band(signal: np.ndarray, dt: float, energy_fraction: float) -> float:
    """Frequency above which the spectrum of `signal` holds at most energy_fraction of its energy."""
    x = np.asarray(signal, dtype=float)
    if not np.any(x):
        return 0.0
    x = x * np.hanning(len(x))  # no jump from the periodic extension of a signal that ends high
    X = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(len(x), dt)
    tail = np.cumsum(X[::-1])[::-1]  # energy at and above each frequency
    above = tail / tail[0]
    k = int(np.argmax(above <= energy_fraction)) if np.any(above <= energy_fraction) else len(f) - 1
    return float(f[max(k - 1, 0)])


def excitation(scene, tolerance: float) -> tuple[float, list[str]]:
    """(highest excitation frequency [Hz], the contributions as text)."""
    from ..runtime.drives import evaluate

    n = min(200_001, whole_steps(scene.duration, scene.step).n + 1)
    t = np.linspace(0.0, scene.duration, n)
    dt = t[1] - t[0]
    parts: list[tuple[float, str]] = []
    for d in scene.drives:
        for kind, drive in (("rotation", d.rotation), ("translation", d.translation)):
            if drive is None:
                continue
            tf = drive.angle if kind == "rotation" else drive.displacement
            vals = np.array([evaluate(tf.kind, dict(tf.params), float(x)) for x in t])
            rate, acc = vals[:, 1], vals[:, 2]
            fb = _band(acc, dt, tolerance**2)
            parts.append((fb, f"band of {d.port}.{kind} acceleration {fb:.3g} Hz"))
            if kind == "rotation":
                fc = _band(rate**2, dt, tolerance**2)
                parts.append((fc, f"band of the squared {d.port} rate (centrifugal load) {fc:.3g} Hz"))
                spin = float(np.max(np.abs(rate)))
                parts.append((spin / (2 * math.pi), f"spin rate {spin:.3g} rad/s = {spin / (2 * math.pi):.3g} Hz "
                              "(Coriolis coupling, loads fixed in space seen from the body)"))
            if tf.kind == "sine":
                fs = dict(tf.params)["frequency_hz"]
                parts.append((fs, f"sine drive {fs:.3g} Hz"))
    for ld in scene.loads:
        if math.isfinite(ld.t_end):
            fw = 1.0 / (ld.t_end - ld.t_start)
            parts.append((fw, f"load window on {ld.port} of {ld.t_end - ld.t_start:g} s: {fw:.3g} Hz"))
    if any(scene.initial.angular_velocity):
        w = float(np.linalg.norm(scene.initial.angular_velocity))
        parts.append((w / (2 * math.pi), f"initial spin {w:.3g} rad/s"))
    if not parts:
        return 0.0, ["no drives or loads with a time scale: quasi-static"]
    parts.sort(key=lambda p: -p[0])
    return parts[0][0], [p[1] for p in parts]


def drive_time_scale(scene) -> float | None:
    """Shortest characteristic time of the drives: T of a spin-up, the period of a sine."""
    out = []
    for d in scene.drives:
        for drive in (d.rotation, d.translation):
            if drive is None:
                continue
            tf = drive.angle if d.rotation is drive else drive.displacement
            p = dict(tf.params)
            if tf.kind == "haug_spinup":
                out.append(p["T"])
            elif tf.kind == "sine" and p["frequency_hz"] > 0:
                out.append(1.0 / p["frequency_hz"])
    return min(out) if out else None


def reduced(body: Body):
    """The ReducedBody (data, reductions) of the body (reduction.reduce_body)."""
    from ..reduction import reduce_body

    return reduce_body(body)


def rechain(body: Body, n_se: int, modes: int | None = None) -> Body:
    """The body as a chain of n_se superelements: ports keep their place along the beam (node k of
    n becomes node k n_se / n, which must be whole: see `valid_counts`)."""
    n0 = body.superelements
    ports = []
    for p in body.ports:
        k, r = divmod(p.node * n_se, n0)
        if r:
            raise ValueError(f"port {p.name!r} at node {p.node} of {n0} is not on a boundary node of {n_se} "
                             "superelements")
        ports.append(dataclasses.replace(p, node=k))
    return dataclasses.replace(body, superelements=n_se, ports=tuple(ports),
                               modes=body.modes if modes is None else modes)


def valid_count(body: Body, n_min: int) -> int:
    """Smallest chain length >= n_min that keeps every port on a boundary node."""
    n0 = body.superelements
    step = n0 // math.gcd(n0, math.gcd(*[p.node for p in body.ports], n0)) if body.ports else 1
    return max(step, step * math.ceil(n_min / step))


def step_cost(n_se: int, terms: str, backend: str = "native") -> float:
    """Predicted cost per step against 1 superelement `linear` on `backend` (calibration.LINEAR_COST_PER_SE,
    TERM_COST, both measured per backend)."""
    from .calibration import LINEAR_COST_PER_SE, TERM_COST

    if backend not in TERM_COST:
        raise ValueError(f"backend must be one of {sorted(TERM_COST)}, got {backend!r}")
    return (1.0 + LINEAR_COST_PER_SE[backend] * (n_se - 1)) * TERM_COST[backend][terms]


def first_frequency(body: Body) -> float:
    """First natural frequency [Hz] of the chain with the motion-driven port parts fixed."""
    from ..linear import natural_frequencies

    f = natural_frequencies(reduced(body).data)
    return float(f[0]) if len(f) else math.nan


def free_free_frequencies(body: Body, n_se: int, n_modes: int) -> np.ndarray:
    """Free-free frequencies [Hz] of one superelement of a chain of n_se (its kept-mode candidates)."""
    sub = dataclasses.replace(body, superelements=n_se, modes=n_modes, ports=())
    data = reduced(sub).data
    return np.asarray(data.superelements[0].frequencies_hz, dtype=float)


def nice_step(h_max: float, duration: float) -> float:
    """The largest of 1, 1.25, 1.6, 2, 2.5, 3.2, 4, 5, 6.4, 8 x 10^k not above h_max that divides the
    duration into whole steps."""
    e = math.floor(math.log10(h_max))
    mant = (1, 1.25, 1.6, 2, 2.5, 3.2, 4, 5, 6.4, 8)
    cands = sorted({float(f"{m * 10.0**k:.6g}") for k in range(e - 3, e + 1) for m in mant}, reverse=True)
    for h in cands:
        if h <= h_max * (1 + 1e-12) and divides(duration, h):
            return float(f"{h:.6g}")
    return float(f"{h_max:.3g}")


def spin_history(scene):
    """(t, rate, acc, axis, source) of the scene's spin (spin.scene_spin: its fastest rotation drive, or its
    initial spin, a constant rate without acceleration); None when nothing spins."""
    from ..spin import scene_spin

    s = scene_spin(scene)
    return None if s is None else (s.t, s.rate, s.acceleration, s.axis, s.source)


def stiffened_frequencies(body: Body, scene, spin: float, axis) -> dict:
    """The first bending frequency of each direction at the scene's top spin, from the body itself: the
    reduced chain with stiffening and the gyroscopic terms linearized about its steady spin
    (linear.directional_spin_modes; docs/stability.md, docs/accuracy.md "Rotating cantilever"), each mode
    told in-plane or out-of-plane by where it moves relative to the spin axis. Where the body has no
    steady spin to linearize about (no drive about an axis through a motion-driven port at the origin,
    e.g. a free body's initial spin), Southwell's law with the coefficient of each direction:
    omega^2 = omega_1^2 + S1 Omega^2 out of the plane, omega_1^2 + (S1 - 1) Omega^2 in it.
    Returns {"in-plane": Hz, "out-of-plane": Hz, "source": text, "modes": [(Hz, direction), ...]}."""
    from ..linear import directional_spin_modes, first_by_direction, natural_frequencies
    from ..runtime.body import BodySystem

    data = reduced(dataclasses.replace(body, modes=max(body.modes, 2))).data
    if spin <= 0.0:
        f0 = natural_frequencies(data)
        f1 = float(f0[0]) if len(f0) else math.nan
        return {"in-plane": f1, "out-of-plane": f1, "source": "no spin: the body's first frequency", "modes": []}
    driven = [p for p in data.ports if p.translation == "motion" and p.rotation == "motion"]
    through = driven and np.linalg.norm(np.cross(axis, data.node_positions[driven[0].node])) <= 1e-9 * body.length
    if through:
        from ..reduction import reduce_body

        data = reduce_body(dataclasses.replace(body, modes=max(body.modes, 2)), stiffening=True).data
        try:
            modes = directional_spin_modes(BodySystem(data, terms="gyroscopic"), spin, axis,
                                           beam_direction=body.direction, length=body.length,
                                           f_max=max(50.0, 10 * spin))
            first = first_by_direction(modes)
            if "in-plane" in first and "out-of-plane" in first:
                return {"in-plane": first["in-plane"], "out-of-plane": first["out-of-plane"],
                        "source": f"the reduced body with stiffening linearized about its steady spin at {spin:.3g} rad/s",
                        "modes": [(m.frequency_hz, m.direction) for m in modes[:12]]}
        except (RuntimeError, np.linalg.LinAlgError):
            pass
    w1 = 2 * math.pi * first_frequency(body)
    S1 = southwell_coefficient()
    return {"in-plane": math.sqrt(max(w1**2 + (S1 - 1.0) * spin**2, 0.0)) / (2 * math.pi),
            "out-of-plane": math.sqrt(w1**2 + S1 * spin**2) / (2 * math.pi),
            "source": f"Southwell's law (S1 = {S1:.4f}; no steady spin of the body to linearize about)", "modes": []}


def excited_directions(scene, axis, beam_direction) -> set:
    """Which bending directions the scene excites, relative to the spin axis a and the beam axis e: a
    rotation drive (its angular acceleration, Coriolis) and loads or gravity normal to a move the beam in
    the plane of rotation; loads, moments about the in-plane normal, gravity and initial displacements
    along a move it out of that plane. Without a spin axis both directions count."""
    if axis is None:
        return {"in-plane", "out-of-plane"}
    from ..directions import excites, spin_plane

    plane = spin_plane(axis, beam_direction)
    out = set()
    if any(d.rotation is not None for d in scene.drives):
        out.add("in-plane")
    for v in [ld.force for ld in scene.loads] + [scene.gravity] + [u for _, u in scene.initial.port_displacements]:
        out |= excites(v, plane)
    for mv in [ld.moment for ld in scene.loads]:
        out |= excites(mv, plane, moment=True)
    return out or {"in-plane"}
