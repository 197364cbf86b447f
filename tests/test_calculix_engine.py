"""CalculiX as an FE engine (solid/calculix_engine.py): a deck's K and M assembled by ccx
(*FREQUENCY, SOLVER=MATRIXSTORAGE) against our scikit-fem assembly of the same mesh, a model file with
[body.export] format = "calculix", and the decks it refuses. Needs `ccx` (bash .ci/run installs it)."""
from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from conftest import end_face_port
from ffrf_fmu.model import load_model
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.solid.calculix_engine import CalculixError, run_ccx, solid_deck
from ffrf_fmu.solid.mesh import Material, assemble, box_points
from ffrf_fmu.solid.source import solid_fe

MODELS = Path(__file__).resolve().parents[1] / "models"


def free_frequencies(fe, n=10):
    w2 = spla.eigsh(fe.K.tocsc(), k=n + 6, M=fe.M.tocsc(), sigma=-1e3, return_eigenvectors=False)
    return np.sqrt(np.abs(np.sort(w2)))[6:] / (2 * np.pi)


def test_conrod_against_calculix_c3d10(tmp_path):
    """The bundled conrod's tet10 mesh as a ccx C3D10 deck: the same nodes and the first 10 elastic
    free-free frequencies within 2 % of ours. ccx integrates a C3D10 with 4 points (degree 2): not N_i N_j
    (degree 4) of the mass, nor the volume of the curved (isoparametric) tets on the bores (det J of
    degree 3), which our quadrature integrates exactly: measured 5.0e-4 apart in mass (bound 1e-3) and
    1.06 % in frequency at most, ccx below."""
    m = load_model(MODELS / "conrod.toml")
    ours = solid_fe(m.body.solid)
    mesh = meshio.read(dict(m.body.solid.files)["mesh"])
    deck = tmp_path / "conrod.inp"
    deck.write_text(solid_deck(mesh.points, [(c.type, c.data) for c in mesh.cells if c.type == "tetra10"],
                               m.body.solid.material))
    ccx = run_ccx(deck)
    assert ccx.n_nodes == ours.n_nodes
    assert ccx.M_scalar.sum() == pytest.approx(ours.M_scalar.sum(), rel=1e-3)
    f_ccx, f_ours = free_frequencies(ccx), free_frequencies(ours)
    assert f_ccx == pytest.approx(f_ours, rel=0.02)


def test_calculix_export_in_a_model_file(tmp_path):
    """[body.export] format = "calculix": a hex8 bar (C3D8, 2 x 2 x 2 Gauss points, exact for K and M of
    a box's trilinear elements, as ours) reduced on two end frames: its free-free frequencies are those
    of our hex8 assembly of the same mesh (1e-6: the same integrals, summed in another order; the reduced
    modes are exact eigenvectors) and the mass is rho V."""
    mat = Material(2.1e11, 0.3, 7850.0)
    mesh = box_points((1.0, 0.1, 0.1), (10, 1, 1))
    ours = assemble(mesh, mat, "hex8")
    points = ours.coords
    cells = [(t, c) for t, c in ours.cells if t == "hexahedron"]
    (tmp_path / "bar.inp").write_text(solid_deck(points, cells, (mat.E, mat.nu, mat.rho)))
    (tmp_path / "bar.toml").write_text(f'''
[body]
name = "bar"
kind = "solid"
modes = 4

[body.export]
format = "calculix"
inp = "bar.inp"
units = "SI: m, kg, N (written so)"

{end_face_port("a", 0.0, link="averaging", point=[0.0, 0.05, 0.05])}

{end_face_port("b", 1.0, link="averaging", point=[1.0, 0.05, 0.05])}

[scenes.free]
duration = 0.01
step = 1e-3
''')
    (red,) = reduce_body(load_model(tmp_path / "bar.toml").body).reductions
    assert red.data.mass == pytest.approx(7850.0 * 0.01, rel=1e-9)
    assert red.data.frequencies_hz == pytest.approx(free_frequencies(ours, 4), rel=1e-6)


@pytest.mark.parametrize("extra, why", [
    ("*BOUNDARY\n1,1,3\n", r"bad.inp:\d+: \*BOUNDARY"),
    ("*ELEMENT,TYPE=S8R,ELSET=SHELLS\n99,1,2,3,4,5,6,7,8\n", r"bad.inp:\d+: \*ELEMENT type S8R"),
])
def test_refused_decks_name_file_and_line(tmp_path, extra, why):
    mesh = box_points((1.0, 0.1, 0.1), (2, 1, 1))
    fe = assemble(mesh, Material(2.1e11, 0.3, 7850.0), "hex8")
    deck = tmp_path / "bad.inp"
    deck.write_text(solid_deck(fe.coords, [(t, c) for t, c in fe.cells if t == "hexahedron"],
                               (2.1e11, 0.3, 7850.0)) + extra)
    with pytest.raises(CalculixError, match=why):
        run_ccx(deck)
