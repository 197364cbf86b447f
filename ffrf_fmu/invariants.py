"""Inertia invariants of a superelement and the magnitude indicators of Witteveen & Pichler (2019),
"On the relevance of inertia related terms in the equations of motion of a flexible body in the
floating frame of reference formulation" (docs/background.md; docs/inertia-terms.md).

Modes. Witteveen assumes mass-normalized free(-surface) modes, origin at the CM, principal axes,
and notes (his 3.7, ref. [8]) that any shape basis can be transformed into such a base. We take
the whole reduced basis Y of eq. (76) of the superelement and solve K_bar v = w^2 M_bar v in it:
Phi = Y V, V^T M_bar V = I. Every column is free (U^T M Phi = 0, eq. 74), mass-normalized and
mass-orthogonal to the others. Because the kept free-free vibration modes Xi lie in span(Y) and
are exact eigenvectors of (K, M), Rayleigh-Ritz returns them exactly as the first `modes`
columns (their frequencies equal SuperelementData.frequencies_hz); the other 6 n_boundary columns
are the pseudo free-free modes of the boundary attachment shapes (axial stretch, torsion, ...).
Amplitude indicators use the kept vibration modes Xi only; spin indicators use all of Phi (a
spun beam stretches in the attachment shapes, not in its bending modes). Axes are model axes
(principal for a straight beam along a coordinate axis); every indicator is a norm ratio and
does not depend on that choice.

Integrals, not lumped sums. For a displacement field u = N q (N: beam section-point
interpolation, fe.beam) with X the undeformed position from the CM, rho the density:
    M     = int N^T N rho                         (geradin 49)
    M_k   = int N^T e~_k N rho                    (translational kernel, geradin 53)
    T_ab  = int N_a^T N_b rho   (a, b = 1..3)     (full tensor kernel, Shabana's S_ab; fe.beam.tensor_kernel)
and the rigid rotation field theta x X = N U_r theta is represented exactly (U_r = rotation
columns of the rigid modes about the CM, eq. 11). The invariants (Witteveen's names, Shabana's
notation, Geradin's equations) are then exact for the FE interpolation:
    I0          = int X~^T X~ rho = U_r^T M U_r                                (eq. 13: J0)
    W1_j        = int (X~^T Phi_j~ + Phi_j~^T X~) rho = C_j + C_j^T,  C_j[:, k] = U_r^T M_k Phi_j
    W2_jl       = int Phi_j~^T Phi_l~ rho = tr(P_jl) I - P_jl^T,  P_jl[a, b] = Phi_j^T T_ab Phi_l
    I(q)        = I0 + sum_j q_j W1_j + sum_jl q_j q_l W2_jl      (his I0 + W1 Qf + Qf^T W2 Qf)
    coupling    = int (X + u)~ Phi rho = C0 + S(q),  C0 = U_r^T M Phi (= 0 for free modes),
                  S(q) = int u~ Phi rho (geradin 54), S(q)[k, :] = (G_k q)^T, i.e. W3[j][k, l] = G_k[l, j]
    G_k         = Phi^T M_k Phi,  G(w) = sum_k w_k G_k                       (geradin 53)
Loads on the modes in a frame spinning at w (body axes):
    centrifugal = -int Phi^T w~ w~ (X + u) rho = f0(w) + Kc(w) q,
                  f0_j = w^T W1_j w / 2 = -sum_k w_k Phi_j^T M_k U_r w   (his [w_1 I ...][W1^T / 2] w: stretch)
                  Kc_jl = w^T W2_jl w = |w|^2 tr P_jl - w^T P_jl w      (his W2 Qf term: softening, >= 0)
    Coriolis    = -2 int Phi^T w~ Phi rho qdot = -2 G(w) qdot              (geradin G, his 2 W3^T Qfdot w)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .fe import FEModel
from .model import Body, Scene

DEFLECTION = 0.01  # characteristic amplitude: largest elastic displacement = 1 % of the superelement length
NEGLIGIBLE = 0.01  # an indicator below 1 % means the term changes what it is compared with by < 1 %
SLOW_SPIN = 0.1  # w / w_1 below this is "considerably lower than 1" (his guideline IV)


@dataclass(frozen=True, eq=False)
class Invariants:
    """Witteveen's invariants of one superelement for the mode set Phi (module doc for formulas)."""

    Phi: np.ndarray  # (n_dof, n) mass-normalized free modes, FE dofs
    omega: np.ndarray  # (n,) rad/s, ascending (Ritz values of the reduced superelement)
    n_vibration: int  # the first n_vibration columns are the kept free-free vibration modes Xi
    mass: float
    length: float  # largest node distance (superelement length)
    I0: np.ndarray  # (3, 3)
    W1: np.ndarray  # (n, 3, 3)
    W2: np.ndarray  # (n, n, 3, 3), W2[l, j] = W2[j, l]^T (3n x 3n symmetric)
    W3: np.ndarray  # (n, 3, n): S(q) = sum_j q_j W3[j]
    C0: np.ndarray  # (3, n) constant rotation-elastic coupling U_r^T M Phi (zero for free modes)
    G: np.ndarray  # (3, n, n) G_k = Phi^T M_k Phi
    P: np.ndarray  # (n, n, 3, 3) P_jl[a, b] = int Phi_j,a Phi_l,b rho
    amplitude: np.ndarray  # (n,) modal amplitude at which the largest displacement is DEFLECTION * length
    dofs_per_node: int = 6  # rows of Phi per FE node, translations first (beam 6, solid 3)

    def inertia(self, q) -> np.ndarray:
        """Inertia tensor of the deformed body about the (undeformed) CM: I0 + W1 q + q^T W2 q."""
        q = np.asarray(q, dtype=float)
        return self.I0 + np.einsum("j,jab->ab", q, self.W1) + np.einsum("j,l,jlab->ab", q, q, self.W2)

    def centrifugal(self, w) -> tuple[np.ndarray, np.ndarray]:
        """(f0, Kc): centrifugal load on the modes f0 + Kc q at body angular velocity w."""
        w = np.asarray(w, dtype=float)
        f0 = 0.5 * np.einsum("a,jab,b->j", w, self.W1, w)
        Kc = np.einsum("a,jlab,b->jl", w, self.W2, w)
        return f0, Kc

    def coriolis(self, w) -> np.ndarray:
        """G(w) = sum_k w_k G_k: the Coriolis load on the modes is -2 G(w) qdot."""
        return np.einsum("k,kij->ij", np.asarray(w, dtype=float), self.G)


def modal_invariants(
    fe: FEModel, T: np.ndarray, U: np.ndarray, Phi: np.ndarray, omega=None, n_vibration=None
) -> Invariants:
    """Invariants of the mode set Phi (n_dof, n), taken as mass-normalized and free (not checked:
    C0 reports the rigid coupling). U: rigid modes about the CM (reduction.Reduction.U)."""
    Ur = U[:, 3:]
    n = Phi.shape[1]
    Mk = fe.M_kernel
    C = np.einsum("ia,kij,jm->mak", Ur, Mk, Phi, optimize=True)  # C[j][:, k] = U_r^T M_k Phi_j
    P = np.einsum("ij,abik,kl->jlab", Phi, T, Phi, optimize=True)
    trP = np.einsum("jlaa->jl", P)
    W2 = trP[:, :, None, None] * np.eye(3) - P.transpose(0, 1, 3, 2)
    G = np.einsum("ij,kil,lm->kjm", Phi, Mk, Phi, optimize=True)
    G = 0.5 * (G - G.transpose(0, 2, 1))  # skew: the symmetric part is round-off
    X = fe.coords - fe.coords.mean(0)
    mass = float(np.trace(U[:, :3].T @ fe.M @ U[:, :3]) / 3.0)
    # largest displacement of each mode: the largest nodal one, at least the mass-averaged one
    # sqrt(Phi^T M Phi / m) = 1 / sqrt(m) (a torsion mode moves section points, not nodes)
    disp = np.maximum(np.linalg.norm(Phi.reshape(fe.n_nodes, 6, n)[:, :3], axis=1).max(0), 1.0 / math.sqrt(mass))
    length = float(np.linalg.norm(X[:, None] - X[None], axis=-1).max())
    return Invariants(
        Phi=Phi,
        omega=np.full(n, np.nan) if omega is None else np.asarray(omega, dtype=float),
        n_vibration=n if n_vibration is None else int(n_vibration),
        mass=mass,
        length=length,
        I0=Ur.T @ fe.M @ Ur,
        W1=C + C.transpose(0, 2, 1),
        W2=W2,
        W3=G.transpose(2, 0, 1),  # W3[j][k, l] = G_k[l, j]
        C0=Ur.T @ fe.M @ Phi,
        G=G,
        P=P,
        amplitude=DEFLECTION * length / disp,
    )


def superelement_invariants(fe: FEModel, T: np.ndarray, red) -> Invariants:
    """Invariants of a reduced superelement (reduction.Reduction) on its pseudo free-free modes
    Phi = Y V, K_bar V = M_bar V diag(w^2), V^T M_bar V = I (module doc)."""
    w2, V = sla.eigh(red.data.K, red.data.M)
    return modal_invariants(fe, T, red.U, red.Y @ V, np.sqrt(np.maximum(w2, 0.0)), len(red.data.frequencies_hz))


def body_invariants(body: Body, reductions=None) -> list[Invariants]:
    """Invariants of every superelement of `body`, FE models rebuilt as reduction.reduce_body does."""
    if reductions is None:
        from .reduction import reduce_body

        reductions = reduce_body(body).reductions
    if body.solid is not None:
        return [solid_invariants(red) for red in reductions]
    from .reduction import superelement_models

    out = []
    for e, red in enumerate(reductions):
        fe, _, T = superelement_models(body, e, tensor=True)
        X_B = fe.coords[[0, -1]] - red.data.x_cm
        if fe.n_dof != red.Y.shape[0] or not np.allclose(X_B, red.data.X_B, atol=1e-9 * body.length):
            raise RuntimeError(f"superelement {e}: FE model rebuilt here does not match reduction.reduce_body")
        out.append(superelement_invariants(fe, T, red))
    return out


def indicators(inv: Invariants, spin_rate: float | None = None, spin_axis=None) -> dict:
    """Magnitude indicators of Witteveen's sections 6-7 for one superelement (JSON-able).

    Amplitude indicators (largest over the kept vibration modes j, each at its characteristic
    amplitude a_j: largest displacement DEFLECTION x length): W1q/I0 = |a W1_j| / |I0|,
    qW2q/I0 = |a^2 W2_jj| / |I0| (inertia change, his 7.1), W3q/I0 = |a W3_j| / sqrt|I0|
    (coupling S(q) against the diagonal blocks I0 and 1 of the mass matrix, his 7.2). Norms are
    spectral; the `_axis` variants use I0^-1/2 (.) I0^-1/2 (I0^-1/2 (.) for W3), i.e. the worst
    relative change about any axis, which is what matters for a beam turning about its own axis
    (tiny I0 there); the `_spin_axis` ones n^T (.) n / n^T I0 n about the spin axis n.
    Spin indicators (all modes, rate w about the unit axis n, w_1 = lowest mode):
      softening = max eig(Kc, K) <= (w / w_1)^2: centrifugal q part against the elastic stiffness
        (instability at 1); softening_gyroscopic_set = max eig(G(w)^T G(w), K): what the
        `gyroscopic` term set implies through G M^-1 G in the two-field equations (78)-(79);
      coriolis = 2 w |G(n) Omega^-1|_2 <= 2 w / w_1: Coriolis force against the elastic force of
        a mode vibrating at its own frequency;
      stretch: q_s = K^-1 f0(w) (static centrifugal widening); widening = its largest nodal
        displacement / length; centrifugal_q_over_const = |Kc q_s| / |f0|, the q part of the
        centrifugal load against the constant part at that widening (his 7.3.2).
    """
    nv = inv.n_vibration
    a = inv.amplitude[:nv]
    out: dict = {
        "mass": inv.mass,
        "length": inv.length,
        "I0": inv.I0.tolist(),
        "omega1_rad_s": float(inv.omega[0]),
        "n_vibration_modes": nv,
        "n_modes": len(inv.omega),
        "rigid_coupling_residual": float(np.abs(inv.C0).max() / math.sqrt(np.linalg.norm(inv.I0, 2))),
        # Witteveen's Tables 2-3 (max |entry|, spectral norm), W1 as 3 x 3n, W2 as 3n x 3n, W3 as 3n x n
        "table": {
            "I0_norm": float(np.linalg.norm(inv.I0, 2)),
            "W1_max": float(np.abs(inv.W1).max()),
            "W1_norm": float(np.linalg.norm(inv.W1.transpose(1, 0, 2).reshape(3, -1), 2)),
            "W2_max": float(np.abs(inv.W2).max()),
            "W2_norm": float(np.linalg.norm(inv.W2.transpose(0, 2, 1, 3).reshape(3 * len(inv.omega), -1), 2)),
            "W3_max": float(np.abs(inv.W3).max()),
            "W3_norm": float(np.linalg.norm(inv.W3.reshape(-1, len(inv.omega)), 2)),
        },
    }
    if nv:
        nI0, s = np.linalg.norm(inv.I0, 2), np.linalg.inv(sla.sqrtm(inv.I0).real)  # s = I0^-1/2

        def worst(A, left, right, scale):  # max_j |A_j|_2 / scale, max_j |left A_j right|_2
            norm = lambda B: float(np.linalg.norm(B, 2, axis=(1, 2)).max())  # noqa: E731
            return norm(A) / scale, norm(left @ A @ right)

        jj = np.arange(nv)
        out["amplitude"] = a.tolist()
        out["W1q_over_I0"], out["W1q_over_I0_axis"] = worst(a[:, None, None] * inv.W1[:nv], s, s, nI0)
        out["qW2q_over_I0"], out["qW2q_over_I0_axis"] = worst(a[:, None, None] ** 2 * inv.W2[jj, jj], s, s, nI0)
        one = np.eye(len(inv.omega))  # the modal block of the mass matrix
        out["W3q_over_I0"], out["W3q_over_I0_axis"] = worst(a[:, None, None] * inv.W3[:nv], s, one, math.sqrt(nI0))
    if spin_rate:
        n = np.asarray(spin_axis, dtype=float)
        n = n / np.linalg.norm(n)
        w = spin_rate * n
        f0, Kc = inv.centrifugal(w)
        Gw = inv.coriolis(w)
        qs = f0 / inv.omega**2  # K^-1 f0: static widening
        u = np.linalg.norm((inv.Phi @ qs).reshape(-1, inv.dofs_per_node)[:, :3], axis=1).max()
        K = np.diag(inv.omega**2)
        if nv:  # inertia change about the spin axis only (what a planar spin feels)
            nIn = n @ inv.I0 @ n
            out["W1q_spin_axis"] = float(max(abs(aj * n @ inv.W1[j] @ n) for j, aj in enumerate(a)) / nIn)
            out["qW2q_spin_axis"] = float(max(aj**2 * n @ inv.W2[j, j] @ n for j, aj in enumerate(a)) / nIn)
        out |= {
            "spin_over_omega1": float(spin_rate / inv.omega[0]),
            "softening": float(sla.eigh(Kc, K, eigvals_only=True)[-1]),
            "softening_gyroscopic_set": float(sla.eigh(Gw.T @ Gw, K, eigvals_only=True)[-1]),
            "coriolis": float(2.0 * np.linalg.norm(Gw / inv.omega[None, :], 2)),
            "widening": float(u / inv.length),
            "centrifugal_q_over_const": float(np.linalg.norm(Kc @ qs) / np.linalg.norm(f0)) if np.any(f0) else 0.0,
        }
    return out


def scene_spin(scene: Scene) -> tuple[float | None, np.ndarray | None, str]:
    """(peak spin rate, unit axis, source) of a scene (spin.scene_spin: its fastest rotation drive, else
    its initial angular velocity), else (None, None, "none")."""
    from .spin import scene_spin as spin_of

    s = spin_of(scene)
    return (s.peak, s.axis, s.source) if s is not None else (None, None, "none")


def body_inertia_report(
    body: Body,
    spin_rate: float | None = None,
    spin_axis=None,
    *,
    first_frequency_hz: float | None = None,
    reductions=None,
) -> dict:
    """Witteveen's invariants, indicators and guidelines for every superelement of `body` (JSON-able).

    spin_rate [rad/s] about spin_axis (body axes; default: the axis of largest I0 of the first
    superelement, a normal axis for a beam). first_frequency_hz: first frequency of the assembled
    system (his guideline IV compares the spin with it); reductions: from reduction.reduce_body.
    Guidelines (his section 8): the deformed inertia (III) and the coupling S(q) (III) are needed
    when their indicator about the worst axis reaches NEGLIGIBLE and the body's rotation is its own
    (no motion-driven port rotation: a prescribed rotation is a stiff connection to an infinite
    inertia, his I-II); the Coriolis terms (IV) when the spin is not below SLOW_SPIN x the first
    frequency or the Coriolis indicator reaches NEGLIGIBLE; stiffening when (spin / first frequency)^2
    reaches NEGLIGIBLE, softening within a superelement when its indicator does.
    """
    invs = body_invariants(body, reductions)
    if spin_rate and spin_axis is None:
        spin_axis = np.linalg.eigh(invs[0].I0)[1][:, -1]
    ses = [indicators(inv, spin_rate, spin_axis) for inv in invs]

    def worst(key) -> float:
        return max((s[key] for s in ses if key in s), default=0.0)

    connected = any(p.rotation == "motion" for p in body.ports)
    w1 = None if first_frequency_hz is None else 2.0 * math.pi * first_frequency_hz
    spin_ratio = spin_rate / w1 if spin_rate and w1 else None
    deformed = max(worst("W1q_over_I0_axis"), worst("qW2q_over_I0_axis"))
    g = {
        "deformed_inertia": deformed >= NEGLIGIBLE and not connected,
        "inertia_coupling": worst("W3q_over_I0_axis") >= NEGLIGIBLE and not connected,
        "coriolis": (spin_ratio or 0.0) >= SLOW_SPIN or worst("coriolis") >= NEGLIGIBLE,
        "centrifugal_softening": worst("softening") >= NEGLIGIBLE,
        "geometric_stiffening": (spin_ratio or 0.0) ** 2 >= NEGLIGIBLE,
        "centrifugal_stretch": worst("widening") >= NEGLIGIBLE * DEFLECTION,
    }
    notes = {
        "deformed_inertia": f"inertia change up to {deformed:.0%} about some axis at {DEFLECTION:.0%} deflection "
        "(beam-like): I0 + W1 q + q^T W2 q is needed (his III); no term set has it (J0 is constant in both)",
        "inertia_coupling": "rotation-elastic coupling S(q) = q^T W3 is needed (his III): term set `gyroscopic`",
        "coriolis": "spin not considerably below the first frequency: Coriolis G(w) on the modes is needed (his IV): "
        "term set `gyroscopic`",
        "centrifugal_softening": "centrifugal softening Kc(w) >= 1 % of a superelement's stiffness, and the geometric "
        "stiffening that balances it is missing from linear superelements: use more superelements as w approaches w_1",
        "geometric_stiffening": f"(spin / first frequency)^2 = {(spin_ratio or 0.0) ** 2:.2g}: centrifugal stiffening "
        "shifts the squared frequencies by O(w^2); linear superelements get it only through the chain of "
        "superelement frames: converge in the number of superelements (benchmark B3)",
        "centrifugal_stretch": f"centrifugal widening f0 = W1^T w w / 2 is >= {NEGLIGIBLE:.0%} of the reference "
        "deflection; no term set applies it inside a superelement (only at the CMs, between superelements)",
    }
    notes = [text for key, text in notes.items() if g[key]]
    if connected:
        notes.append("a port rotation is motion-driven (stiff connection): deformed inertia and coupling are not "
                     "needed whatever their indicators (his 7.1.3, 7.2.3, I-II)")
    if not spin_rate:
        w1s = min(inv.omega[0] for inv in invs)
        lim = [f"{0.1 * w1s:.3g} rad/s (softening < 1 %)"] + ([f"{SLOW_SPIN * w1:.3g} rad/s (Coriolis)"] if w1 else [])
        notes.append("no spin in this scene; spin terms stay negligible below " + " and ".join(lim))
    return {
        "deflection": DEFLECTION,
        "spin_rate": spin_rate,
        "spin_axis": [float(x) for x in spin_axis] if spin_rate else None,
        "first_frequency_hz": first_frequency_hz,
        "spin_over_first_frequency": spin_ratio,
        "connected": connected,
        "superelements": ses,
        "needed": g,
        "notes": notes,
    }


def solid_invariants(red):
    """Witteveen's invariants (invariants.Invariants) of a reduced solid on its pseudo free-free modes
    Phi = Y V, K_bar V = M_bar V diag(w^2) (as invariants.superelement_invariants for a beam), from the
    sparse node mass. Its length is the diagonal of the nodes' bounding box (not the largest node
    distance: that is O(n^2) on a mesh)."""
    import math

    import scipy.linalg as sla

    from .reduction_sparse import inertia_terms, node_kernels

    fe = red.fe
    w2, V = sla.eigh(red.data.K, red.data.M)
    Phi = red.Y @ V
    n = Phi.shape[1]
    Ur = red.U[:, 3:]
    Q, R = node_kernels(fe, Phi, Ur)
    G, W1, W2 = inertia_terms(Q, R)
    mass = float(red.data.mass)
    disp = np.maximum(np.linalg.norm(fe.translations(Phi), axis=1).max(0), 1.0 / math.sqrt(mass))
    length = float(np.linalg.norm(fe.coords.max(0) - fe.coords.min(0)))
    return Invariants(
        Phi=Phi, omega=np.sqrt(np.maximum(w2, 0.0)), n_vibration=len(red.data.frequencies_hz), mass=mass,
        length=length, I0=red.data.J0, W1=W1, W2=W2, W3=G.transpose(2, 0, 1), C0=Ur.T @ (fe.M @ Phi),
        G=0.5 * (G - G.transpose(0, 2, 1)), P=Q.transpose(2, 3, 0, 1), amplitude=DEFLECTION * length / disp,
        dofs_per_node=fe.dofs_per_node,
    )
