"""Campbell diagrams: the first frequencies of a body about a steady spin against the spin rate, in the
spinning frame, reduced (the runtime's equations linearized about their relative equilibrium,
linear.spin_modes) and, for a solid, the full FE model linearized about the same steady spin.

The full FE model (docs/solids.md, "Campbell diagrams"): the rigid frames' node sets eliminated as in
the reduction, the motion-driven parts of the ports' frames fixed (they spin with the drive), u the displacement seen from the spinning frame
about the axis a through the world origin, Omega the rate, S = M_s (x) (I - a a^T):

    static:  (K - Omega^2 S) u0 = Omega^2 S X                   (centrifugal load on the nodes X)
    modes:   M u'' + 2 Omega M_s (x) a~ u' + (K + K_G(sigma(u0)) - Omega^2 S) u = 0

K_G the geometric stiffness of the steady stress (stress stiffening; solid/stiffening.py, needs the
mesh), Omega^2 S the spin softening, the middle term Coriolis. A solid given by exported matrices has
no stresses: its full model is linearized without K_G (`stress = False`), and the reduced one is
built without stiffening. The quadratic eigenproblem is solved in first-order form [u, u'] by ARPACK in
shift-invert mode about 0 (the model with those parts fixed is positive definite below its divergence speed).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Campbell:
    """Frequencies [Hz] in the spinning frame, (rates, n) each; NaN where a mode diverges."""

    model: str
    axis: tuple
    rates: np.ndarray  # (k,) spin rates [rad/s]
    reduced: np.ndarray  # (k, n)
    full: np.ndarray | None = None  # (k, n) the full FE model's, or None
    stiffening: bool = False  # reduced with geometric stiffening, full with stress stiffening
    terms: str = "linear"
    notes: dict = field(default_factory=dict)

    def table(self) -> str:
        n = self.reduced.shape[1]
        head = "rate [rad/s] | " + " | ".join(f"reduced f{i + 1} [Hz]" + (f" | full f{i + 1} | diff" if self.full is not None
                                                                          else "") for i in range(n))
        rows = [head]
        for k, w in enumerate(self.rates):
            cells = []
            for i in range(n):
                cells.append(f"{self.reduced[k, i]:.4f}")
                if self.full is not None:
                    cells += [f"{self.full[k, i]:.4f}", f"{self.reduced[k, i] / self.full[k, i] - 1:+.3%}"]
            rows.append(f"{w:g} | " + " | ".join(cells))
        return "\n".join(rows)


def reduced_frequencies(data, rates, axis, n: int, terms: str = "linear", f_max: float = 1e5) -> np.ndarray:
    """(k, n) the first n frequencies [Hz] of the reduced body `data` (runtime BodyData) about its steady
    spin at each rate (linear.spin_modes; the motion-driven ports spin about `axis` through the origin)."""
    from ..linear import spin_modes
    from ..runtime.body import BodySystem

    out = np.full((len(rates), n), np.nan)
    for k, w in enumerate(rates):
        s = BodySystem(data, terms=terms, rho_inf=0.8)
        f, _ = spin_modes(s, float(w), axis, f_max)
        f = f[np.isfinite(f)]  # a divergent mode (NaN) is not a frequency
        out[k, : min(n, len(f))] = f[:n]
    return out


def full_frequencies(fe, frames, fixed_parts, rates, axis, n: int, stress: bool = True) -> np.ndarray:
    """(k, n) the first n frequencies [Hz] of the full FE model (SolidFE) about its steady spin at each
    rate (module doc), its rigid frames' node sets eliminated as in the reduction (u = T z,
    solid/constraints.py) and the frame parts `fixed_parts` fixed: (frame index, 0 | 3) for its
    translation | rotation. stress: with the stress stiffening K_G."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from ..solid.constraints import constraints, mass_properties
    from ..runtime.rotation import skew

    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    c = constraints(fe, frames, mass_properties(fe)[1])
    T = c.T.tocsc()
    fixed = set()
    for f, part in fixed_parts:
        if frames[f].coupling != "rigid":
            raise ValueError(f"port {frames[f].name!r}: a motion-driven averaging frame holds no node of the full model")
        for k in range(part, part + 3):
            fixed.update(c.L[6 * f + k].indices.tolist())
    free = np.setdiff1d(np.arange(T.shape[1]), np.fromiter(fixed, dtype=int))
    Tf = T[:, free]
    S = fe.kernel(np.eye(3) - np.outer(a, a))  # spin softening, solid/__init__.py
    Gc = fe.kernel(skew(a))
    X = fe.field(fe.coords)
    sub = lambda A: (Tf.T @ (A @ Tf)).tocsc()  # noqa: E731
    M, K, Sz, Gz = sub(fe.M), sub(fe.K), sub(S), sub(Gc)
    m = len(free)
    Z = sp.csc_matrix((m, m))
    I = sp.identity(m, format="csc")
    B = sp.bmat([[I, Z], [Z, M]], format="csc")
    out = np.full((len(rates), n), np.nan)
    for k, w in enumerate(rates):
        Ke = (K - w * w * Sz).tocsc()
        if stress:
            if fe.strain is None:
                raise ValueError(f"{fe.source}: stress stiffening needs a mesh and its material")
            from ..solid.stiffening import geometric_stiffness

            u = Tf @ spla.spsolve(Ke, w * w * (Tf.T @ (S @ X)))
            Ke = (Ke + sub(geometric_stiffness(fe.strain, u))).tocsc()
        A = sp.bmat([[Z, I], [-Ke, -2.0 * w * Gz]], format="csc")  # B x' = A x, x = [z, z']
        lam = spla.eigs(A, k=min(2 * n + 2, 2 * m - 2), M=B, sigma=0.0, which="LM", return_eigenvectors=False,
                        tol=1e-12)
        f = np.sort(np.abs(lam.imag[lam.imag > 1e-9 * np.abs(lam).max()])) / (2 * np.pi)
        out[k, : min(n, len(f))] = f[:n]
        if np.any(lam.real > 1e-6 * np.abs(lam)):
            out[k, 0] = np.nan  # a divergent mode
    return out


def campbell(model, rates, n: int = 3, full: bool = True, terms: str | None = None, scene: str | None = None) -> Campbell:
    """The Campbell diagram of a model's body (model.Model) in a scene (default the first): the axis of
    the scene's rotation drive, stiffening where the body can have it (a beam or a mesh; not a partner's
    export), the scene's term set unless `terms` is given; full: also the full FE model (solids only).
    Divergent reduced modes are counted in the notes, not drawn."""
    from ..model import scene_body
    from ..reduction import reduce_body
    from ..spin import scene_spin

    scene = model.scene(scene)
    spin = scene_spin(scene)
    if spin is None:
        raise ValueError(f"{model.body.source}: scene {scene.name!r} has no rotation drive to take the spin axis from")
    axis = tuple(float(x) for x in spin.axis)
    solid = model.body.solid is not None
    body = scene_body(model.body, scene)
    if solid:
        from ..solid.source import solid_fe

        stiff = solid_fe(body.solid).strain is not None
    else:
        stiff = True
    if not any(p.rotation == "motion" for p in body.ports):
        raise ValueError(f"{model.body.source}: scene {scene.name!r} drives no port's rotation: a steady spin needs "
                         "one (its rotation drive turns the body)")
    reduced = reduce_body(body, stiffening=stiff, inertia=(terms or scene.terms) == "full")
    data, reds = reduced.data, reduced.reductions
    terms = terms or scene.terms
    rates = np.asarray(rates, dtype=float)
    red = reduced_frequencies(data, rates, axis, n, terms)
    fullf = None
    notes = {}
    if full and solid:
        r = reds[0]
        fixed_parts = [(p.node, part) for p in data.ports for part, kind in ((0, p.translation), (3, p.rotation))
                if kind == "motion"]
        if not fixed_parts:
            raise ValueError(f"{model.body.source}: no port is motion-driven: nothing holds the full model in the "
                             "spinning frame")
        fullf = full_frequencies(r.fe, r.frames, fixed_parts, rates, axis, n, stiff)
    if full and not solid:
        notes["full"] = "no full FE model drawn: the comparison with the full model is for solids"
    if not stiff:
        notes["stress"] = "exported matrices: no stress stiffening in either model (spin softening and Coriolis only)"
    return Campbell(model.body.name, axis, rates, red, fullf, stiff, terms, notes)


def plot(c: Campbell, path) -> None:
    """The diagram as a PNG: reduced (lines) and full (markers) frequencies against the rate, and the
    1x and 2x per revolution lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 4.4))
    for i in range(c.reduced.shape[1]):
        ax.plot(c.rates, c.reduced[:, i], "-", color=f"C{i}", label=f"mode {i + 1}, reduced")
        if c.full is not None:
            ax.plot(c.rates, c.full[:, i], "o", mfc="none", color=f"C{i}", label=f"mode {i + 1}, full FE")
    rev = c.rates / (2 * np.pi)
    ax.plot(c.rates, rev, "k:", lw=0.8, label="1 x rev")
    ax.plot(c.rates, 2 * rev, "k--", lw=0.8, label="2 x rev")
    top = np.nanmax(c.reduced) * 1.1
    ax.set_ylim(0, top)
    ax.set_xlabel("spin rate [rad/s]")
    ax.set_ylabel("frequency in the spinning frame [Hz]")
    what = "geometric stiffening on" if c.stiffening else "no stress stiffening (exported matrices)"
    ax.set_title(f"{c.model}: Campbell diagram ({what}, terms {c.terms})", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes: no curve hidden
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
