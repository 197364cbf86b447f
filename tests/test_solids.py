"""Solid bodies (docs/solids.md): scikit-fem assembly, partners' FE exports, interface frames and the
sparse reduction (reduction_sparse.py) to one superelement the runtime takes unchanged."""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from conftest import end_face_port, toml_table
from ffrf_fmu.fe.beam import beam_model
from ffrf_fmu.model import ModelError, Section, load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.invariants import solid_invariants
from ffrf_fmu.reduction_sparse import reduce_solid
from ffrf_fmu.solid import node_block_mass
from ffrf_fmu.solid.exports import read_abaqus, read_ansys, rigid_residual
from ffrf_fmu.solid.frames import Frame, select_nodes
from ffrf_fmu.solid.mesh import Material, assemble, box_points

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
DATA = f"{MODELS}/data/"
STEEL = Material(2e11, 0.3, 7800.0)


def free_free_hz(K, M, k):
    """The k lowest elastic free-free frequencies [Hz] of sparse K, M (6 rigid modes dropped)."""
    sigma = -(2 * np.pi * 50.0) ** 2  # below every elastic mode here (>= 400 Hz): well-conditioned shift-invert
    w2 = np.sort(spla.eigsh(sp.csr_matrix(K), k=6 + k, M=sp.csr_matrix(M), sigma=sigma, which="LM", tol=1e-12)[0])
    return np.sqrt(w2[6:]) / (2 * np.pi)


def end_frames(fe, L, link):
    out = []
    for name, x in (("a", 0.0), ("b", L)):
        idx = select_nodes(fe.coords, {}, {"plane": {"point": [x, 0, 0], "normal": [1, 0, 0]}}, L)
        out.append(Frame(name, idx, link, np.array([x, 0.0, 0.0])))
    return out


def abaqus(name):
    return read_abaqus(f"{DATA}{name}.inp", f"{DATA}{name}_STIF1.mtx" if "/" in name else f"{DATA}{name}STIF1.mtx",
                       f"{DATA}{name}_MASS1.mtx" if "/" in name else f"{DATA}{name}MASS1.mtx")


def ansys_rotor():
    return read_ansys(DATA + "rotorAnsysStiffnessMatrixSparse.txt", DATA + "rotorAnsysMassMatrixSparse.txt",
                      DATA + "rotorAnsysMatrixDofMappingVector.txt", DATA + "rotorAnsysNodalCoordinates.txt",
                      DATA + "rotorAnsysElements.txt")


@pytest.mark.parametrize("element", ["hex8", "hex27", "tet10"])
def test_box_rigid_properties_are_analytic(element):
    """Mass, CM and inertia of a generated box (about its CM) from the reduced superelement against
    m = rho a b c, the centre, m (b^2 + c^2) / 12 ...: the consistent mass integrates rigid fields exactly,
    so the agreement is round-off (1e-12)."""
    a, b, c, o = 0.6, 0.2, 0.1, np.array([0.3, -0.1, 0.05])
    mesh = box_points((a, b, c), (3, 2, 1), o)
    if element.startswith("tet"):
        from skfem import MeshTet
        from skfem.io.meshio import to_meshio

        mesh = to_meshio(MeshTet.init_tensor(*(np.linspace(oi, oi + s, 3) for oi, s in zip(o, (a, b, c)))))
    fe = assemble(mesh, STEEL, element)
    red = reduce_solid(fe, [Frame(n, select_nodes(fe.coords, {}, {"plane": {"point": list(o + [x, 0, 0]), "normal": [1, 0, 0]}}, a),
                              "rigid", o + [x, b / 2, c / 2]) for n, x in (("a", 0.0), ("b", a))], n_modes=2)
    m = 7800.0 * a * b * c
    d = red.data
    assert d.mass == pytest.approx(m, rel=1e-12)
    assert np.allclose(d.x_cm, o + [a / 2, b / 2, c / 2], rtol=0, atol=1e-12)
    J = m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    assert np.allclose(d.J0, J, rtol=0, atol=1e-12 * np.abs(J).max())
    assert red.orthogonality_error < 1e-12  # eq. (74)


def test_solid_bar_converges_to_the_timoshenko_beam():
    """Free-free bending frequencies of a steel bar (1 m, 0.1 m square) as hex27 solids of growing mesh
    against fe/'s Timoshenko beam (200 elements: converged; shear coefficient 10(1+nu)/(12+11nu) of a
    square): the error falls with the mesh (measured 1.5 %, 0.33 %, 0.056 % on the first pair, docs/solids.md)
    and hex8 locks (35 % on its coarsest mesh)."""
    E, nu, rho, L, a = 2e11, 0.3, 7800.0, 1.0, 0.1
    G, A, I = E / (2 * (1 + nu)), a * a, a**4 / 12
    kap = 10 * (1 + nu) / (12 + 11 * nu)
    sec = Section(EA=E * A, GJ=G * 0.1406 * a**4, EI2=E * I, EI3=E * I, m=rho * A, m22=rho * I, m33=rho * I,
                  GA2=kap * G * A, GA3=kap * G * A)
    fb = beam_model(sec, [0, 0, 0], [1, 0, 0], L, 200)
    beam = free_free_hz(fb.K, fb.M, 2)[0]
    errors = []
    for div in ((4, 1, 1), (8, 1, 1), (16, 2, 2)):
        fe = assemble(box_points((L, a, a), div), STEEL, "hex27")
        errors.append(free_free_hz(fe.K, fe.M, 2)[0] / beam - 1)
    assert errors[0] > errors[1] > errors[2] > 0  # from above (Rayleigh-Ritz), monotone
    assert errors[2] < 1e-3
    hex8 = assemble(box_points((L, a, a), (8, 1, 1)), STEEL, "hex8")
    assert free_free_hz(hex8.K, hex8.M, 2)[0] / beam - 1 > 0.3  # locking: why docs/solids.md advises quadratic


def test_averaging_frames_leave_the_free_free_modes_rigid_frames_stiffen():
    """RBE3 adds no constraint: the reduced body's free-free frequencies equal the mesh's; RBE2 makes the end
    faces rigid: higher frequencies (a constraint: interlacing), well above the 1e-8 the RBE3 match holds. Kept modes are exact eigenvectors."""
    fe = assemble(box_points((1.0, 0.1, 0.1), (8, 1, 1)), STEEL, "hex27")
    mesh = free_free_hz(fe.K, fe.M, 4)
    avg = reduce_solid(fe, end_frames(fe, 1.0, "averaging"), n_modes=4).data.frequencies_hz
    rig = reduce_solid(fe, end_frames(fe, 1.0, "rigid"), n_modes=4).data.frequencies_hz
    assert np.allclose(avg, mesh, rtol=1e-8)
    assert np.all(rig / mesh - 1 > 1e-7)  # measured 1.2e-6 and 6.5e-6 (faces of a slender bar stay nearly plane)


def test_cutoff_keeps_every_mode_below_it():
    fe = assemble(box_points((1.0, 0.1, 0.1), (8, 1, 1)), STEEL, "hex27")
    mesh = free_free_hz(fe.K, fe.M, 12)
    red = reduce_solid(fe, end_frames(fe, 1.0, "averaging"), cutoff_hz=2000.0)
    assert np.allclose(red.data.frequencies_hz, mesh[mesh <= 2000.0], rtol=1e-8)


def test_block_exports_c3d8_against_c3d10():
    """The Abaqus block (4 x 1 x 1 m, rho 2900) in C3D8 and C3D10: the same mass (11600 kg), CM and inertia;
    C3D8's mass is lumped (diagonal), C3D10's consistent. Their first bending pair differs by 2.8 %
    (438.8 against 451.3 Hz): the hex27 solid of the same block converges to 448.5 Hz (16 x 4 x 4), C3D10
    is 0.6 % above it (a coarse quadratic mesh, from above) and C3D8 2.2 % below (lumped mass lowers)."""
    h8, t10 = abaqus("abaqus/blockC3D8"), abaqus("abaqus/blockC3D10")
    for fe in (h8, t10):
        assert fe.M.sum() / 3 == pytest.approx(11600.0, rel=1e-12)
        assert rigid_residual(fe.coords, fe.K) < 1e-12
    assert h8.M.nnz == h8.n_dof and t10.M.nnz > 3 * t10.n_dof  # lumped vs consistent
    f8, f10 = free_free_hz(h8.K, h8.M, 2), free_free_hz(t10.K, t10.M, 2)
    ref = 448.5  # hex27 16 x 4 x 4 of the same block (docs/solids.md)
    assert f10[0] / ref - 1 == pytest.approx(0.0063, abs=0.002)
    assert f8[0] / ref - 1 == pytest.approx(-0.0217, abs=0.002)
    r8 = reduce_solid(h8, end_frames(h8, 4.0, "averaging"), n_modes=2).data
    r10 = reduce_solid(t10, end_frames(t10, 4.0, "averaging"), n_modes=2).data
    assert np.allclose(r8.x_cm, [2.0, 0.5, 0.5], atol=1e-12) and np.allclose(r10.x_cm, r8.x_cm, atol=1e-12)
    J = 11600 / 12 * np.diag([2.0, 17.0, 17.0])
    # C3D10 (consistent) integrates X X^T exactly; C3D8's lumped nodal masses are the trapezoid rule on its
    # 10 x 3 x 3 grid: per axis the variance L^2/12 + h^2/6 (h = 0.4, 1/3, 1/3 m), 22 % more about X
    assert np.allclose(r10.J0, J, rtol=1e-9)
    var = np.array([16 / 12 + 0.4**2 / 6, 1 / 12 + 1 / 54, 1 / 12 + 1 / 54])
    assert np.allclose(r8.J0, 11600 * np.diag([var[1] + var[2], var[0] + var[2], var[0] + var[1]]), rtol=1e-9)


def test_rotor_exports_are_the_same_mesh_and_mass_and_stiffness_over_100():
    """The Abaqus and the Ansys rotor: the same nodes (1.2e-8 m), the same mass node for node (77.966 kg,
    1e-7: printed digits), and the Ansys stiffness is the Abaqus one / 100 node for node (1.3e-7): E = 2.1e9
    where the Abaqus deck says 2.1e11. The matrices are compared, never altered. The Abaqus mass is the deck's
    density x the volume of its mesh (SI units)."""
    ab, an = abaqus("rotorDiscTest"), ansys_rotor()
    from scipy.spatial import cKDTree

    dist, idx = cKDTree(an.coords).query(ab.coords)
    assert dist.max() < 1e-7
    P = (3 * idx[:, None] + np.arange(3)).ravel()
    assert abs(an.M[P][:, P] - ab.M).max() < 1e-6 * abs(ab.M).max()
    assert abs(100.0 * an.K[P][:, P] - ab.K).max() < 1e-6 * abs(ab.K).max()
    import meshio

    mesh = meshio.read(DATA + "rotorDiscTest.inp")
    volume = assemble(mesh, Material(1.0, 0.3, 1.0), "hex8").M_scalar.sum()
    from ffrf_fmu.solid.exports import abaqus_material

    assert abaqus_material(DATA + "rotorDiscTest.inp") == {"density": 7850.0, "E": 2.1e11, "nu": 0.3}
    assert ab.M.sum() / 3 == pytest.approx(7850.0 * volume, rel=1e-6)
    assert an.M.sum() / 3 == pytest.approx(ab.M.sum() / 3, rel=1e-7)


def test_rotor_models_frequencies_differ_by_ten():
    """The bundled rotor models reduce (bearing frames on the seats) and their frequencies differ by exactly
    sqrt(100) (the stiffness factor), mass and inertia agree."""
    a = reduce_body(load_model(MODELS / "rotor_abaqus.toml").body).data.superelements[0]
    b = reduce_body(load_model(MODELS / "rotor_ansys.toml").body).data.superelements[0]
    assert a.mass == pytest.approx(b.mass, rel=1e-7)
    assert np.allclose(a.J0, b.J0, rtol=1e-6, atol=1e-9)
    assert np.allclose(a.frequencies_hz, 10.0 * b.frequencies_hz, rtol=1e-5)


def test_node_block_mass_is_checked():
    M = sp.kron(sp.identity(2), sp.diags([1.0, 1.0, 2.0]), format="csr")
    with pytest.raises(ValueError, match="not of node-block form"):
        node_block_mass(M)


def test_solid_invariants_match_the_reduced_data():
    """Witteveen's invariants of a solid from the sparse node mass: I0 = J0, G_k of the pseudo-modes
    skew, W1 symmetric, and the kept vibration modes free (C0 = 0 to round-off)."""
    fe = assemble(box_points((1.0, 0.1, 0.1), (8, 1, 1)), STEEL, "hex27")
    red = reduce_solid(fe, end_frames(fe, 1.0, "rigid"), n_modes=4, inertia=True)
    inv = solid_invariants(red)
    assert np.allclose(inv.I0, red.data.J0)
    assert np.abs(inv.C0).max() < 1e-10 * np.sqrt(np.abs(inv.I0).max())
    assert np.allclose(inv.W1, inv.W1.transpose(0, 2, 1))
    assert np.allclose(inv.omega[:4] / (2 * np.pi), red.data.frequencies_hz, rtol=1e-8)


def write(tmp_path, text):
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def solid(extra: str, sel: str, scene: str) -> str:
    """A model file of a STEEL hex27 bar with the body keys `extra`, ports a (the end face x = 0) and b
    (nodes `sel`), and the scene keys `scene`."""
    return f"""
[body]
kind = "solid"
{extra}
[body.mesh]
box = {{ size = [1.0, 0.1, 0.1], divisions = [4, 1, 1] }}
element = "hex27"
{toml_table("body.material", E=STEEL.E, nu=STEEL.nu, rho=STEEL.rho)}
{end_face_port("a", 0.0)}
[body.ports.b]
select = {sel}
[scenes.s]
duration = 0.1
step = 0.01
{scene}
"""


def test_solid_model_errors(tmp_path):
    ok = dict(extra="modes = 2", sel="{ plane = { point = [1, 0, 0], normal = [1, 0, 0] } }", scene="")
    load_model(write(tmp_path, solid(**ok)))
    with pytest.raises(ModelError, match="a solid is one superelement"):
        load_model(write(tmp_path, solid(**{**ok, "extra": "modes = 2\nsuperelements = 2"})))
    with pytest.raises(ModelError, match="one of modes = N or cutoff_hz"):
        load_model(write(tmp_path, solid(**{**ok, "extra": ""})))
    one_node = "{ near = { point = [1, 0, 0], radius = 0.001 } }"
    m = load_model(write(tmp_path, solid(**{**ok, "sel": one_node})))
    with pytest.raises(ValueError, match="does not fix a frame's rotation"):
        reduce_body(m.body)
    m = load_model(write(tmp_path, solid(**{**ok, "sel": "{ set = 'nothere' }"})))
    with pytest.raises(ValueError, match="no node set 'nothere'"):
        reduce_body(m.body)
    m = load_model(write(tmp_path, solid(**{**ok, "scene": "stiffening = true"})))
    from ffrf_fmu.reduction import reduce_scene_body

    assert reduce_scene_body(m.body, m.scenes[0]).data.superelements[0].stiffening  # a mesh: from its stresses


def test_haug_solid_b1_within_one_percent_of_the_beam():
    """B1 as a hex27 solid bar (same L, m, EI, EA; models/haug_solid.toml) against haug_beam.toml with
    1 superelement, stiffening off, the same scene: the peak tip deflection within 1 % (measured -0.38 %;
    the solid's first cantilever frequency is 0.24 % above the beam's)."""
    from ffrf_fmu.simulate import run_scene

    short = ["duration=10"]  # the peak is at t = 8.1 s in both (spin-up to 15 s)
    s = run_scene(load_model(MODELS / "haug_solid.toml", short), "spinup").summary["metrics"]["tip_deflection_max_m"]
    b = run_scene(load_model(MODELS / "haug_beam.toml", ["superelements=1"] + short), "spinup").summary["metrics"][
        "tip_deflection_max_m"]
    assert s == pytest.approx(b, rel=0.01)


@pytest.mark.parametrize("model, overrides", [
    (MODELS / "haug_solid.toml", ["duration=2", "step=0.01"]),
    (MODELS / "rotor_abaqus.toml", ["duration=0.02", "step=2e-4"]),
    (MODELS / "rotor_ansys.toml", ["duration=0.02", "step=2e-4"]),
])
def test_solid_fmu_equals_its_standalone_run(tmp_path, model, overrides):
    """Each bundled solid as an FMU (what `ffrf-fmu build` writes) under fmpy against its standalone run
    (`ffrf-fmu validate`), a shortened scene: the reduced solid is body data like a beam's, so the FMU
    reproduces the standalone run within validate's default tolerances and matches the model."""
    from ffrf_fmu.fmu.builder import build_fmu
    from ffrf_fmu.validate import validate

    fmu = build_fmu(model, tmp_path / "solid.fmu", scene="spinup", overrides=overrides)
    rep = validate(fmu, model=model, scene="spinup", overrides=overrides, plots=False)
    assert rep["fmu_reached_stop_time"] and rep["fmu_matches_model"] and rep["passed"]


def test_quality_report_kept_modes_exact_and_effective_mass():
    """The kept free-free modes are exact eigenvectors of the full model: frequency error at round-off and
    MAC 1 (1e-8); the next ones are approximations (error > 0, from above). Effective mass fractions clamped at
    a port lie in [0, 1] and grow with the modes admitted (cutoff)."""
    from ffrf_fmu.reduction_quality import effective_mass, frequency_report, quality_report

    (red,) = reduce_body(load_model(MODELS / "haug_solid.toml").body).reductions
    rows = frequency_report(red, 30.0)
    kept = [r for r in rows if r["kept"]]
    assert len(kept) == 6 and all(abs(r["error"]) < 1e-7 and r["mac"] > 1 - 1e-8 for r in kept)
    assert all(r["error"] > 1e-3 for r in rows if not r["kept"])  # measured +8.3 % on the 4th bending pair
    few, all_ = effective_mass(red, 10.0), effective_mass(red)
    for port in ("hub", "tip"):
        assert all(0.0 <= a <= b <= 1.0 + 1e-12 for a, b in zip(few[port], all_[port]))
    assert all_["hub"][1] > 0.9  # transverse: the bending shapes carry > 90 % (measured 0.945)
    # the full FE model's effective mass beside the reduced body's (what `info` prints): the same rigid totals,
    # and at 30 Hz the reduced bending fraction within 1 % of the full model's (measured 0.925 against 0.918)
    rep = quality_report(red, 30.0)
    for port in ("hub", "tip"):
        full = rep["full_effective_mass"][port]
        assert full["rigid"][:3] == pytest.approx([red.data.mass] * 3, rel=1e-12)
        assert all(0.0 <= f <= 1.0 for f in full["fraction"])
        assert rep["effective_mass_fraction"][port][1] == pytest.approx(full["fraction"][1], abs=0.01)


def test_recovered_mesh_follows_the_port_frames(tmp_path):
    """Result recovery (simulate/recovery.py): the nodes of a rigid set, recovered as x0 + R0 (X - x_cm + Y q),
    sit where the run's port frame carries them, x_f + R_f (X - X_f), up to the second-order term of the
    frame's elastic rotation alpha (the superelement's kinematics u = Y q are linear, the frames' rotations
    exact): |alpha|^2 r / 2 with r the set's radius (measured 2.8e-8 m against |alpha|^2 r / 2 = 4.0e-8 m
    at alpha = 1.76e-3). At t = 0 the mesh is the reference. Modal CSV and VTK (read back with meshio) are written."""
    import meshio

    from ffrf_fmu.simulate.recovery import deformed_positions, run_recorded, write_modal_csv, write_vtk

    rec, red, data = run_recorded(load_model(MODELS / "haug_solid.toml", ["duration=1", "step=0.01"]), every=25)
    assert np.allclose(deformed_positions(red, rec.x0[0], rec.R0[0], rec.q[0]), red.fe.coords, atol=1e-12)
    hub = red.frames[0]
    x = deformed_positions(red, rec.x0[-1], rec.R0[-1], rec.q[-1])[hub.nodes]
    carried = rec.xN[-1, 0] + (red.fe.coords[hub.nodes] - hub.point) @ rec.RN[-1, 0].T
    alpha = np.linalg.norm(rec.q[-1][3:6])  # the hub frame's elastic rotation relative to the CM frame
    r = np.linalg.norm(red.fe.coords[hub.nodes] - hub.point, axis=1).max()
    assert np.abs(x - carried).max() <= 1.2 * alpha**2 * r / 2 + 1e-12
    assert np.abs(rec.q[-1]).max() > 0  # the spin-up deforms it
    write_modal_csv(rec, red, tmp_path / "modal.csv")
    assert np.loadtxt(tmp_path / "modal.csv", delimiter=",", skiprows=1).shape == (len(rec.t), 1 + red.data.n)
    write_vtk(rec, red, tmp_path, "bar")
    m = meshio.read(tmp_path / f"bar_{len(rec.t) - 1:05d}.vtu")
    full = deformed_positions(red, rec.x0[-1], rec.R0[-1], rec.q[-1])
    assert m.cells[0].type == "hexahedron" and np.allclose(m.points, full[: len(m.points)], rtol=0, atol=1e-12)


def test_generated_cylinder_volume_converges():
    """The generated cylinder (elliptical grid mapping, straight-sided cells): its volume approaches pi r^2 L
    from below as the polygonal section refines, -2.6 %, -0.66 %, -0.17 % for 2, 4, 8 cells per radius
    (the chord error, x 1/4 per halving)."""
    from ffrf_fmu.solid.mesh import cylinder_points

    errors = [assemble(cylinder_points(0.1, 1.0, r, 2), Material(1.0, 0.3, 1.0), "hex8").M_scalar.sum()
              / (np.pi * 0.01) - 1 for r in (2, 4, 8)]
    assert errors[0] < errors[1] < errors[2] < 0
    assert errors[1] / errors[0] == pytest.approx(0.25, abs=0.03) and errors[2] / errors[1] == pytest.approx(0.25, abs=0.03)


def test_mesh_file_with_a_named_set(tmp_path):
    """A mesh file read with meshio (an Abaqus .inp written here with a point set) as a model's solid: the
    named set selects the end face, to which hex20's face and edge mid nodes are added (corners 6 -> 13
    nodes); the body's mass is rho x volume."""
    import meshio

    m = box_points((1.0, 0.2, 0.1), (4, 2, 1))
    m.point_sets = {"end": np.flatnonzero(np.isclose(m.points[:, 0], 1.0))}
    meshio.write(tmp_path / "bar.inp", m)
    (tmp_path / "bar.toml").write_text(solid(extra="modes = 2", sel="{ set = 'end' }", scene="").replace(
        'box = { size = [1.0, 0.1, 0.1], divisions = [4, 1, 1] }\nelement = "hex27"', 'file = "bar.inp"\nelement = "hex20"'))
    (red,) = reduce_body(load_model(tmp_path / "bar.toml").body).reductions
    assert red.frames[1].nodes.size == 13
    assert np.allclose(red.fe.coords[red.frames[1].nodes, 0], 1.0)
    assert red.data.mass == pytest.approx(7800 * 0.02, rel=1e-12)


def test_nested_dissection_reduction_equals_the_minimum_degree_one(monkeypatch):
    """The LU's ordering (solid/ordering.py) changes the cost, not the result: a 15,795-dof hex27 bar with a
    rigid and an averaging end frame reduced with nested dissection and with SuperLU's MMD_AT_PLUS_A (the
    ordering used before) gives the same kept frequencies and the same reduced eigenvalues to the solvers'
    tolerance (ARPACK tol 1e-10, static solves 1e-10; measured 3e-13 on the frequencies, 1e-14 relative on
    the reduced eigenvalues). At this size both orderings fill alike (1.00e7 and 0.99e7 entries); the gain is
    at scale (docs/solids.md, "Scale")."""
    import ffrf_fmu.reduction_sparse as rs
    from ffrf_fmu.solid.ordering import factor

    fe = assemble(box_points((4.0, 0.5, 0.5), (32, 4, 4)), STEEL, "hex27")
    frames = end_frames(fe, 4.0, "averaging")
    frames[0] = Frame("a", frames[0].nodes, "rigid", frames[0].point)

    def reduce_with(ordering):
        def lu(K, M, sigma, c, coords):
            return factor(K - sigma * M, c.dof_node, coords, ordering)

        monkeypatch.setattr(rs, "shifted_lu", lu)
        red = rs.reduce_solid(fe, frames, n_modes=8)
        return red.data.frequencies_hz, np.sort(sla.eigh(red.data.K, red.data.M, eigvals_only=True))

    f_nd, w2_nd = reduce_with("nested_dissection")
    f_md, w2_md = reduce_with("MMD_AT_PLUS_A")
    assert fe.n_dof == 15795
    assert np.allclose(f_nd, f_md, rtol=1e-10, atol=0)
    assert np.allclose(w2_nd, w2_md, rtol=1e-10, atol=1e-12 * w2_md.max())


@pytest.mark.parametrize("port", [0, 1])
def test_full_model_effective_masses_sum_to_the_rigid_mass_about_the_port(port):
    """Effective mass at a port (reduction_quality.py): a 1 x 0.1 x 0.1 m hex27 bar (222 dofs in z), port a rigid,
    port b averaging, clamped at one port. Over ALL clamped modes (dense) the effective masses plus what the
    clamped port carries itself, e_d^T (L M^-1 L^T)^-1 e_d, are the mass (x, y, z) and the inertia about the
    frame (rx, ry, rz) to round-off (measured 1.3e-12); those equal the box's analytic values (m = 7.8 kg,
    I about the frame point by the parallel-axis rule). The port's own share shrinks when the mesh is
    refined (measured 2.9 % -> 1.5 % of the mass at the rigid port a, 0.58 % -> 0.40 % at the averaging port b,
    from 4 to 8 elements along the bar): the sum tends to the rigid mass. The sparse computation (ARPACK on the free model's LU with the bordered solve) gives
    the dense partial sums up to a cutoff between two clamped frequencies (not inside a bending pair)."""
    import math

    from ffrf_fmu.reduction_quality import full_effective_mass, full_model, port_motion

    shares = []
    for div in ((4, 1, 1), (8, 2, 2)):
        fe = assemble(box_points((1.0, 0.1, 0.1), div), STEEL, "hex27")
        frames = [Frame(name, select_nodes(fe.coords, {}, {"plane": {"point": [x, 0, 0], "normal": [1, 0, 0]}}, 1.0),
                        link, np.array([x, 0.05, 0.05])) for name, x, link in (("a", 0.0, "rigid"), ("b", 1.0, "averaging"))]
        full = full_model(fe, frames)
        K, M = full.K.toarray(), full.M.toarray()
        L = full.c.L[6 * port : 6 * port + 6].toarray()
        N = sla.null_space(L)  # the clamped model: L z = 0
        w2, V = sla.eigh(N.T @ K @ N, N.T @ M @ N)
        Z = port_motion(full.c, port)
        gamma2 = (V.T @ (N.T @ (M @ Z))) ** 2  # (modes, 6)
        rigid = np.einsum("ij,ij->j", Z, M @ Z)
        share = np.diag(np.linalg.inv(L @ np.linalg.solve(M, L.T)))
        assert np.allclose(gamma2.sum(0) + share, rigid, rtol=1e-11, atol=0)
        shares.append(share[0] / rigid[0])
        if div == (4, 1, 1):
            m = 7800 * 1.0 * 0.1 * 0.1
            d = np.array([0.5, 0.0, 0.0]) - frames[port].point + np.array([0.0, 0.05, 0.05])  # CM from the frame
            J = m / 12 * np.diag([0.02, 1.01, 1.01]) + m * (d @ d * np.eye(3) - np.outer(d, d))
            assert np.allclose(rigid, [m, m, m, *np.diag(J)], rtol=1e-12)
            f = np.sqrt(w2) / (2 * np.pi)
            assert f[9] / f[8] > 1.1  # the cutoff falls between two clamped modes
            cut = math.sqrt(f[8] * f[9])
            red = reduce_solid(fe, frames, n_modes=4)
            sparse = full_effective_mass(red, cut, full)[frames[port].name]
            assert np.allclose(sparse["fraction"], gamma2[:9].sum(0) / rigid, rtol=1e-9, atol=0)
            assert np.allclose(sparse["rigid"], rigid, rtol=1e-12)
    assert shares[1] < 0.8 * shares[0]  # halving the elements: x 0.51 (port a), x 0.69 (port b)
