"""Superelement reduction of geradin section 7 (docs/background.md).

Basis (eq. 76): free attachment modes with inertia relief recast on the boundary displacements,
plus free-free vibration modes, all mass-orthogonal to the rigid modes about the CM (eq. 74),
so the reduced coordinates are elastic displacements seen from the CM frame. Craig-Bampton
is not admissible here (its constraint modes are not orthogonal to the rigid modes).
"""
from __future__ import annotations

import dataclasses

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .fe import FEModel, node_dofs, rigid_modes, with_lumped_masses
from .fe.beam import beam_model, local_frame, strain_kernels, tensor_kernel
from .model import Body, ModelError, body_damping, reduction_options, scene_body  # noqa: F401 (reduction_options: its name here too)
from .port_data import compliance, port_data
from .runtime.data import BodyData, ReducedBody, SuperelementData


@dataclass(frozen=True, eq=False)
class Reduction:
    data: SuperelementData  # from ffrf_fmu.runtime.data
    Y: np.ndarray  # (n_dof, n) basis of eq. (76)
    U: np.ndarray  # (n_dof, 6) rigid modes about the CM
    orthogonality_error: float  # max|U^T M Y| / max|M|
    block_diagonality_error: float  # max|K_bar boundary-modal block| / max|K_bar|
    n_fe_dofs: int


def mass_properties(fe: FEModel) -> tuple[float, np.ndarray]:
    """Mass and centre of mass from the rigid modes about the model origin (eq. 11-13).

    U0_t^T M U0_t = m I and U0_t^T M U0_r = -m skew(x_cm).
    """
    U0 = rigid_modes(fe.coords, np.zeros(3))
    MU = U0.T @ fe.M @ U0
    mass = np.trace(MU[:3, :3]) / 3.0
    S = -MU[:3, 3:] / mass  # = skew(x_cm)
    return mass, np.array([S[2, 1], S[0, 2], S[1, 0]])


def mass_projector(M: np.ndarray, U: np.ndarray) -> np.ndarray:
    """P = I - M U (U^T M U)^-1 U^T: removes from a load its rigid (inertia-relief) resultant."""
    return np.eye(M.shape[0]) - M @ U @ np.linalg.solve(U.T @ M @ U, U.T)


def free_free_modes(fe: FEModel, U: np.ndarray, n_modes: int) -> tuple[np.ndarray, np.ndarray]:
    """First n_modes elastic modes of K x = w^2 M x (6 rigid ones dropped), mass-normalized and
    projected explicitly against the rigid modes: the raw eigenvectors are orthogonal to U only
    to ~1e-8 when the axial stiffness dwarfs the bending one (docs/background.md).

    Returns (Xi (n_dof, n_modes), omega^2 (n_modes,)).
    """
    if n_modes == 0:
        return np.zeros((fe.n_dof, 0)), np.zeros(0)
    import scipy.linalg as sla  # (here: a cached body, body_cache.py, runs without importing scipy)

    try:
        w2, X = sla.eigh(fe.K, fe.M, subset_by_index=[6, 5 + n_modes])
    except np.linalg.LinAlgError as err:
        raise ValueError(f"mass matrix not positive definite (zero rotary/torsional inertia?): {err}") from None
    A = U.T @ fe.M @ U
    X = X - U @ np.linalg.solve(A, U.T @ (fe.M @ X))
    X = X / np.sqrt(np.einsum("ij,ik,kj->j", X, fe.M, X))
    return X, w2


def attachment_modes(fe: FEModel, U: np.ndarray, boundary: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Free attachment modes with inertia relief F_B = G_e L_B^T, G_e = P^T G_c P.

    G_c is the flexibility with the dofs `support` fixed (any isostatic support: G_e does not
    depend on it, since P L_B^T is self-equilibrated). boundary, support: dof index arrays.
    """
    import scipy.linalg as sla

    P = mass_projector(fe.M, U)
    free = np.setdiff1d(np.arange(fe.n_dof), support)
    load = P[:, boundary]  # P L_B^T
    x = np.zeros_like(load)
    x[free] = sla.solve(fe.K[np.ix_(free, free)], load[free], assume_a="sym")
    # P^T applied twice: the first pass leaves U^T M F at round-off of |U^T M x|, which the
    # stiffness F_BB^-1 then amplifies (~1e-10 on B2 at 32 elements); the second pass removes it
    return P.T @ (P.T @ x)


CORRECTION_THRESHOLD = 1e-3  # keep a centrifugal correction shape whose part outside span(Y) exceeds this (M-norm)


def centrifugal_loads(fe: FEModel, U: np.ndarray) -> np.ndarray:
    """FE load vectors F_ab (6, n_dof) of the centrifugal field -rho w~ w~ X about the CM, one per
    product w_a w_b (a <= b; off-diagonal ones counted once, i.e. times 2 in the sum):

        f0(w) = -int N^T w~ w~ X rho = sum_ab w_a w_b F_ab,  F_ab = -(M_b U_ra + M_a U_rb) / 2

    (translational kernel M_k of eq. 53, U_r the rotation columns of the rigid modes about the CM),
    so that Y^T F_ab = W1[:, a, b] / 2 (Witteveen's constant centrifugal load, docs/inertia-terms.md).
    """
    Ur, Mk = U[:, 3:], fe.M_kernel
    pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    return np.stack([-0.5 * (Mk[b] @ Ur[:, a] + Mk[a] @ Ur[:, b]) for a, b in pairs])


def correction_modes(fe: FEModel, U: np.ndarray, Y: np.ndarray, boundary: np.ndarray, count: int | None = None) -> np.ndarray:
    """Static correction modes for the centrifugal load about the CM (docs/equations.md).

    The free (inertia-relief) static responses x_ab = G_e F_ab to the six centrifugal load cases,
    made zero on the boundary dofs with the attachment columns (as the vibration modes of eq. 76
    are: q_B must stay the boundary displacement of the spatial coordinates), then M-orthogonalized
    against the modal columns and orthonormalized in M (SVD). Shapes whose remaining M-norm exceeds
    CORRECTION_THRESHOLD of the largest response are kept (a straight beam: one, the axial stretch
    under w_perp^2; with a point mass whose inertia is not isotropic, also the tilt of its node under
    the centrifugal moment). Without them a superelement's axial force is that of its attachment shapes
    (linear in the abscissa) where the centrifugal one is parabolic. count: keep exactly the `count`
    largest shapes (reduce_body: every superelement of a body needs the same number), each still above
    CORRECTION_FLOOR of the largest response.
    """
    import scipy.linalg as sla

    n_b = boundary.size
    P = mass_projector(fe.M, U)
    free = np.setdiff1d(np.arange(fe.n_dof), boundary[:6])
    F = P @ centrifugal_loads(fe, U).T
    x = np.zeros_like(F)
    x[free] = sla.solve(fe.K[np.ix_(free, free)], F[free], assume_a="sym")
    x = P.T @ (P.T @ x)  # free, mass-orthogonal to the rigid modes (74), twice as in attachment_modes
    r = x - Y[:, :n_b] @ x[boundary]
    Ym = Y[:, n_b:]
    if Ym.shape[1]:
        r -= Ym @ np.linalg.solve(Ym.T @ fe.M @ Ym, Ym.T @ (fe.M @ r))
    scale = np.sqrt(np.einsum("ij,ik,kj->j", x, fe.M, x)).max()
    if scale == 0.0:
        return np.zeros((fe.n_dof, 0))
    Lc = np.linalg.cholesky(fe.M)  # M-orthonormal basis of the residual shapes: SVD of L^T r
    _, sv, vt = np.linalg.svd(Lc.T @ r, full_matrices=False)
    keep = sv > CORRECTION_THRESHOLD * scale
    if count is not None:
        if count > sv.size or sv[count - 1] <= CORRECTION_FLOOR * scale:
            raise ValueError(f"{count} centrifugal correction shapes requested, but this superelement has only "
                             f"{int(np.sum(sv > CORRECTION_FLOOR * scale))} above {CORRECTION_FLOOR:g} of its response")
        keep = np.arange(sv.size) < count
    return r @ vt[keep].T / sv[keep]


CORRECTION_FLOOR = 1e-8  # a correction shape below this fraction of the largest response is round-off, not a shape
STRAIN_RANK_TOL = 1e-9  # axial strain shapes below this fraction of the largest singular value are round-off


def stiffening_data(fe: FEModel, U: np.ndarray, Y: np.ndarray, strain) -> dict:
    """Reduced stiffening data of one superelement: W1 (n, 3, 3) and the second-order strain tensors.

    W1_j = C_j + C_j^T, C_j[:, k] = U_r^T M_k Y_j (Witteveen, docs/inertia-terms.md), on the basis Y.
    Strain (docs/equations.md, "Geometric stiffening"): the axial strain shapes the basis can hold,
    E (ng, r) with E^T W E = I (W = diag(EA ds)) spanning range(A Y); the membrane strain is taken
    in that space (assumed strain: the L2 projection of e + s, against membrane locking):
        eps_k = a_k q + 1/2 q^T B_k q,  a = E^T W A Y (r, n),  B_k = Y^T (C^T W_k C + D^T W_k D) Y,
        W_k = diag(w E[:, k]).
    """
    C = np.einsum("ia,kij,jm->mak", U[:, 3:], fe.M_kernel, Y, optimize=True)
    w, A, Cs, D = strain
    sw = np.sqrt(w)
    u, sv, _ = np.linalg.svd(sw[:, None] * (A @ Y), full_matrices=False)
    Us = u[:, sv > STRAIN_RANK_TOL * sv.max()]  # = W^1/2 E
    a = Us.T @ (sw[:, None] * (A @ Y))
    wE = sw[:, None] * Us  # W E (ng, r)
    CY, DY = Cs @ Y, D @ Y
    B = np.einsum("gk,gi,gj->kij", wE, CY, CY, optimize=True) + np.einsum("gk,gi,gj->kij", wE, DY, DY, optimize=True)
    return {"W1": C + C.transpose(0, 2, 1), "vk_a": a, "vk_B": 0.5 * (B + B.transpose(0, 2, 1))}


def inertia_data(fe: FEModel, U: np.ndarray, Y: np.ndarray, T: np.ndarray) -> dict:
    """Witteveen's W1 (n, 3, 3) and W2 (n, n, 3, 3) on the basis Y (docs/inertia-terms.md), for the
    term set `full`: W1_j = C_j + C_j^T, C_j[:, k] = U_r^T M_k Y_j; W2_jl = tr(P_jl) I - P_jl^T,
    P_jl[a, b] = Y_j^T T_ab Y_l with T the full tensor kernel (fe.beam.tensor_kernel)."""
    C = np.einsum("ia,kij,jm->mak", U[:, 3:], fe.M_kernel, Y, optimize=True)
    P = np.einsum("ij,abik,kl->jlab", Y, T, Y, optimize=True)
    W2 = np.einsum("jlaa->jl", P)[:, :, None, None] * np.eye(3) - P.transpose(0, 1, 3, 2)
    return {"W1": C + C.transpose(0, 2, 1), "W2": 0.5 * (W2 + W2.transpose(1, 0, 3, 2))}


def reduce_superelement(
    fe: FEModel, boundary_nodes: Sequence[int], n_modes: int, global_nodes: Sequence[int], strain=None, tensor=None,
    n_correction: int | None = None,
) -> Reduction:
    """Reduce `fe` to eq. (76): q = Y [q_B; eta], q_B = 6 dofs per boundary node (node-major,
    order of boundary_nodes), eta = amplitudes of the n_modes free-free modes.

    Y = [[I, 0], [F_IB F_BB^-1, Xi_I - F_IB F_BB^-1 Xi_B]] (rows: boundary, interior dofs).
    Body axes = model axes (no principal-axis rotation), origin at the CM.
    """
    boundary = node_dofs(boundary_nodes)
    n_b = boundary.size
    mass, x_cm = mass_properties(fe)
    U = rigid_modes(fe.coords, x_cm)
    F = attachment_modes(fe, U, boundary, support=boundary[:6])  # first boundary node clamped
    F_BB = F[boundary]
    F_BB = 0.5 * (F_BB + F_BB.T)  # symmetric in exact arithmetic (L_B G_e L_B^T)
    d = 1.0 / np.sqrt(np.abs(np.diag(F_BB)))
    # Jacobi-scaled condition: axial and bending flexibilities differ by ~1e5 legitimately
    # (measured ~80-170 scaled for 2..32 elements); with no interior node it is ~1e17
    if np.linalg.cond(F_BB * np.outer(d, d)) > 1e10:
        raise ValueError(
            "boundary flexibility F_BB is singular: a superelement needs interior nodes "
            "(at least 2 elements per superelement)"
        )
    if n_modes < 0 or n_b + n_modes > fe.n_dof - 6:
        raise ValueError(
            f"{n_modes} modes requested but the FE model ({fe.n_nodes} nodes, {fe.n_dof} dofs) has room for "
            f"at most {fe.n_dof - 6 - n_b} besides its 6 rigid modes and {n_b} boundary dofs: use more elements"
        )
    Xi, w2 = free_free_modes(fe, U, n_modes)
    interior = np.setdiff1d(np.arange(fe.n_dof), boundary)
    FBinv = np.linalg.solve(F_BB, F[interior].T).T  # F_IB F_BB^-1 (F_BB symmetric)
    Y = np.zeros((fe.n_dof, n_b + n_modes))
    Y[boundary, :n_b] = np.eye(n_b)
    Y[interior, :n_b] = FBinv
    Y[interior, n_b:] = Xi[interior] - FBinv @ Xi[boundary]
    if strain is not None:  # geometric stiffening: static correction modes appended to eta
        Y = np.concatenate([Y, correction_modes(fe, U, Y, boundary, n_correction)], axis=1)
    K_bar = Y.T @ fe.K @ Y
    M_bar = Y.T @ fe.M @ Y
    d = 1.0 / np.sqrt(np.diag(M_bar))
    # Y must have full rank: a mode whose shape the boundary attachment modes already span
    # (e.g. 3 bending pairs on a 3-element beam) makes M_bar singular (scaled cond ~1e16)
    if np.linalg.cond(M_bar * np.outer(d, d)) > 1e10:
        raise ValueError(
            f"the {n_modes} kept modes are not independent of the boundary attachment modes on this mesh "
            f"({fe.n_nodes - 1} elements): use more elements or fewer modes"
        )
    G = np.einsum("ia,kij,jb->kab", Y, fe.M_kernel, Y, optimize=True)
    J0 = U[:, 3:].T @ fe.M @ U[:, 3:]  # eq. (13) about the CM, model axes
    data = SuperelementData(
        mass=float(mass),
        J0=0.5 * (J0 + J0.T),
        x_cm=x_cm,
        X_B=fe.coords[np.asarray(boundary_nodes)] - x_cm,
        nodes=np.asarray(global_nodes, dtype=int),
        K=0.5 * (K_bar + K_bar.T),  # symmetrized: the asymmetry is round-off
        M=0.5 * (M_bar + M_bar.T),
        G=0.5 * (G - G.transpose(0, 2, 1)),  # skew-symmetrized: the symmetric part is round-off
        frequencies_hz=np.sqrt(np.maximum(w2, 0.0)) / (2.0 * np.pi),
        **{**(stiffening_data(fe, U, Y, strain) if strain is not None else {}),
           **(inertia_data(fe, U, Y, tensor) if tensor is not None else {})},
    )
    return Reduction(
        data=data,
        Y=Y,
        U=U,
        orthogonality_error=float(np.abs(U.T @ fe.M @ Y).max() / np.abs(fe.M).max()),
        block_diagonality_error=float(np.abs(K_bar[:n_b, n_b:]).max(initial=0.0) / np.abs(K_bar).max()),
        n_fe_dofs=fe.n_dof,
    )


def build_body(model, scene: str | None = None) -> BodyData:
    """The reduced body of a model (model.Model) as its scene (default: the first) runs it: the public
    ffrf_fmu.build_body. A model.Body alone is reduced by `reduce_body` (which also returns the
    reductions)."""
    if isinstance(model, Body):
        raise TypeError("build_body(model, scene) takes a loaded model (ffrf_fmu.load_model); a model.Body is reduced "
                        "by ffrf_fmu.reduction.reduce_body(body, stiffening=..., inertia=...), which returns a ReducedBody")
    return reduce_scene_body(model.body, model.scene(scene)).data


def reduce_scene_body(body: Body, scene) -> ReducedBody:
    """The body as a scene runs it: the scene's causality (model.scene_body) and the data its
    options need (reduction_options)."""
    return reduce_body(scene_body(body, scene), **reduction_options(scene))


def superelement_models(body: Body, e: int, strain: bool = False, tensor: bool = False):
    """The FE model of superelement e of `body` (its segment of the beam, the point masses on its nodes),
    and on request its strain kernels (fe.beam.strain_kernels) and tensor kernel (fe.beam.tensor_kernel):
    (fe, strain | None, tensor | None). A point mass on a node shared by two superelements belongs to the
    one nearer the origin."""
    n_se, n_el = body.superelements, body.elements_per_superelement
    d = np.asarray(body.direction, dtype=float)
    d = d / np.linalg.norm(d)
    seg = body.length / n_se
    R = local_frame(d)
    lumped = []
    for pm in body.masses:
        owner = 0 if pm.at <= 0.0 else min(n_se - 1, int(np.ceil(pm.at / seg - 1e-9)) - 1)
        k = (pm.at - e * seg) / (seg / n_el)
        if owner == e:
            if abs(k - round(k)) > 1e-9 * n_el:
                raise ModelError(f"{body.source}: point mass at {pm.at:g} m is not on a node of {n_se} superelement(s) x "
                                 f"{n_el} elements (element length {seg / n_el:g} m)")
            lumped.append((int(round(k)), pm.mass, R @ np.diag(pm.inertia) @ R.T))
    fe = with_lumped_masses(beam_model(body.section, np.asarray(body.origin, dtype=float) + e * seg * d, d, seg, n_el), lumped)
    return (fe, strain_kernels(body.section, d, seg, n_el) if strain else None,
            tensor_kernel(body.section, d, seg, n_el, lumped) if tensor else None)


def reduce_solid_body(body: Body, stiffening: bool = False, inertia: bool = False) -> ReducedBody:
    """The ReducedBody (BodyData, (SolidReduction,)) of a solid body: one superelement on its port frames.
    Its FE model (solid/source.py) and the sparse reduction (reduction_sparse.py) are imported here, on
    first use, so that a beam's reduction never loads them."""
    from .reduction_sparse import reduce_solid
    from .solid.frames import solid_frames
    from .solid.source import solid_fe

    spec = body.solid
    try:  # a bad selection, a set that cannot hold a frame, a mechanism: the model's fault, said as such
        fe = solid_fe(spec)
        frames = solid_frames(spec, fe)
        red = reduce_solid(fe, frames, n_modes=body.modes if spec.cutoff_hz is None else None,
                           cutoff_hz=spec.cutoff_hz, inertia=inertia, stiffening=stiffening)
    except ValueError as e:
        raise ModelError(f"body {body.name!r} ({body.source}): {e}") from None
    data = BodyData(name=body.name, superelements=(red.data,),
                    node_positions=np.array([f.point for f in frames]),
                    ports=port_data(body, len(frames)), damping=body_damping(body, red.data.n))
    if any("compliant" in (p.translation, p.rotation) for p in data.ports):
        data = dataclasses.replace(data, ports=tuple(compliance(data, body, p) for p in data.ports))
    return ReducedBody(data, (red,))


def reduce_body(body: Body, stiffening: bool = False, inertia: bool = False) -> ReducedBody:
    """Split the beam into body.superelements equal segments, each its own FE model of
    body.elements_per_superelement elements, reduce each on its two end nodes.
    stiffening: add the geometric stiffening data (centrifugal correction modes, W1, strain kernels).
    inertia: add Witteveen's W1, W2 (the term set `full`).

    Global boundary node i sits at s = i L / n_se; superelement e joins nodes (e, e+1).
    The ports keep the body's causality: a scene's overrides come in through model.scene_body
    (reduce_scene_body).
    """
    if body.solid is not None:  # a solid: one sparse superelement on its port frames (reduction_sparse.py)
        return reduce_solid_body(body, stiffening=stiffening, inertia=inertia)
    n_se, n_el = body.superelements, body.elements_per_superelement
    if n_se < 1:
        raise ValueError(f"body {body.name!r}: needs at least one superelement")
    if n_el < 2:
        raise ValueError(
            f"body {body.name!r}: {n_el} element(s) per superelement leaves F_BB singular; use at least 2"
        )
    d = np.asarray(body.direction, dtype=float)
    d = d / np.linalg.norm(d)
    node_positions = np.asarray(body.origin, dtype=float) + np.outer(np.arange(n_se + 1) * body.length / n_se, d)
    def reduce_all(n_correction=None):
        out = []
        for e in range(n_se):
            fe, strain, tensor = superelement_models(body, e, strain=stiffening, tensor=inertia)
            try:
                out.append(reduce_superelement(fe, boundary_nodes=(0, n_el), n_modes=body.modes, global_nodes=(e, e + 1),
                                               strain=strain, tensor=tensor, n_correction=n_correction))
            except ValueError as err:
                raise ValueError(f"body {body.name!r} ({body.source}), superelement {e}: {err}") from None
        return tuple(out)

    reductions = reduce_all()
    counts = {r.Y.shape[1] for r in reductions}
    if len(counts) > 1:  # point masses: more correction shapes in some superelements; the layout needs one count
        reductions = reduce_all(max(counts) - 6 * 2 - body.modes)
    data = BodyData(
        name=body.name,
        superelements=tuple(r.data for r in reductions),
        node_positions=node_positions,
        ports=port_data(body, n_se + 1),
        damping=body_damping(body, reductions[0].data.n),
    )
    if any("compliant" in (p.translation, p.rotation) for p in data.ports):
        data = dataclasses.replace(data, ports=tuple(compliance(data, body, p) for p in data.ports))
    return ReducedBody(data, reductions)


