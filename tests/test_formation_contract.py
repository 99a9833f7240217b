"""One contract test for every registered formation.

``quatform.formations.testing.check_formation`` checks round trips, the rate maps against
central differences and against each other, dense Jacobians = rate maps, batch = single,
sign and yaw-wrap invariance and the declared behaviour at and near each special set;
here it runs over :data:`quatform.formations.FORMATIONS` (the examples of every description
class registered in ``FORMATION_TYPES`` when it is defined), so a new description is checked
as soon as its module is imported. The seeds' own numbers and the external oracles stay in
``test_formations.py``, ``test_ugv_uav.py`` and ``test_oracles.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.errors import InvalidInputError, NonFiniteError, ShapeError
from quatform.formations import FORMATION_TYPES, FORMATIONS, TEAM_FORMATIONS, Formation, RobotLayout, TeamChart
from quatform.formations.testing import check_formation, cluster_distance

KEYS = sorted(FORMATIONS)


def _subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def test_registry_covers_every_description():
    """Every concrete Formation subclass of the package is registered once, under a unique key."""
    classes = {c for c in _subclasses(Formation) if c.__module__.startswith("quatform.formations.")
               and not c.__name__.startswith("_")}
    assert classes == {type(F) for F in FORMATIONS.values() if type(F).__module__.startswith("quatform.")}
    assert set(FORMATION_TYPES.values()) >= classes
    assert len({type(F) for F in FORMATIONS.values()}) >= 8
    assert {k: type(FORMATIONS[k]) for k in TEAM_FORMATIONS} == TEAM_FORMATIONS  # the team classes, once each


def test_a_preset_is_a_formation_of_its_own_key_not_a_second_team_description():
    """EuclideanPair and RobotSpace (two robots, the pair chart) run the contract under their
    own keys; the team controllers stay one per team description: a subclass that inherits its
    parent's controller name runs under it and claims none, one that sets a taken name in its
    own body is one line naming both."""
    from quatform.control.team import team_descriptions
    from quatform.formations import EuclideanPair, EuclideanTeam, RobotSpace, RobotSpaceTeam

    for preset, team, key in ((EuclideanPair, EuclideanTeam, "euclidean"), (RobotSpace, RobotSpaceTeam, "robot")):
        assert issubclass(preset, team) and preset.key == preset.name == key
        assert FORMATION_TYPES[key] is preset and type(FORMATIONS[key]) is preset
        assert preset not in TEAM_FORMATIONS.values()
        assert preset().chart_variables == team(2, chart="pair").chart_variables
    np.testing.assert_array_equal(RobotSpace().forward(np.zeros(8)), np.zeros(8))  # c = r, robots on each other
    for bad, err in ((np.zeros(7), ShapeError), (np.full(8, np.nan), NonFiniteError)):
        with pytest.raises(err, match="^c "):  # the identity of robot space still checks what it is given
            RobotSpace().inverse_jacobian_at(bad)
    with pytest.raises(ShapeError, match=r"^e_dot must have shape \(\.\.\., 8\)"):
        RobotSpace().from_chart(np.array([0, 0, 1.5, 0.3, 0.5, 1.0, 0, 0]), np.zeros(3))
    with pytest.raises(InvalidInputError, match="needs two xyz_yaw robots"):
        RobotSpaceTeam(3, chart="pair")
    names = team_descriptions()
    assert names["cluster-space"] is EuclideanTeam and names["robot-space"] is RobotSpaceTeam
    try:
        class _Variant(EuclideanTeam):  # registers itself: removed below
            key = "variant-team"

        assert team_descriptions() == names

        class _Clash(EuclideanTeam):
            key = "clash-team"
            controller = "cluster-space"

        with pytest.raises(InvalidInputError, match="EuclideanTeam and _Clash both set controller = 'cluster-space'"):
            team_descriptions()
    finally:
        FORMATION_TYPES.pop("variant-team", None)
        FORMATION_TYPES.pop("clash-team", None)
    assert team_descriptions() == names


@pytest.mark.parametrize("key", KEYS)
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_contract(key, seed):
    check_formation(FORMATIONS[key], np.random.default_rng(seed), n=24)


@pytest.mark.parametrize("key", KEYS)
def test_layout_names_the_robot_variables(key):
    F = FORMATIONS[key]
    assert isinstance(F.layout, RobotLayout)
    assert F.robot_variables == F.layout.variables and F.n_r == F.layout.size
    if type(F) in TEAM_FORMATIONS.values():  # the team chart (formations.team_chart)
        assert F.chart_variables == TeamChart(F.layout).variables
    else:
        assert len(F.chart_variables) == (8 if F.layout.n == 2 and F.n_r == 8 else 6)


def test_pair_and_ugv_uav_names_stay():
    from quatform.formations import ROBOT_PAIR_VARIABLES, UGV_UAV_VARIABLES

    assert [v.name for v in ROBOT_PAIR_VARIABLES] == ["x1", "y1", "z1", "theta1", "x2", "y2", "z2", "theta2"]
    assert [v.name for v in UGV_UAV_VARIABLES] == ["x_p", "y_p", "z_p", "x_b", "y_b", "z_b"]


GOLDEN = Path(__file__).parent / "data" / "formation_jacobians.json"


@pytest.mark.parametrize("key", [k for k in KEYS if type(FORMATIONS[k]) not in TEAM_FORMATIONS.values()])
def test_dense_jacobians_equal_the_matrices_before_the_rate_maps(key):
    """The matrices applied to the unit vectors equal those main built directly before the rate
    maps became the primitive (recorded at 12 states per description), within 1e-12."""
    rec = json.loads(GOLDEN.read_text())[key]
    F = FORMATIONS[key]
    r = np.array(rec["r"])
    c = F.forward(r)
    np.testing.assert_allclose(c, rec["c"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.inverse_jacobian_at(c, r=r), rec["inverse_jacobian_at"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.jacobian(r), rec["jacobian"], rtol=0, atol=1e-12 * np.abs(rec["jacobian"]).max())


def test_check_formation_refuses_a_batch_it_cannot_split():
    with pytest.raises(InvalidInputError, match="multiple of 6"):
        check_formation(FORMATIONS["euclidean"], np.random.default_rng(0), n=10)


def test_cluster_distance_sees_a_flip_of_a_signed_block_but_not_of_a_sign_free_one():
    F = FORMATIONS["dual-quaternion"]
    r = F.sample_robot_state(np.random.default_rng(1), (4,))
    c = F.forward(r)
    flipped_c, flipped_s = c.copy(), c.copy()
    flipped_c[..., 0:8] *= -1  # qhat_c: sign means nothing
    flipped_s[..., 8:16] *= -1  # qhat_s: the other branch, another formation
    assert np.max(cluster_distance(F, flipped_c, c)) < 1e-15
    assert np.min(cluster_distance(F, flipped_s, c)) > 0.1
