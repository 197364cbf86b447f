"""Shell bodies on 6-dof nodes: the mass split into node-block mass and fibre mass points
(ffrf_fmu/solid/__init__.py, solid/shell_body.py), the invariants from it against a brute-force
quadrature of the deformed body (docs/equations.md, "Invariants of a body with rotational dofs"),
Witteveen's plate as a bundled model (models/witteveen_plate.toml) and its FMU."""
from pathlib import Path

import meshio
import numpy as np
import pytest

from ffrf_fmu.checked_toml import ModelError
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.reduction_sparse import reduce_solid
from ffrf_fmu.solid.constraints import mass_properties
from ffrf_fmu.runtime.rotation import skew
from ffrf_fmu.solid.frames import Frame
from ffrf_fmu.solid.mesh import Material
from ffrf_fmu.solid.shell import assemble_shells, element_frame, plate_mesh
from ffrf_fmu.solid.shell_body import shell_body

MODELS = Path(__file__).resolve().parents[1] / "models"
STEEL = Material(2.1e11, 0.3, 7850.0)
LEISSA = np.array([13.49, 19.79, 24.43, 35.02, 35.02])  # free square plate, nu 0.3 (docs/shells.md)


def folded_plate():
    """An L-shaped strip folded 90 degrees along x = 0.3 (two flat parts, normals Z and X), distorted
    quads (no parallelogram) and two thicknesses: the fibre directions differ between elements."""
    nodes, quads = plate_mesh(0.6, 0.2, 6, 3)
    nodes[:, 1] += 0.02 * np.sin(7.0 * nodes[:, 0]) * (nodes[:, 1] > 0) * (nodes[:, 1] < 0.2)  # distorted
    x = nodes[:, 0].copy()
    bent = x > 0.3
    nodes[bent, 0], nodes[bent, 2] = 0.3, x[bent] - 0.3
    t = np.where(np.arange(len(quads)) % 2 == 0, 0.004, 0.006)
    return assemble_shells(nodes, quads, t, STEEL)


def material_points(shell):
    """(node indices q, normal n, N (4,), height z, weight [kg]) of every point of a 3 x 3 Gauss rule in
    the plane of each element and 3 through its thickness (exact for the polynomial integrands here),
    and the point's undeformed position X."""
    g, w = np.polynomial.legendre.leggauss(3)
    xi_n, eta_n = np.array([-1, 1, 1, -1]), np.array([-1, -1, 1, 1])
    for e, q in enumerate(shell.quads):
        T, xy = element_frame(shell.coords[q])
        t, c = shell.thickness[e], shell.coords[q].mean(0)  # the flat element's plane passes through its centre
        for xi, wx in zip(g, w):
            for eta, wy in zip(g, w):
                N = 0.25 * (1 + xi_n * xi) * (1 + eta_n * eta)
                dN = 0.25 * np.array([xi_n * (1 + eta_n * eta), eta_n * (1 + xi_n * xi)])
                detJ = np.linalg.det(dN @ xy)
                for zeta, wz in zip(g, w):
                    z = 0.5 * t * zeta
                    yield q, T[2], N, z, STEEL.rho * detJ * wx * wy * 0.5 * t * wz, c + (N @ xy) @ T[:2] + z * T[2]


def displacement(U, q, n, N, z):
    """u = u_0 + z theta x n at a material point from the node fields U (n_nodes, 6)."""
    return N @ U[q, :3] + z * np.cross(N @ U[q, 3:], n)


def brute_force_kernel(shell, U1, U2, A):
    """int rho u1^T A u2 over the shell's volume (material_points)."""
    return sum(m * displacement(U1, q, n, N, z) @ A @ displacement(U2, q, n, N, z)
               for q, n, N, z, m, _ in material_points(shell))


def brute_force_inertia(shell, U, x_cm):
    """The inertia tensor about x_cm of the shell deformed by the node field U (n, 6), by quadrature."""
    J = np.zeros((3, 3))
    for q, n, N, z, m, X in material_points(shell):
        r = X - x_cm + displacement(U, q, n, N, z)
        J += m * (r @ r * np.eye(3) - np.outer(r, r))
    return J


@pytest.fixture(scope="module")
def folded():
    shell = folded_plate()
    fe = shell_body(shell)
    X = fe.coords
    frames = [Frame(name, np.flatnonzero(np.abs(X[:, k] - v) < 1e-9), "rigid", p)
              for name, k, v, p in (("a", 0, 0.0, np.array([0.0, 0.1, 0.0])),
                                    ("b", 2, 0.3, np.array([0.3, 0.1, 0.3])))]
    return shell, fe, reduce_solid(fe, frames, n_modes=6, inertia=True)


def test_mass_split_adds_up_and_gives_mass_and_cm(folded):
    """six_dof_fe refuses a split that does not add up to M (1e-9); the split's mass and CM are the
    shell's: rho t A summed, and the area-weighted centre (exact: the two legs are rectangles of the
    distorted mesh's area, computed here by quadrature)."""
    shell, fe, _ = folded
    m, c = mass_properties(fe)
    ones = np.zeros((fe.n_nodes, 6))
    ones[:, 0] = 1.0
    mass = brute_force_kernel(shell, ones, ones, np.eye(3))
    first = np.array([brute_force_kernel(shell, ones, field, np.eye(3)) for field in
                      [np.column_stack([fe.coords[:, k], np.zeros((fe.n_nodes, 5))]) for k in range(3)]])
    assert m == pytest.approx(mass, rel=1e-12)
    assert c == pytest.approx(first / mass, abs=1e-12)


def test_invariants_against_quadrature_of_the_deformed_shell(folded):
    """I(q) = I0 + sum q_j W1_j + sum q_j q_l W2_jl of the reduction (W1, W2 from the node mass and the
    fibre mass points) against the inertia tensor of the deformed folded shell integrated through its
    thickness (brute_force_inertia): exact in both, so to round-off (1e-10 of |I0|). q is large (the
    quadratic term matters): 5 % of the size. Also G_k = Y^T M_k Y (Coriolis, geradin 53) against
    int rho u_1 . (e_k x u_2)."""
    shell, fe, red = folded
    d = red.data
    rng = np.random.default_rng(3)
    q = rng.standard_normal(d.K.shape[0])
    u = red.Y @ q
    q *= 0.05 * 0.6 / np.abs(fe.translations(u[:, None])).max()
    U = (red.Y @ q).reshape(-1, 6)
    J_ref = brute_force_inertia(shell, U, d.x_cm)
    J = d.J0 + np.einsum("j,jab->ab", q, d.W1) + np.einsum("j,l,jlab->ab", q, q, d.W2)
    scale = np.abs(d.J0).max()
    assert np.abs(J - J_ref).max() < 1e-10 * scale
    assert np.abs(np.einsum("j,jab->ab", q, d.W1)).max() > 1e-3 * scale  # the deformation counts
    q2 = rng.standard_normal(d.K.shape[0])
    U2 = (red.Y @ q2).reshape(-1, 6)
    for k in range(3):
        g_ref = brute_force_kernel(shell, U, U2, skew(np.eye(3)[k]))
        assert q @ d.G[k] @ q2 == pytest.approx(g_ref, rel=1e-9, abs=1e-12 * np.abs(d.G).max())


@pytest.fixture(scope="module")
def plate():
    model = load_model(MODELS / "witteveen_plate.toml")
    (red,) = reduce_body(model.body).reductions
    return model, red


def test_witteveen_plate_mass_and_free_frequencies(plate):
    """His plate, 1000 x 1000 x 0.5 mm, 3.9 kg (steel: 3.925 kg). Its 20 kept free-free modes are the free
    plate's (the 4 corner frames are averaging: they add no stiffness); lambda = omega a^2 sqrt(rho t/D)
    of the first five against Leissa's within 1.5 % (the 20 x 20 MITC4 mesh: 0.6 % at 16 x 16 in
    docs/shells.md, converging from below on the 2nd; Leissa's values themselves are Ritz bounds)."""
    model, red = plate
    assert red.data.mass == pytest.approx(3.925, rel=1e-12)
    assert red.data.x_cm == pytest.approx([0.5, 0.5, 0.0], abs=1e-12)
    D = STEEL.E * 0.0005**3 / (12 * (1 - STEEL.nu**2))
    lam = 2 * np.pi * red.data.frequencies_hz[:5] * np.sqrt(STEEL.rho * 0.0005 / D)
    assert lam == pytest.approx(LEISSA, rel=0.015)
    assert len(red.data.frequencies_hz) == 20 and red.orthogonality_error < 1e-10


def in_t_mm(red):
    """The reduced plate's FE model in t and mm (his units): translations x 1e3 (mm), rotations in rad,
    energies x 1e3 (N mm), masses x 1e-3 (t); the frames' points in mm; reduced again."""
    import dataclasses

    import scipy.sparse as sp

    from ffrf_fmu.solid import MassPoints

    fe, s, e = red.fe, 1e3, 1e3
    Di = sp.diags(1.0 / np.tile([s, s, s, 1.0, 1.0, 1.0], fe.n_nodes))
    fe_mm = dataclasses.replace(fe, coords=fe.coords * s, K=sp.csr_matrix(e * Di @ fe.K @ Di),
                                M=sp.csr_matrix(e * Di @ fe.M @ Di), M_scalar=fe.M_scalar * 1e-3,
                                mass_points=MassPoints(sp.csr_matrix(s * fe.mass_points.N @ Di), fe.mass_points.w * 1e-3))
    frames = [dataclasses.replace(f, point=np.asarray(f.point) * s) for f in red.frames]
    return reduce_solid(fe_mm, frames, n_modes=len(red.data.frequencies_hz), inertia=True)


def test_witteveen_plate_invariants_in_his_units(plate):
    """His Table 2-3 plate row (t, mm; 20 free + 24 interface modes, as ours: 44 pseudo free-free modes):
    max |W1| 42.1, "norm" of W1 21.1 (his norm is W1 / 2 again, docs/inertia-terms.md ambiguity 3),
    max |W2| 1.0, |W2| 2.0. His corner frames are not published, ours are our choice: 10 %. His |I0| =
    65.74 is a tenth of what 3.9 kg on 1000 x 1000 mm allows: m (a^2 + b^2) / 12 = 650 t mm^2 about the
    normal whatever the mesh; ours is that (1e-4: the fibres' rotary inertia adds m t^2 / 12). The model
    in t and mm has the frequencies of the model in SI (1e-7: the static solves' tolerance)."""
    from ffrf_fmu.invariants import indicators, solid_invariants

    _, red = plate
    red_mm = in_t_mm(red)
    assert red_mm.data.frequencies_hz == pytest.approx(red.data.frequencies_hz, rel=1e-7)
    t = indicators(solid_invariants(red_mm))["table"]
    assert t["I0_norm"] == pytest.approx(3.925e-3 * 2e6 / 12, rel=1e-4)
    assert t["W1_max"] == pytest.approx(42.1, rel=0.1)
    assert t["W1_norm"] / 2 == pytest.approx(21.1, rel=0.1)
    assert t["W2_max"] == pytest.approx(1.0, rel=0.1) and t["W2_norm"] == pytest.approx(2.0, rel=0.1)


def test_witteveen_plate_fmu_equals_its_standalone_run(tmp_path):
    """The shell body as an FMU under fmpy against its standalone run (validate's tolerances), shortened."""
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.validate import validate

    model, overrides = MODELS / "witteveen_plate.toml", ["duration=2.4", "step=0.01"]
    fmu = build_fmu(model, tmp_path / "plate.fmu", overrides=overrides)
    rep = validate(fmu, model=model, overrides=overrides, plots=False)
    assert rep["fmu_reached_stop_time"] and rep["fmu_matches_model"] and rep["passed"]


@pytest.mark.parametrize("mesh, why", [
    ('plate = { size = [1.0, 1.0], divisions = [2, 2] }\nelement = "mitc4"', "needs thickness"),
    ('plate = { size = [1.0, 1.0], divisions = [2, 2] }\nelement = "hex8"', "meshed with shells"),
    ('box = { size = [1.0, 1.0, 0.1], divisions = [2, 2, 1] }\nelement = "mitc4"\nthickness = 0.01', "is a shell"),
    ('plate = { size = [1.0], divisions = [2, 2] }\nelement = "mitc4"\nthickness = 0.01', "2 positive lengths"),
])
def test_shell_mesh_errors_name_the_key(tmp_path, mesh, why):
    text = (MODELS / "witteveen_plate.toml").read_text()
    head, rest = text.split("[body.mesh]\n", 1)
    rest = rest.split("\n\n", 1)[1]
    f = tmp_path / "bad.toml"
    f.write_text(f"{head}[body.mesh]\n{mesh}\n\n{rest}")
    with pytest.raises(ModelError, match=why):
        load_model(f)


def test_witteveen_plate_against_calculix_s8(plate):
    """The bundled plate's first 10 elastic free-free frequencies against CalculiX (`ccx`, installed by
    bash .ci/run; fails without it) on the same 20 x 20 quads made quadratic (S8: a node at each edge's
    midpoint, which ccx expands to C3D20 bricks). Its linear S4 locks at a/h = 2000 (7.68 Hz where the
    4th pair is 4.35 Hz, docs/shells.md), S8 does not. Two discretizations of one plate: MITC4 bilinear
    (within 0.6 % of Leissa at 16 x 16) against a quadratic element; measured at most 0.8 % apart: 1.5 %."""
    from ffrf_fmu.solid.shell import plate_mesh
    from ffrf_fmu.solid.shell_calculix import run_calculix

    _, red = plate
    nodes, quads = plate_mesh(1.0, 1.0, 20, 20)
    f_ccx = run_calculix(nodes, quads, 0.0005, STEEL, 16, element="S8")
    # six rigid modes: ccx prints them up to 0.03 Hz (eigenvalues 3e-4 of the first elastic one: round-off)
    assert np.all(np.abs(f_ccx[:6]) < 0.05 * f_ccx[6])
    assert red.data.frequencies_hz[:10] == pytest.approx(f_ccx[6:16], rel=0.015)


def test_batched_assembly_equals_the_element_loop():
    """shell_batch (array operations over blocks of elements) against shell.py's element by element
    assembly on the folded, distorted mesh of two thicknesses: the same K and M to 1e-13 of their
    largest entry (only the summation order differs), in blocks smaller than the mesh."""
    import ffrf_fmu.solid.shell_batch as batch

    ref = folded_plate()
    old = batch.BLOCK
    try:
        batch.BLOCK = 5
        fast = batch.assemble_mitc4(ref.coords, ref.quads, ref.thickness, STEEL)
    finally:
        batch.BLOCK = old
    for A, B in ((fast.K, ref.K), (fast.M, ref.M)):
        assert abs(A - B).max() <= 1e-13 * abs(B).max()
    with pytest.raises(ValueError, match="quad 1"):  # a bow-tie: named, not assembled
        bad = ref.coords[ref.quads[:2]].reshape(-1, 3)
        batch.assemble_mitc4(bad, [[0, 1, 2, 3], [4, 5, 7, 6]], 0.01, STEEL)


def test_two_loose_plates_are_a_mechanism_and_a_soft_one_is_not():
    """Two plates that share no node have 12 zero modes: refused, saying so. One plate on frames at two
    corners, 0.5 mm thick (its first mode 1.68 Hz, 1e-12 of nothing: the mechanism bound is relative to
    the elements' K_ii / M_ii, not to a Ritz estimate of w_1^2 that a soft structure undercuts) is reduced."""
    n1, q1 = plate_mesh(0.2, 0.2, 2, 2)
    n2 = n1 + [0.5, 0.0, 0.0]
    shell = assemble_shells(np.vstack([n1, n2]), np.vstack([q1, q1 + len(n1)]), 0.002, STEEL)
    fe = shell_body(shell)
    frames = [Frame("a", np.arange(9), "rigid", np.zeros(3)), Frame("b", 9 + np.arange(9), "rigid", n2[0])]
    with pytest.raises(ValueError, match="more than 6 rigid modes"):
        reduce_solid(fe, frames, n_modes=2)


def test_thickness_from_cell_data(tmp_path):
    """A mesh file's cell data gives each quad its thickness ([body.mesh] thickness = {cell_data = NAME}):
    a plate of two halves, 1 and 3 mm, weighs rho (1 + 3) mm x half its area; a missing field or a
    non-positive thickness is an error naming the file and the field."""
    import meshio

    nodes, quads = plate_mesh(1.0, 1.0, 20, 20)  # the model's corner frames need the corner's neighbours
    t = np.where(nodes[quads].mean(1)[:, 0] < 0.5, 0.001, 0.003)
    text = (MODELS / "witteveen_plate.toml").read_text()
    head, rest = text.split("[body.mesh]\n", 1)
    rest = rest.split("\n\n", 1)[1]
    for name, field, why in (("good", t, None), ("missing", None, "no cell data 'thickness'"),
                             ("negative", -t, "quad 0 has thickness")):
        mesh = tmp_path / f"{name}.vtu"
        data = {"thickness": [field]} if field is not None else {"other": [t]}
        meshio.write(mesh, meshio.Mesh(nodes, [("quad", quads)], cell_data=data))
        f = tmp_path / f"{name}.toml"
        f.write_text(f'{head}[body.mesh]\nfile = "{mesh.name}"\nelement = "mitc4"\n'
                     f'thickness = {{ cell_data = "thickness" }}\n\n{rest}')
        if why is None:
            (red,) = reduce_body(load_model(f).body).reductions
            assert red.data.mass == pytest.approx(STEEL.rho * 0.5 * (0.001 + 0.003), rel=1e-12)
        else:
            with pytest.raises((ModelError, ValueError), match=why):
                reduce_body(load_model(f).body)


def test_triangles_are_bodies_too():
    """A folded strip of MITC4 quads and DKT triangles (half its quads split): the fibre mass points of
    both element types add up to the assembled mass (to 1e-12 of max|M|; with the triangles' points
    left out the rotary inertia of their fibres is missing), and the mass is rho t A."""
    from ffrf_fmu.solid.shell_tri import split_quads

    ref = folded_plate()
    half = len(ref.quads) // 2
    shell = assemble_shells(ref.coords, ref.quads[:half], 0.004, STEEL, trias=split_quads(ref.quads[half:], "13"))
    fe = shell_body(shell)
    assert abs(fe.kernel(np.eye(3)) - fe.M).max() <= 1e-12 * abs(fe.M).max()
    X = shell.coords
    area = sum(0.5 * np.linalg.norm(np.cross(X[c[1]] - X[c[0]], X[c[2]] - X[c[0]])) for c in shell.trias)
    area += sum(0.5 * np.linalg.norm(np.cross(X[q[2]] - X[q[0]], X[q[3]] - X[q[1]])) for q in shell.quads)
    assert mass_properties(fe)[0] == pytest.approx(STEEL.rho * 0.004 * area, rel=1e-12)


def test_model_file_mesh_of_quads_and_triangles(tmp_path):
    """A mesh file of quads and triangles (the Witteveen plate with its right half split into DKT
    triangles): mass 3.925 kg exactly and the first five free-free frequencies within 1.5 % of the
    all-quad plate's (both elements within 0.7 % of Leissa at 16 x 16, docs/shells.md)."""
    from ffrf_fmu.solid.shell_tri import split_quads

    nodes, quads = plate_mesh(1.0, 1.0, 20, 20)
    right = nodes[quads].mean(1)[:, 0] > 0.5
    mesh = tmp_path / "mixed.vtu"
    meshio.write(mesh, meshio.Mesh(nodes, [("quad", quads[~right]), ("triangle", split_quads(quads[right], "02"))]))
    text = (MODELS / "witteveen_plate.toml").read_text()
    head, rest = text.split("[body.mesh]\n", 1)
    rest = rest.split("\n\n", 1)[1]
    f = tmp_path / "mixed.toml"
    f.write_text(f'{head}[body.mesh]\nfile = "{mesh.name}"\nelement = "mitc4"\nthickness = 0.0005\n\n{rest}')
    (red,) = reduce_body(load_model(f).body).reductions
    (ref,) = reduce_body(load_model(MODELS / "witteveen_plate.toml").body).reductions
    assert red.data.mass == pytest.approx(3.925, rel=1e-12)
    assert red.data.frequencies_hz[:5] == pytest.approx(ref.data.frequencies_hz[:5], rel=0.015)
