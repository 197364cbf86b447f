"""The body's assembled residual and Jacobian, as BodySystem evaluates them on both backends (`_local`:
the C runtime's `ffrf_body_residual`, and the numpy path's assembly over the oracle, runtime/assembly.py),
against the oracle's own assembly from the reduced data (runtime/equations.py body_residual_and_jacobian),
at states reached by B1, B2 and B4.

The C runtime evaluates the same equations in another order, so it agrees to round-off: we allow 1e-12 of
each row's largest entry (measured: ~1e-15). A missing or wrong term, or a row assembled into the wrong
place, shows up as an O(1) relative difference in its rows.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ffrf_fmu import simulate as sim
from ffrf_fmu.model import load_model
from ffrf_fmu.model import scene_body
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime import equations
from ffrf_fmu.runtime.body import BodySystem

SCENES = {  # (model, scene, overrides): a few steps into each benchmark, where everything moves
    "B1": ("models/haug_beam.toml", "spinup", ["superelements=2", "step=0.01"], 2.0),
    "B2": ("models/spherical_beam.toml", "torque_then_tip", ["step=0.01"], 1.0),
    "B4": ("models/free_beam.toml", "tumble", ["step=0.01"], 0.3),
}


def _state(name: str, terms: str) -> BodySystem:
    path, scene_name, overrides, t_end = SCENES[name]
    model = load_model(path, overrides + [f"terms={terms}"])
    scene = model.scene(scene_name)
    body = reduce_body(scene_body(model.body, scene)).data
    system, inputs = sim.build_system(body, scene, model.body.origin)
    while system.t < t_end - 1e-9:
        system.step(scene.step, inputs)
    return system


def _row_relative(a: np.ndarray, b: np.ndarray) -> float:
    scale = np.abs(b).max(axis=-1, keepdims=True)
    return float((np.abs(a - b) / np.where(scale > 0, scale, 1.0)).max())


def _both(s: BodySystem, backend: str):
    """(F, F_ydot, F_y) of the body on `backend` and of the oracle at the state's configuration and rates
    moved off the solution (at the solution F is round-off of the cancelling terms, not a measure of them)."""
    yd = s.yd + np.random.default_rng(0).normal(size=s.yd.shape) * (0.1 + np.abs(s.yd))
    b = BodySystem(s.data, terms=s.terms, rho_inf=s.rho_inf, gravity=s.gravity, backend=backend)
    assert b.backend == backend
    ours = b._local(s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd, True)
    plain = equations.body_residual_and_jacobian(s.data, s.layout, s.terms, s.gravity, s.xN, s.RN, s.x0, s.R0, s.eta, s.v, yd)
    return ours, plain


@pytest.mark.parametrize("backend", ["native", "numpy"])
@pytest.mark.parametrize("terms", ["linear", "gyroscopic"])
@pytest.mark.parametrize("name", ["B1", "B2", "B4"])
def test_body_equations_match_the_plain_oracle(name, terms, backend):
    s = _state(name, terms)
    (F, Fz, Fy), (F0, Fz0, Fy0) = _both(s, backend)
    # the residual sums terms far larger than itself (K_bar q_bar against inertia): round-off is relative to them
    terms = max(np.abs(F0).max(), np.abs(s.K).max() * np.abs(s.elastic_coordinates()).max())
    assert np.abs(F - F0).max() <= 1e-12 * terms
    assert _row_relative(Fz, Fz0) <= 1e-12
    assert _row_relative(Fy, Fy0) <= 1e-12
    assert np.abs(Fy0).max() > 0 and np.abs(F0).max() > 0  # a real state, not the rest state


def test_term_hooks_add_an_elastic_force():
    """A term added through the oracle's hooks (an extra stiffness g = K_x q_bar, with dg_y = K_x Dq) gives
    the same residual and Jacobian as a superelement whose K_bar already contains K_x: the hooks' projection
    on the CM and node rows (91) and their Jacobian columns are right. K_x = 0.1 K_bar keeps the state
    meaningful."""
    s = _state("B1", "gyroscopic")
    e, sd = 0, s.data.superelements[0]
    cfg, vel = s.layout.cfg_map[e], s.layout.vel_map[e]
    local = (s.x0[e], s.R0[e], s.eta[e], s.xN[sd.nodes], s.RN[sd.nodes], s.v[e], s.yd[cfg], s.yd[vel])

    def plain_term(se, kin, v, zdot, vdot):
        dg_y = np.zeros((len(kin.q), len(zdot) + len(v)))
        dg_y[:, : len(zdot)] = 0.1 * se.K @ kin.Dq
        return 0.1 * se.K @ kin.q, np.zeros_like(dg_y), dg_y

    se = equations.Superelement(sd.K, sd.M, sd.G, sd.mass, sd.J0, sd.X_B)
    hooked = equations.residual_and_jacobian(se, "gyroscopic", s.gravity, *local, g_terms=(plain_term,))
    direct = equations.residual_and_jacobian(dataclasses.replace(se, K=1.1 * sd.K), "gyroscopic", s.gravity, *local)
    for a, b in zip(hooked, direct):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()


@pytest.mark.parametrize("name", ["B1", "B4"])
def test_elastic_rates_are_the_oracles(name):
    """BodySystem.elastic_rates (q_bar_dot of eq. 91, stacked: the rigid field's r_bar at initialization, the
    damping's power) against the oracle's `kinematics`, superelement by superelement: round-off (1e-12 of
    the largest rate). A sign or a transpose wrong in one of its two rows is an O(1) difference."""
    s = _state(name, "gyroscopic")
    s.yd = s.yd + np.random.default_rng(1).normal(size=s.yd.shape)
    qd = s.elastic_rates()
    for e, sd in enumerate(s.data.superelements):
        se = equations.Superelement(sd.K, sd.M, sd.G, sd.mass, sd.J0, sd.X_B)
        kin = equations.kinematics(se, s.x0[e], s.R0[e], s.eta[e], s.xN[sd.nodes], s.RN[sd.nodes], s.yd[s.layout.cfg_map[e]])
        assert np.abs(qd[e] - kin.qdot).max() <= 1e-12 * np.abs(kin.qdot).max()
        assert np.abs(kin.qdot[: 6 * len(sd.nodes)]).max() > 0.1  # the rates move the boundary, not only eta
