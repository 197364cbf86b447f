"""`recover --png` (studies/render.py: the surface of a recovered solid, deformation scaled) and the advice
where the reference is the scene's own converged modes (studies/modal_advice.py)."""
import math

import numpy as np
import pytest

from ffrf_fmu.studies import render


def test_surface_faces_of_volume_and_shell_cells():
    """Two tetrahedra sharing a face: 8 faces, 6 on the surface. A box of 2 x 1 x 1 hexahedra: 12 faces,
    10 on the surface (the shared one is inside). Shell quads are the surface themselves; an unknown cell
    type is named in the error."""
    tets = ("tetra", np.array([[0, 1, 2, 3], [1, 2, 3, 4]]))
    assert len(render.surface_faces([tets])) == 6
    hexes = ("hexahedron27", np.array([[0, 1, 2, 3, 4, 5, 6, 7] + [0] * 19, [1, 8, 9, 2, 5, 10, 11, 6] + [0] * 19]))
    assert len(render.surface_faces([hexes])) == 10
    assert len(render.surface_faces([("quad", np.arange(8).reshape(2, 4))])) == 2
    with pytest.raises(ValueError, match="pyramid"):
        render.surface_faces([("pyramid", np.zeros((1, 5), int))])


def test_render_states_the_scale(tmp_path):
    """haug_solid (hex27 bar) at its first mode's amplitude: the PNG is written, the default scale draws the
    largest |u| as 5 % of the 8 m extent, and the largest |u| is the one of Y q."""
    from ffrf_fmu.model import load_model
    from ffrf_fmu.reduction import reduce_body

    m = load_model("models/haug_solid.toml")
    (red,) = reduce_body(m.body).reductions
    q = np.zeros(red.Y.shape[1])
    q[-red.data.frequencies_hz.size] = 1.0  # the first free-free mode, unit modal amplitude
    pic = render.render_state(red, q, tmp_path / "bar.png", t=0.5)
    u = render.elastic_displacements(red, q)
    assert pic.path.stat().st_size > 10_000
    assert pic.u_max == pytest.approx(np.linalg.norm(u, axis=1).max(), rel=1e-12)
    assert pic.scale * pic.u_max == pytest.approx(0.05 * 8.0, rel=1e-9)


def test_modal_advice_of_the_runup():
    """The Jeffcott run-up (a rotating unbalance: no full-order reference): modes per superelement = the
    free-free modes below 3 x the spin rate's 54.1 Hz (340 rad/s); step: the period error within the budget
    at the first kept mode, and at most 0.2 rad of spin per step (the run-up fails Newton at 0.29 rad with gyroscopic,
    0.31 with full W1 + W2, holds at 0.17, docs/inertia-terms.md), a step that divides the 10 s."""
    from ffrf_fmu.model import load_model
    from ffrf_fmu.studies import modal_advice as ma
    from ffrf_fmu.studies.calibration import RESERVE, STEP_ERROR_FACTOR
    from ffrf_fmu.studies.indicators import period_error

    m = load_model("models/jeffcott_runup.toml")
    sc = m.scene("runup")
    assert ma.needs_modal_reference(m, sc)
    a = ma.advise_modal(m, sc, 0.01, max_modes=10)
    f = np.sort(ma._frequencies(m, sc, 10))
    assert a.modes == max(2, int(np.sum(f < 3.0 * 340.0 / (2 * math.pi))))
    assert a.step * 340.0 <= ma.MAX_SPIN_PER_STEP
    assert abs(period_error(2 * math.pi * max(f[0], 340 / (2 * math.pi)) * a.step, sc.rho_inf)) * STEP_ERROR_FACTOR \
        <= RESERVE * 0.01
    assert abs(10.0 / a.step - round(10.0 / a.step)) < 1e-9


def test_modal_check_halves_the_reference_step_until_it_converges(monkeypatch):
    """check_modal's reference (a metric 1 + c h^2 + 0.1 / n^4 of the step h and the mode count n, no runs): the
    modes are refined until a cutoff moves it by < 0.1 x tolerance, then the step halved until a halving does (a
    halving moves it by 3 c h^2 / 4); the reference is the last run, the verdict none when MAX_HALVINGS halvings do
    not converge it."""
    from ffrf_fmu.studies import modal_advice as ma

    def fake(c):
        def run(model_path, scene_name, modes, terms, step, overrides=()):
            return ma.MetricRun(f"{modes}/{step}", modes, terms, step, 1.0 + c * step**2 + 0.1 / modes**4, 0.0, True)
        return run

    advice = ma.ModalAdvice("linear", 4, 0.1, 0.01)  # its run: 1.0054 against the reference 1.00034, 0.5 %
    monkeypatch.setattr(ma, "run_metric", fake(0.5))  # halvings move it by 3.75e-3, 9.4e-4 (< 1e-3): two halvings
    res = ma.check_modal("m.toml", "s", advice, [2, 4, 8, 16])
    assert [r.modes for r in res["modes_table"]] == [2, 4, 8]  # 2 -> 4 moves it by 5.9e-3, 4 -> 8 by 3.7e-4
    assert [r.step for r in res["step_table"]] == [0.05, 0.025]
    assert res["reference"].step == 0.025 and res["resolved"] and res["within_tolerance"]
    monkeypatch.setattr(ma, "run_metric", fake(50.0))  # each halving moves it by > 1e-3 up to h = 0.0125
    res = ma.check_modal("m.toml", "s", advice, [2, 4, 8])
    assert len(res["step_table"]) == ma.MAX_HALVINGS and not res["resolved"] and res["within_tolerance"] is None


def test_advise_refuses_a_scene_that_its_partners_move():
    """The crank drive's scene (models/conrod_crank.toml) is the conrod with its ports open to the partner FMUs:
    nothing in the model file moves it, so `advise` (which runs the model's scene) says so instead of advising
    `linear` for a body at rest (the drive needs W1: docs/inertia-terms.md, 2.3 % without it), and names the route
    that advises it in its system (`--system crank`, tests/test_crank_advice.py)."""
    from ffrf_fmu.checked_toml import ModelError
    from ffrf_fmu.model import load_model
    from ffrf_fmu.studies import modal_advice as ma

    m = load_model("models/conrod_crank.toml")
    with pytest.raises(ModelError, match="partners outside the model file.*--system crank"):
        ma.advise_modal(m, m.scene("crank"), 0.01)
