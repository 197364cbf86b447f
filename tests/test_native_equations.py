"""The C runtime's superelement (runtime/native/superelement.c, `ffrf_body_superelement`) against the
plain oracle (runtime/equations.py superelement_residual_and_jacobian), field by field: the local
rows F and the blocks F_ydot, F_y of each superelement, by the names of runtime/layout.py (rows k_x,
k_T, k_q, e_x0, e_T0, e_eta, e_xP, e_TP; columns x0, Theta0, eta, x_P, Theta_P, v0, Omega0, r), for
every term set (linear, gyroscopic, full and its switches), each with and without the geometric
stiffening, at random states: far from the reference (every frame rotated apart, conftest
far_from_reference) and near a rigidly rotated, slightly deformed reference, with random rates.

Both evaluate the same equations in different orders, so they agree to round-off. Tolerance: 1e-12
of each block's scale, which is the block's largest oracle entry, floored at 1e-3 of its row
field's largest entry: a few blocks are sums that cancel analytically or nearly (e.g. F_ydot of
e_T0 on x0dot, the coupling's r^T G_k applied to a rigid translation: 1e-21 to 7e-5 of their row
field here), and their round-off is that of the cancelling terms, of their row's size. Measured over
these 18 cases x 4 states x 2 superelements: at most 2.0e-13 of a block's scale (that block, full
with W1 at a near state), 1.5e-14 for the F fields. The same for a stiffened solid (the small bar of
conftest.SOLID_BAR: one superelement on two frames, membrane tensors from its mesh). W1 and W2 are scaled by 1e4 (any W is a valid
body for this identity) so that their blocks stand well above the floor. A missing or wrong term
shows up as an O(1) relative difference in its blocks: `test_every_switch_is_seen` checks that the
comparison fails against the oracle of the same body with any one switch off (measured: at least
2.5e-3 of a block's scale, the coupling switch; 1e-9 required).
"""
from __future__ import annotations

import ctypes
import dataclasses

import numpy as np
import pytest

from ffrf_fmu.model import Body, Port
from ffrf_fmu.reduction import reduce_body
from ffrf_fmu.runtime import equations
from ffrf_fmu.runtime.body import BodySystem
from ffrf_fmu.runtime.layout import Segments
from ffrf_fmu.runtime.native.binding import NativeBody
from ffrf_fmu.runtime.native.image import body_image
from ffrf_fmu.runtime.rotation import expm
from ffrf_fmu.runtime.terms import FULL_TERMS as FULL

TOL = 1e-12
FLOOR = 1e-3  # of the row field's largest entry: the scale of a block that cancels
TERM_SETS = {  # name: (terms, full_terms)
    "linear": ("linear", ()),
    "gyroscopic": ("gyroscopic", ()),
    "full": ("full", FULL),
    "full-W1": ("full", ("inertia_W1",)),
    "full-W2": ("full", ("inertia_W2",)),
    "full-coupling": ("full", ("inertia_coupling",)),
    "full-coriolis": ("full", ("coriolis",)),
    "full-coriolis-W2": ("full", ("coriolis", "inertia_W2")),
    "full-W1-W2-coupling": ("full", ("inertia_W1", "inertia_W2", "inertia_coupling")),
}
STATES = [("far", 1), ("far", 2), ("near", 3), ("near", 4)]


_DATA = {}


def _data(b1, stiff):
    """Two superelements of B1's section (4 elements, 3 modes each) with the inertia data W1, W2
    [and the stiffening data], W1 and W2 scaled by 1e4 (built once per module); stiff = "solid": the
    small solid bar of conftest (one superelement on two frames, stiffening from its mesh)."""
    if stiff in _DATA:
        return _DATA[stiff]
    if stiff == "solid":
        from conftest import solid_bar_body

        data = solid_bar_body(True, True)[0]
        ses = tuple(dataclasses.replace(se, W1=se.W1 * 1e4, W2=se.W2 * 1e4) for se in data.superelements)
        _DATA[stiff] = dataclasses.replace(data, superelements=ses)
        return _DATA[stiff]
    section, length = b1
    body = Body("b", length, (0, 0, 0), (1, 0, 0), section, 2, 4, 3,
                (Port("hub", 0, "motion", "force"), Port("tip", 2, "force", "force")))
    data = reduce_body(body, stiffening=stiff, inertia=True).data
    ses = tuple(dataclasses.replace(se, W1=se.W1 * 1e4, W2=se.W2 * 1e4) for se in data.superelements)
    _DATA[stiff] = dataclasses.replace(data, superelements=ses)
    return _DATA[stiff]


def _near(s: BodySystem, seed: int) -> None:
    """The reference configuration rotated and moved rigidly at random, every frame and mode then
    perturbed a little (a deformed state), random velocities."""
    rng = np.random.default_rng(seed)
    Rg, t = expm(rng.normal(size=3)), rng.normal(size=3)
    s.xN = t + s.xN @ Rg.T + rng.normal(size=s.xN.shape) * 0.01
    s.x0 = t + s.x0 @ Rg.T + rng.normal(size=s.x0.shape) * 0.01
    s.RN = Rg @ s.RN @ expm(rng.normal(size=(len(s.RN), 3)) * 0.05)
    s.R0 = Rg @ s.R0 @ expm(rng.normal(size=(len(s.R0), 3)) * 0.05)
    s.eta = rng.normal(size=s.eta.shape) * 0.01
    s.v = rng.normal(size=s.v.shape)


def _system(term_set: str, stiff: bool, state, b1, far_from_reference) -> tuple[BodySystem, np.ndarray]:
    """The body with the term set at a random state, and random rates yd."""
    terms, full_terms = TERM_SETS[term_set]
    kind, seed = state
    s = BodySystem(_data(b1, stiff), terms=terms, rho_inf=0.7, **({"full_terms": full_terms} if terms == "full" else {}))
    if kind == "far":
        far_from_reference(s, seed)
    else:
        _near(s, seed)
    return s, np.random.default_rng(100 + seed).normal(size=s.yd.shape)


class _Native:
    """The C body of a BodySystem (its image, runtime/native/image.py) and its test entry point
    `ffrf_body_superelement` (ffrf_runtime.h): one superelement's rows and blocks in the body's own
    work space."""

    def __init__(self, s: BodySystem):
        self.body = NativeBody(body_image(s))
        self.fn = self.body.lib.ffrf_body_superelement
        p, i = ctypes.c_void_p, ctypes.c_int
        self.fn.restype, self.fn.argtypes = i, [p, i, p, p, p, i, p, p, p]
        self.size = (s.layout.nv + s.layout.nc, s.layout.nc + s.layout.nv)

    def superelement(self, e: int, p, yd, R):
        """(F, F_ydot, F_y) of superelement e at the stage p, yd, R."""
        F, Fz, Fy = np.zeros(self.size[0]), np.zeros(self.size), np.zeros(self.size)
        p, yd, R = (np.ascontiguousarray(a, dtype=float) for a in (p, yd, R))
        code = self.fn(self.body.ptr, e, *(a.ctypes.data for a in (p, yd, R)), 1, *(a.ctypes.data for a in (F, Fz, Fy)))
        assert code == 0
        return F, Fz, Fy


def _stage(s: BodySystem) -> tuple[np.ndarray, np.ndarray]:
    """The stage the C runtime reads: p (ny) with the linear quantities at their rate slots (node and
    CM translations, modes, velocities; runtime/layout.py), R (N + E, 3, 3) the node then CM frames."""
    L = s.layout
    p = np.zeros(L.ny)
    p[(6 * np.arange(L.n_nodes)[:, None] + np.arange(3)).ravel()] = s.xN.ravel()
    p[L.cfg_map[:, 0:3].ravel()] = s.x0.ravel()
    p[L.cfg_map[:, 6 : 6 + L.nm].ravel()] = s.eta.ravel()
    p[L.vel_map.ravel()] = s.v.ravel()
    return p, np.ascontiguousarray(np.concatenate([s.RN, s.R0]))


def _oracle(s: BodySystem, yd, e: int, term_set: str, switch_off: str | None = None):
    """(F, F_ydot, F_y) of superelement e by the oracle; switch_off: one switch of the term set (or
    "stiffening": the membrane strain) turned off."""
    terms, full_terms = TERM_SETS[term_set]
    # the oracle takes W2 as given; the body subtracts G^T M^-1 G from it when coriolis is on
    ses = tuple(dataclasses.replace(se, W2=s.W2[k]) if s.W2 is not None else se for k, se in enumerate(s.data.superelements))
    if switch_off == "stiffening":
        ses = tuple(dataclasses.replace(se, vk_a=None, vk_B=None) for se in ses)  # the membrane strain
    elif switch_off is not None:
        full_terms = tuple(t for t in full_terms if t != switch_off)
    data = dataclasses.replace(s.data, superelements=ses)
    return equations.superelement_residual_and_jacobian(data, s.layout, terms, s.gravity, e, s.xN, s.RN, s.x0, s.R0, s.eta,
                                                        s.v, yd, full_terms)


def _fields(s: BodySystem) -> tuple[Segments, Segments]:
    """The named rows and columns of a superelement's local blocks (runtime/layout.py)."""
    L = s.layout
    rows = {"k_x": 3, "k_T": 3, "k_q": L.n, "e_x0": 3, "e_T0": 3, "e_eta": L.nm}
    cols = {"x0": 3, "Theta0": 3, "eta": L.nm}
    for k in range(L.nb):
        rows.update({f"e_x{k}": 3, f"e_T{k}": 3})
        cols.update({f"x_{k}": 3, f"Theta_{k}": 3})
    cols.update({"v0": 3, "Omega0": 3, "r": L.n})
    return Segments(**rows), Segments(**cols)


def _differences(s: BodySystem, c, oracle) -> list[tuple[float, str]]:
    """(difference / scale, name) of every named field of F and block of F_ydot, F_y."""
    rows, cols = _fields(s)
    out = []
    (F, Fz, Fy), (F0, Fz0, Fy0) = c, oracle
    for r, rs in rows.slices.items():
        scale = np.abs(F0[rs]).max()
        out.append((_relative(F[rs], F0[rs], scale), f"F[{r}]"))
        for name, A, A0 in (("F_ydot", Fz, Fz0), ("F_y", Fy, Fy0)):
            row = np.abs(A0[rs]).max()
            for col, cs in cols.slices.items():
                scale = max(np.abs(A0[rs, cs]).max(), FLOOR * row)
                out.append((_relative(A[rs, cs], A0[rs, cs], scale), f"{name}[{r}, {col}]"))
    return out


def _relative(a, b, scale: float) -> float:
    d = np.abs(a - b).max()
    return d / scale if scale > 0 else (0.0 if d == 0 else np.inf)


@pytest.mark.parametrize("stiff", [False, True, "solid"], ids=["plain", "stiffening", "solid-stiffening"])
@pytest.mark.parametrize("term_set", list(TERM_SETS))
def test_superelement_rows_and_blocks_match_the_oracle(term_set, stiff, b1, far_from_reference):
    worst = []
    for state in STATES:
        s, yd = _system(term_set, stiff, state, b1, far_from_reference)
        body = _Native(s)
        p, R = _stage(s)
        for e in range(s.layout.n_se):
            c = body.superelement(e, p, yd, R)
            oracle = _oracle(s, yd, e, term_set)
            assert np.abs(oracle[2]).max() > 0 and np.abs(oracle[0]).max() > 0  # a real state, not the rest state
            worst += [(d, f"{state} e={e} {name}") for d, name in _differences(s, c, oracle) if not d <= TOL]
    assert not worst, sorted(worst, reverse=True)[:10]


@pytest.mark.parametrize("switch", [*FULL, "stiffening"])
def test_every_switch_is_seen(switch, b1, far_from_reference):
    """The comparison fails by far more than its tolerance against the oracle of the same body with
    one switch off: every part of the equations the C runtime computes is compared. (The stiffened
    body carries W1 whatever the switches: inertia_W1 is seen on the plain one.)"""
    s, yd = _system("full", switch == "stiffening", STATES[2], b1, far_from_reference)
    _every_switch_seen(s, yd, switch)


def test_the_solid_membrane_strain_is_seen(b1, far_from_reference):
    """The stiffened solid bar (conftest.SOLID_BAR): the comparison fails against the oracle without
    its membrane tensors."""
    s, yd = _system("full", "solid", STATES[2], b1, far_from_reference)
    _every_switch_seen(s, yd, "stiffening")


def _every_switch_seen(s, yd, switch):
    body = _Native(s)
    p, R = _stage(s)
    for e in range(s.layout.n_se):
        c = body.superelement(e, p, yd, R)
        assert max(d for d, _ in _differences(s, c, _oracle(s, yd, e, "full"))) <= TOL
        assert max(d for d, _ in _differences(s, c, _oracle(s, yd, e, "full", switch_off=switch))) > 1e3 * TOL



def test_a_superelement_the_body_lacks_is_refused(b1, far_from_reference):
    """ffrf_body_superelement answers -1 (and writes nothing) for an index outside the body's superelements."""
    s, yd = _system("linear", False, STATES[0], b1, far_from_reference)
    body = _Native(s)
    p, R = _stage(s)
    F = np.full(body.size[0], 7.0)
    for e in (-1, s.layout.n_se):
        assert body.fn(body.body.ptr, e, p.ctypes.data, yd.ctypes.data, R.ctypes.data, 0, F.ctypes.data, None, None) == -1
    assert (F == 7.0).all()
