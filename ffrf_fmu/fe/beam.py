"""3D two-node Timoshenko beam: stiffness (geradin eq. 47), consistent mass (eq. 49) and the
translational mass kernel M_k of the gyroscopic matrix (eq. 53), all from one set of shape
functions.

Conventions (match model.Section):
- Local axis 1 = beam direction. Local axis 2 = normalize(e_z x e1); if e1 is parallel to e_z
  (|e_z x e1| < 1e-8) axis 2 = normalize(e_x x e1) instead. Axis 3 = e1 x axis 2. For e1 = +X
  this gives axis 2 = +Y, axis 3 = +Z; for e1 = +Z it gives axis 2 = -Y, axis 3 = +X.
- Generalized strains [eps, gamma2, gamma3, kappa1, kappa2, kappa3] with stiffnesses
  [EA, GA2, GA3, GJ, EI2, EI3]: gamma2 = u2' - theta3 (shear along axis 2, bends with EI3,
  deflection along axis 2), gamma3 = u3' + theta2 (shear along axis 3, bends with EI2,
  deflection along axis 3), kappa_i = theta_i'. GA None -> shear rigid (Euler-Bernoulli).
- Rotary inertia per unit length diag(m11, m22, m33) about the local axes, m11 = m22 + m33
  unless given. The section is taken doubly symmetric about its centroid (shear centre =
  centroid = mass centre), so its second moments of mass are S = diag(0, m33, m22)
  (m22 = rho int y3^2 dA, m33 = rho int y2^2 dA).

Shape functions: interdependent interpolation (IIE) of Friedman & Kosmatka (1993), cubic
deflection and quadratic rotation coupled through Phi = 12 EI / (GA L^2); they solve the
homogeneous Timoshenko equations, so the element is nodally exact for end loads, and reduce
to cubic Hermite (theta = v') for Phi = 0. Axial displacement and twist are linear.
All integrals use 4-point Gauss quadrature, exact for the degree-6 products of cubics, so
M and M_k are the exact integrals of the same interpolation and rigid motions (constant
translation, linear deflection with constant rotation) are represented exactly.
"""
from __future__ import annotations

import numpy as np

from ..section import Section
from ..runtime.rotation import skew
from . import FEModel, lumped_kernels, node_dofs

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)
_XI = 0.5 * (_GAUSS_X + 1.0)  # points on [0, 1]
_W = 0.5 * _GAUSS_W  # weights on [0, 1]


def local_frame(direction) -> np.ndarray:
    """(3, 3) rotation whose columns are local axes 1, 2, 3 in model axes (rule in module doc)."""
    e1 = np.asarray(direction, dtype=float)
    e1 = e1 / np.linalg.norm(e1)
    a2 = np.cross([0.0, 0.0, 1.0], e1)
    if np.linalg.norm(a2) < 1e-8:
        a2 = np.cross([1.0, 0.0, 0.0], e1)
    e2 = a2 / np.linalg.norm(a2)
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def iie_shape(xi: np.ndarray, L: np.ndarray, phi: np.ndarray):
    """IIE bending shape functions of Friedman & Kosmatka (1993) in a plane with deflection v and
    section rotation theta (v' = theta + gamma), nodal dofs (v_a, theta_a, v_b, theta_b).

    xi (ng,) in [0, 1], L and phi (n_el,). Returns Nv, dNv/dx, Nt, dNt/dx, each (n_el, ng, 4).
    """
    x = xi[None, :]
    L = np.asarray(L, dtype=float)[:, None]
    p = np.asarray(phi, dtype=float)[:, None]
    c = 1.0 / (1.0 + p)
    Nv = c[..., None] * np.stack(
        [
            2 * x**3 - 3 * x**2 - p * x + 1 + p,
            L * (x**3 - (2 + p / 2) * x**2 + (1 + p / 2) * x),
            -(2 * x**3 - 3 * x**2 - p * x),
            L * (x**3 - (1 - p / 2) * x**2 - (p / 2) * x),
        ],
        -1,
    )
    dNv = c[..., None] * np.stack(
        [
            (6 * x**2 - 6 * x - p) / L,
            3 * x**2 - (4 + p) * x + 1 + p / 2,
            -(6 * x**2 - 6 * x - p) / L,
            3 * x**2 - (2 - p) * x - p / 2,
        ],
        -1,
    )
    Nt = c[..., None] * np.stack(
        [
            6 * (x**2 - x) / L,
            3 * x**2 - (4 + p) * x + 1 + p,
            -6 * (x**2 - x) / L,
            3 * x**2 - (2 - p) * x,
        ],
        -1,
    )
    dNt = c[..., None] * np.stack(
        [
            6 * (2 * x - 1) / L**2,
            (6 * x - (4 + p)) / L,
            -6 * (2 * x - 1) / L**2,
            (6 * x - (2 - p)) / L,
        ],
        -1,
    )
    return Nv, dNv, Nt, dNt


def _phi(EI: float, GA: float | None, L: np.ndarray) -> np.ndarray:
    return np.zeros_like(L) if GA is None else 12.0 * EI / (GA * L**2)


def local_interpolation(section: Section, L: np.ndarray):
    """Local-axes interpolation at the Gauss points, element dofs [u1 u2 u3 t1 t2 t3]_a,b.

    Returns N_c (centreline displacement), N_t (section rotation), B (generalized strains,
    order of module doc), each (n_el, ng, 3|3|6, 12).
    """
    L = np.asarray(L, dtype=float)
    n_el, ng = L.size, _XI.size
    Nc = np.zeros((n_el, ng, 3, 12))
    Nt = np.zeros((n_el, ng, 3, 12))
    B = np.zeros((n_el, ng, 6, 12))
    lin = np.stack([1.0 - _XI, _XI], -1)  # (ng, 2) axial and torsion
    dlin = np.stack([-1.0 / L, 1.0 / L], -1)[:, None, :]  # (n_el, 1, 2)
    Nc[:, :, 0, [0, 6]] = lin
    Nt[:, :, 0, [3, 9]] = lin
    B[:, :, 0, [0, 6]] = dlin
    B[:, :, 3, [3, 9]] = dlin
    # plane 1-2: v = u2, theta = t3 (v' = t3 + gamma2), EI3 with GA2
    Nv, dNv, Nr, dNr = iie_shape(_XI, L, _phi(section.EI3, section.GA2, L))
    d = [1, 5, 7, 11]
    Nc[:, :, 1, d] = Nv
    Nt[:, :, 2, d] = Nr
    B[:, :, 1, d] = dNv - Nr
    B[:, :, 5, d] = dNr
    # plane 1-3: w = u3 and theta = -t2 (w' = -t2 + gamma3), EI2 with GA3; sign flips on t2 dofs
    Nv, dNv, Nr, dNr = iie_shape(_XI, L, _phi(section.EI2, section.GA3, L))
    d, s = [2, 4, 8, 10], np.array([1.0, -1.0, 1.0, -1.0])
    Nc[:, :, 2, d] = Nv * s
    Nt[:, :, 1, d] = -Nr * s
    B[:, :, 2, d] = (dNv - Nr) * s  # gamma3 = w' + t2 = w' - theta
    B[:, :, 4, d] = -dNr * s
    return Nc, Nt, B


def element_matrices(section: Section, L: np.ndarray, R: np.ndarray):
    """Element K (eq. 47), M (eq. 49) and kernel M_k (eq. 53) in model axes.

    L (n_el,) lengths, R (n_el, 3, 3) local frames (columns = local axes in model axes).
    Returns Ke, Me (n_el, 12, 12) and Mke (n_el, 3, 12, 12).
    M = int m N_c^T N_c + N_t^T J N_t ds, J = R diag(m11, m22, m33) R^T.
    M_k = int m N_c^T skew(e_k) N_c + N_t^T skew(S e_k) N_t ds: the exact kernel of the
    section-point displacement N_c q - skew(y) N_t q integrated over the section
    (int rho skew(y)^T skew(e_k) skew(y) dA = skew(S e_k), S = int rho y y^T dA), i.e. the
    same kinematics as M: for rigid rotations theta, phi it gives -e_k^T Sigma (theta x phi)
    with Sigma = tr(J0)/2 I - J0 taken from M (checked in tests/test_fe.py).
    """
    sec = section
    m11 = sec.m22 + sec.m33 if sec.m11 is None else sec.m11
    Nc, Nt, B = local_interpolation(sec, L)
    # to model axes: displacement R u_loc, dofs q_loc = blockdiag(R^T x 4) q
    T = np.zeros((len(L), 12, 12))
    for i in range(4):
        T[:, 3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = np.swapaxes(R, 1, 2)
    Nc = np.einsum("eij,egjk,ekl->egil", R, Nc, T)
    Nt = np.einsum("eij,egjk,ekl->egil", R, Nt, T)
    B = np.einsum("egij,ejk->egik", B, T)
    wL = _W[None, :] * L[:, None]  # (n_el, ng): ds = L dxi
    shear = [0.0 if sec.GA2 is None else sec.GA2, 0.0 if sec.GA3 is None else sec.GA3]
    D = np.diag([sec.EA, *shear, sec.GJ, sec.EI2, sec.EI3])
    J = np.einsum("eij,j,ekj->eik", R, [m11, sec.m22, sec.m33], R)
    S = np.einsum("eij,j,ekj->eik", R, [0.0, sec.m33, sec.m22], R)
    Ke = np.einsum("eg,egia,ij,egjb->eab", wL, B, D, B, optimize=True)
    Me = sec.m * np.einsum("eg,egia,egib->eab", wL, Nc, Nc, optimize=True) + np.einsum(
        "eg,egia,eij,egjb->eab", wL, Nt, J, Nt, optimize=True
    )
    E = skew(np.eye(3))  # E[k] = skew(e_k)
    SE = skew(np.einsum("eij,jk->eki", S, np.eye(3)))  # (n_el, 3, 3, 3): skew(S e_k)
    Mke = sec.m * np.einsum("eg,egia,kij,egjb->ekab", wL, Nc, E, Nc, optimize=True) + np.einsum(
        "eg,egia,ekij,egjb->ekab", wL, Nt, SE, Nt, optimize=True
    )
    return Ke, Me, Mke


def _assemble(n_dof: int, idx: np.ndarray, Ae: np.ndarray) -> np.ndarray:
    """Scatter element matrices Ae (n_el, 12, 12) with dof indices idx (n_el, 12)."""
    A = np.zeros((n_dof, n_dof))
    np.add.at(A, (idx[:, :, None], idx[:, None, :]), Ae)
    return A


def beam_model(section: Section, origin, direction, length: float, n_elements: int) -> FEModel:
    """Straight beam from `origin` along `direction`, `n_elements` equal IIE Timoshenko elements.

    Nodes 0..n_elements at s = i * length / n_elements; dof = 6 * node + k, model axes.
    """
    if n_elements < 1:
        raise ValueError(f"beam needs at least one element, got {n_elements}")
    R0 = local_frame(direction)
    s = np.linspace(0.0, length, n_elements + 1)
    coords = np.asarray(origin, dtype=float) + s[:, None] * R0[:, 0]
    L = np.diff(s)
    R = np.broadcast_to(R0, (n_elements, 3, 3))
    Ke, Me, Mke = element_matrices(section, L, R)
    conn = np.stack([np.arange(n_elements), np.arange(1, n_elements + 1)], -1)
    idx = (6 * conn[:, :, None] + np.arange(6)).reshape(n_elements, 12)
    n_dof = 6 * (n_elements + 1)
    Mk = np.stack([_assemble(n_dof, idx, Mke[:, k]) for k in range(3)])
    return FEModel(coords=coords, K=_assemble(n_dof, idx, Ke), M=_assemble(n_dof, idx, Me), M_kernel=Mk)


def strain_kernels(section: Section, direction, length: float, n_elements: int):
    """Second-order (von Karman) axial strain of the beam_model mesh at the Gauss points:

        eps = e + s,  e = A q (linear axial strain u1'),  s = 1/2 ((C q)^2 + (D q)^2),

    with C q = u2', D q = u3' the slopes of the centreline in the two bending planes (local axes,
    centreline displacement derivative: u2' = gamma2 + theta3, u3' = gamma3 - theta2 from the IIE
    interpolation of `local_interpolation`). The strain energy beyond the linear K is then
    sum_g w_g (e_g s_g + s_g^2 / 2), w_g = EA ds (Gauss weight times element length).

    Returns w (ng,), A, C, D (ng, n_dof) in model dofs, ng = 4 n_elements (same rule as K and M:
    e s and s^2 are exact for the degree of these products up to 6).
    """
    R = local_frame(direction)
    L = np.full(n_elements, length / n_elements)
    _, Nt, B = local_interpolation(section, L)
    Tq = np.kron(np.eye(4), R.T)  # local dofs = Tq @ model dofs
    A = B[:, :, 0] @ Tq
    C = (B[:, :, 1] + Nt[:, :, 2]) @ Tq
    D = (B[:, :, 2] - Nt[:, :, 1]) @ Tq
    n_dof = 6 * (n_elements + 1)
    idx = (6 * np.arange(n_elements)[:, None] + np.arange(12)).reshape(n_elements, 12)

    def scatter(X):  # (n_el, ng, 12) -> (n_el * ng, n_dof)
        out = np.zeros((n_elements, X.shape[1], n_dof))
        out[np.arange(n_elements)[:, None, None], np.arange(X.shape[1])[None, :, None], idx[:, None, :]] = X
        return out.reshape(-1, n_dof)

    w = (section.EA * _W[None, :] * L[:, None]).ravel()
    return w, scatter(A), scatter(C), scatter(D)


def tensor_kernel(section: Section, direction, length: float, n_elements: int, lumped=()) -> np.ndarray:
    """T[a, b] = int N_a^T N_b rho (3, 3, n_dof, n_dof), model axes, for the beam_model mesh and the
    rigid bodies `lumped` at its nodes ((node, mass, J) as fe.with_lumped_masses, fe.lumped_kernels).

    Section-point displacement N_c q + theta x y (fe.beam): int over the section gives
    m N_c,a^T N_c,b + N_t^T E_a^T S E_b N_t, S = int rho y y^T = R diag(0, m33, m22) R^T, E_a = e_a~.
    Consistent with the FE model: sum_a T_aa = M (m11 = m22 + m33) and -eps_kab T_ab = M_k.
    """
    R = local_frame(direction)
    L = np.full(n_elements, length / n_elements)
    Nc, Nt, _ = local_interpolation(section, L)  # (n_el, ng, 3, 12), local axes and dofs
    w = 0.5 * np.polynomial.legendre.leggauss(Nc.shape[1])[1]  # same Gauss rule as fe.beam
    Tq = np.kron(np.eye(4), R.T)  # local dofs = Tq @ model dofs
    Nc = np.einsum("ij,egjk,kl->egil", R, Nc, Tq)
    Nt = np.einsum("ij,egjk,kl->egil", R, Nt, Tq)
    S = R @ np.diag([0.0, section.m33, section.m22]) @ R.T
    E = skew(np.eye(3))
    ESE = np.einsum("aji,jk,bkl->abil", E, S, E)  # E_a^T S E_b
    wL = w[None, :] * L[:, None]
    Te = section.m * np.einsum("eg,egai,egbj->abeij", wL, Nc, Nc) + np.einsum(
        "eg,egpi,abpr,egrj->abeij", wL, Nt, ESE, Nt, optimize=True
    )
    idx = node_dofs(np.arange(n_elements + 1)).reshape(-1, 6)
    idx = np.concatenate([idx[:-1], idx[1:]], axis=1)  # (n_el, 12) element dofs
    n = 6 * (n_elements + 1)
    T = np.zeros((3, 3, n, n))
    np.add.at(T, (slice(None), slice(None), idx[:, :, None], idx[:, None, :]), Te)
    for node, mass, J in lumped:
        i = node_dofs([node])
        T[:, :, i[:, None], i[None, :]] += lumped_kernels(mass, J)[2]
    return T
