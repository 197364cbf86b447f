"""Structural (material) damping of a body: modal damping ratios or Rayleigh coefficients, and the
damping matrix D of each superelement that the body equations use (docs/equations.md, "Structural damping").

Damping acts on the elastic deformation only, measured in the body's co-rotated frame: the force
D q_bar_dot joins the elastic force g of eq. (78), with q_bar_dot the co-rotated elastic rates of
eq. (91). D is built on the free-free modes of the reduced superelement,

    K_bar phi_i = omega_i^2 M_bar phi_i,  phi_i^T M_bar phi_j = delta_ij,
    D = (M_bar Phi) diag(c_i) (M_bar Phi)^T,  c_i = 2 zeta_i omega_i + alpha + beta omega_i^2.

Every one of the n modes is elastic: q_bar = [d_P, alpha_P; eta] is measured from the CM frame
(x0, R0), which carries the whole rigid motion, and the reduction's basis (eq. 76: attachment modes
with inertia relief, free-free modes) is mass-orthogonal to the rigid modes, so K_bar is positive
definite (B1 in 2 superelements of 4 elements and 3 modes: the lowest eigenvalue 5515 s^-2, the first
free-free bending of a 4 m beam, 74 rad/s). A rigid motion has q_bar_dot = 0 and is never damped.
With ratios zeta_i this is modal damping; with alpha, beta it is Rayleigh damping alpha M_bar +
beta K_bar exactly (M_bar Phi Phi^T M_bar = M_bar, M_bar Phi diag(omega^2) Phi^T M_bar = K_bar). A
model file states one of the two (model.py refuses both); the C runtime and the FMU use the same c_i,
so an FMU can change the ratios or the coefficients before initialization without an eigensolver
(runtime/native/body.c `ffrf_damping_update`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Damping:
    """A body's structural damping. ratios: () none, (zeta,) for every mode, or one ratio per mode of a
    superelement's reduced model (n = 6 nb + modes of them, by rising frequency); alpha [1/s] on the
    mass, beta [s] on the stiffness (Rayleigh)."""

    ratios: tuple[float, ...] = ()
    alpha: float = 0.0
    beta: float = 0.0

    def __post_init__(self):
        values = tuple(self.ratios) + (self.alpha, self.beta)
        if not all(np.isfinite(values)) or min(values) < 0.0:
            raise ValueError(f"damping: expected finite values >= 0, got ratios {list(self.ratios)}, "
                             f"alpha {self.alpha}, beta {self.beta}")

    @property
    def kind(self) -> str:
        """'modal', 'rayleigh' or 'none' (both at once only through an FMU's parameters: they add)."""
        if self.ratios and (self.alpha or self.beta):
            return "modal+rayleigh"
        return "modal" if self.ratios else "rayleigh" if (self.alpha or self.beta) else "none"

    def as_meta(self) -> dict:
        return {"ratios": list(self.ratios), "alpha": self.alpha, "beta": self.beta}

    @classmethod
    def from_meta(cls, meta: dict | None) -> "Damping | None":
        if not meta:
            return None
        return cls(tuple(float(z) for z in meta["ratios"]), float(meta["alpha"]), float(meta["beta"]))


@dataclass(frozen=True, eq=False)
class ModalBasis:
    """The modes of every superelement's reduced model: omega (E, n) [rad/s] rising, MPhi (E, n, n)
    = M_bar Phi with Phi mass-normalized."""

    omega: np.ndarray
    MPhi: np.ndarray

    @property
    def n_elastic(self) -> int:
        return self.omega.shape[1]


def modal_basis(K: np.ndarray, M: np.ndarray) -> ModalBasis:
    """The modes of each reduced superelement (K, M: (E, n, n)), by a Cholesky reduction M = L L^T,
    L^-1 K L^-T = V diag(lambda) V^T, Phi = L^-T V (numpy only: no scipy at run time)."""
    omegas, mphis = [], []
    for e, (Ke, Me) in enumerate(zip(K, M)):
        L = np.linalg.cholesky(0.5 * (Me + Me.T))
        Li = np.linalg.inv(L)
        lam, V = np.linalg.eigh(Li @ (0.5 * (Ke + Ke.T)) @ Li.T)
        if not lam[0] > 0.0:
            raise ValueError(f"superelement {e}: its reduced stiffness is not positive definite (lowest eigenvalue "
                             f"{lam[0]:.3g}): no modes to damp")
        omegas.append(np.sqrt(lam))
        mphis.append(Me @ (Li.T @ V))
    return ModalBasis(np.array(omegas), np.array(mphis))


def per_mode_ratios(damping: Damping, n_elastic: int) -> np.ndarray:
    """The ratio of every mode (n_elastic,): one ratio for all, or the list, checked for length."""
    z = damping.ratios
    if len(z) == 0:
        return np.zeros(n_elastic)
    if len(z) == 1:
        return np.full(n_elastic, float(z[0]))
    if len(z) != n_elastic:
        raise ValueError(f"damping ratios: expected one ratio or one per mode of a superelement's reduced model "
                         f"({n_elastic} = 6 x its boundary frames + its modes), got {len(z)}")
    return np.asarray(z, dtype=float)


def modal_coefficients(damping: Damping, basis: ModalBasis) -> np.ndarray:
    """c_i = 2 zeta_i omega_i + alpha + beta omega_i^2 of every superelement's modes (E, n):
    mode i's equation reads eta_i'' + c_i eta_i' + omega_i^2 eta_i = ..., so its ratio is c_i / (2 omega_i),
    i.e. zeta_i for modal damping and alpha / (2 omega_i) + beta omega_i / 2 for Rayleigh's."""
    w = basis.omega
    return 2.0 * per_mode_ratios(damping, basis.n_elastic) * w + damping.alpha + damping.beta * w * w


def body_basis(damping: Damping | None, K: np.ndarray, M: np.ndarray) -> ModalBasis | None:
    """The modal basis a body carries (the C runtime's image, so that an FMU's damping parameters act
    without an eigensolver): always when damped; without damping None where a reduced stiffness is not
    positive definite (the body then cannot be damped)."""
    try:
        return modal_basis(K, M)
    except (ValueError, np.linalg.LinAlgError):
        if damping is not None and damping.kind != "none":
            raise
        return None


def is_damped(damping: Damping | None) -> bool:
    """Whether a body's damping damps (a Damping of no ratios and no coefficients does not)."""
    return damping is not None and damping.kind != "none"


def damping_matrices(damping: Damping | None, basis: ModalBasis | None) -> np.ndarray | None:
    """D (E, n, n) of each superelement, or None without damping."""
    if not is_damped(damping):
        return None
    c = modal_coefficients(damping, basis)
    return np.einsum("eik,ek,ejk->eij", basis.MPhi, c, basis.MPhi)
