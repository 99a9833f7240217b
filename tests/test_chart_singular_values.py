"""A chart's value at and near its singular set.

On the set (the UAV straight over the UGV: the spherical ``alpha_c = atan2(0, 0)``) the value
is the chart's convention, the reference's ``alpha_c`` (``near_e`` / ``near_c``), the same
floats on NumPy and JAX. Near it the value is the robots' true azimuth, carried with fewer
digits the closer they are: :meth:`Formation.value_spread` bounds how far it moves for a
given change of the positions, and the bound is tight (the ill-conditioning is real: a UAV
a nanometre off the vertical turns ``alpha_c`` by 1e-5 rad for a 1e-14 m change).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from quatform.algebra import wrap_angle
from quatform.errors import InvalidInputError
from quatform.formations import EuclideanPair, UgvUavRestricted, UgvUavSpherical
from quatform.scenarios.ugv_uav import UGV_UAV_FORMATIONS

EPS = np.finfo(float).eps
UGV = np.array([0.3, -0.2, 0.1])
RHO = 0.75
PHI = 2.2  # the true azimuth near the set
#: The reference the chart is read near: alpha_c wound one turn, the UAV over the UGV.
NEAR_E = np.array([0.3, -0.2, 0.1, RHO, 0.4 + 2 * math.pi, 0.5 * math.pi])


def _robots(h, phi=PHI):
    """The UGV and the UAV ``h`` m off its vertical at azimuth ``phi``, ``RHO`` apart."""
    d = np.array([h * math.cos(phi), h * math.sin(phi), math.sqrt(RHO * RHO - h * h)])
    return np.r_[UGV, UGV + d]


@pytest.mark.parametrize("h", [0.0, 1e-13])  # h / rho <= OVERHEAD_TOL: on the set
@pytest.mark.parametrize("formation", list(UGV_UAV_FORMATIONS))
def test_on_the_set_the_azimuth_is_the_reference(formation, h):
    F = UGV_UAV_FORMATIONS[formation]
    r = _robots(h)
    # the spherical state is its own chart: its alpha_c is read near the reference (as the
    # controller reads it), the others' chart from the robots
    c = F.forward(r, near_c=NEAR_E) if isinstance(F, UgvUavSpherical) else F.forward(r)
    e = F.to_chart(c, near_e=NEAR_E, r=r)
    assert e[4] == NEAR_E[4]  # the convention, exactly
    np.testing.assert_allclose(e[[0, 1, 2, 3, 5]], NEAR_E[[0, 1, 2, 3, 5]], rtol=0, atol=1e-15 + 2 * h / RHO)


@pytest.mark.parametrize("h", [0.0, 1e-13, 1e-9 * RHO, 1e-6 * RHO, 1e-3 * RHO])
def test_jax_reads_the_chart_as_numpy(h):
    """The chart's one kernel (``forward_arrays``) on both namespaces: on the set the same
    convention (the same floats), near it the same value within the rounding's spread."""
    jax = pytest.importorskip("jax")
    S = UgvUavSpherical()
    r = _robots(h)
    a = S.forward(r, near_c=NEAR_E)
    with jax.enable_x64(True):
        b = np.asarray(S.forward_arrays(jax.numpy.asarray(r), jax.numpy.asarray(NEAR_E)))
    spread = S.value_spread(r, EPS * np.abs(r).max())
    np.testing.assert_array_less(np.abs(b - a), 1e-15 + spread)
    if h <= 1e-12 * RHO:
        assert a[4] == b[4] == NEAR_E[4]


@pytest.mark.parametrize("h", [1e-9 * RHO, 1e-6 * RHO, 1e-3 * RHO])
def test_near_the_set_the_azimuth_is_the_robots_within_its_spread(h):
    S = UgvUavSpherical()
    r = _robots(h)
    e = S.forward(r, near_c=NEAR_E)
    spread = S.value_spread(r, EPS * np.abs(r).max())[4]
    assert abs(e[4] - (PHI + 2 * math.pi)) <= 1e-15 + spread  # the true azimuth, wound near the reference's
    assert spread < 1e-5  # and it means something: rounding moves it by a few ulps over h


@pytest.mark.parametrize("h", [1e-9 * RHO, 1e-6 * RHO, 1e-3 * RHO, 0.5])
def test_the_spread_bounds_the_change_and_is_tight(h):
    """A move ``delta`` of the UAV across its azimuth turns ``alpha_c`` by ``delta / h``:
    within :meth:`value_spread`, and not far below it (the bound grows as the chart's
    condition number does)."""
    S = UgvUavSpherical()
    r = _robots(h)
    delta = 1e-14 if h < 1e-6 else 1e-9
    moved = r.copy()
    moved[3:5] += delta * np.array([-math.sin(PHI), math.cos(PHI)])  # across the azimuth (|move| = delta)
    turned = abs(float(wrap_angle(S.forward(moved, near_c=NEAR_E)[4] - S.forward(r, near_c=NEAR_E)[4])))
    spread = S.value_spread(r, delta + EPS * np.abs(r).max())[4]
    assert turned <= spread
    assert turned >= 0.1 * spread


@pytest.mark.parametrize("F", [EuclideanPair(), UgvUavSpherical(), UgvUavRestricted()], ids=lambda F: F.name)
def test_the_spread_bounds_random_moves(F):
    """Random states (some a hair from the chart's singular set) moved by at most ``delta``
    per entry: every value moves within the spread."""
    rng = np.random.default_rng(5)
    r = F.sample_robot_state(rng, 40)
    if isinstance(F, EuclideanPair):  # robot 1 nearly straight over robot 2 in a quarter of them
        p = F.layout.positions(r)
        p[:10, 0, :2] = p[:10, 1, :2] + 1e-7 * rng.standard_normal((10, 2))
        r = F.layout.compose(p, F.layout.yaws(r))
    delta = 1e-10
    near = F.forward(r)
    for _ in range(5):
        moved = r + delta * rng.uniform(-1, 1, r.shape)
        change = F.forward(moved, near_c=near) - near
        angles = np.array([v.unit == "rad" for v in F.variables])
        change[..., angles] = wrap_angle(change[..., angles])
        spread = F.value_spread(r, delta + EPS * np.abs(r).max(axis=-1), near_c=near)
        np.testing.assert_array_less(np.abs(change), 1e-15 + spread)


def test_on_the_set_no_digit_is_left_and_a_negative_delta_is_refused():
    S = UgvUavSpherical()
    assert S.value_spread(_robots(0.0), 1e-15)[4] >= 10 * math.pi  # rounding alone: any azimuth
    with pytest.raises(InvalidInputError, match="delta must be finite and >= 0") as err:
        S.value_spread(_robots(0.1), -1.0)
    assert "\n" not in str(err.value)
