"""Issue 12, the UGV-UAV formation of Marciano 2021 (seed 001), kinematic side: each item
of the hardening brief has its own test here."""

from __future__ import annotations

import numpy as np
import pytest

import quatform.control as control


# -- item 7: the UGV-UAV layouts carry their name ------------------------------------------------

def test_ugv_uav_layout_names_are_not_the_generic_ones():
    assert control.UGV_UAV_MEASURED_NAMES[:3] == ("x_p", "y_p", "psi_p")
    assert len(control.UGV_UAV_MEASURED_NAMES) == 11
    assert control.UGV_UAV_COMMAND_NAMES == ("v_p", "omega_p", "u_x_b", "u_y_b", "u_z_b", "u_psi_b")
    assert not hasattr(control, "COMMAND_NAMES") and not hasattr(control, "MEASURED_NAMES")
    assert "UGV_UAV_COMMAND_NAMES" in control.__all__ and "COMMAND_NAMES" not in control.__all__


# -- items 3 and 5: the scenario loader ------------------------------------------------------------

import dataclasses  # noqa: E402

from quatform.errors import InvalidInputError, ResourceLimitError  # noqa: E402
from quatform.sim import load_scenario  # noqa: E402
from quatform.sim.ugv_uav import simulate_ugv_uav, ugv_uav_scenario_from_dict  # noqa: E402

BASE = {"kind": "ugv-uav", "name": "t", "path": "circle", "r_x": 1.0, "r_y": 1.0, "omega": 0.2, "d_c": 1.5,
        "duration_s": 2.0, "gains": {"k_psi": 3.0}}


def _load(**changes):
    data = {**BASE, **changes}
    return ugv_uav_scenario_from_dict({k: v for k, v in data.items() if v is not None}, "my.toml")


@pytest.mark.parametrize("key, value, words", [
    ("floor_below_platform_m", float("nan"), "floor_below_platform_m = nan must be finite"),
    ("uav_front_until_s", float("nan"), "uav_front_until_s = nan must be finite"),
    ("gains", 5, "gains must be a table"),
    ("d_c", {"a": 1}, "d_c = {'a': 1} must be a number"),
    ("r_x", "1.0", "r_x = '1.0' must be a number"),
    ("duration_s", -1.0, "duration_s = -1.0 must be > 0"),
    ("mocap_noise_m", -0.001, "mocap_noise_m = -0.001 must be >= 0"),
    ("center", [1, 2], "center = [1, 2] must be a list of 3 numbers"),
    ("seed", "abc", "seed = 'abc' must be an integer"),
    ("seed", 1.5, "seed = 1.5 must be an integer"),
    ("duraton_s", 3.0, "unknown key 'duraton_s' at top level (did you mean 'duration_s'?)"),
    ("path", "cirle", "path = 'cirle' is not one of circle, lemniscate (did you mean 'circle'?)"),
    ("max_fraction", 1.5, "max_fraction = 1.5 must be <= 1"),
    ("omega", 0.0, "omega = 0.0 must be nonzero"),
    ("control_period_s", 0.001, "control_period_s = 0.001 must be >= dt_s"),
    ("uav_start", [0.0, -0.6, -0.5], "uav_start z = -0.5 m is below the floor"),
    ("name", None, "missing key name"),
    ("duration_s", None, "missing key duration_s"),
    ("title", 3, "title = 3 must be a string"),
    ("mocap_dropout_rate", 1.0, "mocap_dropout_rate = 1.0 must be < 1"),
])
def test_loader_refuses_each_bad_value_naming_the_key(key, value, words):
    with pytest.raises(InvalidInputError, match=None) as info:
        _load(**{key: value})
    msg = str(info.value)
    assert msg.startswith("my.toml: ") and words in msg and "\n" not in msg


@pytest.mark.parametrize("gains, words", [
    ({"k_x": "big"}, "[gains] k_x = 'big' must be a number"),
    ({"k_x": [1.0, 2.0]}, "[gains] k_x = [1.0, 2.0] must be a list of 3 numbers"),
    ({"k_w": [1.0, -1.0, 1.0]}, "[gains] k_w = -1.0 must be > 0"),
    ({"k_psi": float("inf")}, "[gains] k_psi = inf must be finite"),
    ({"l_d": {"x": 1}}, "[gains] l_d = {'x': 1} must be a number"),
    ({"compensation": 1}, "[gains] compensation = 1 must be true or false"),
    ({"k_pis": 3.0}, "unknown key 'k_pis' at [gains] (did you mean 'k_psi'?)"),
    ({"arena": 1.0}, "unknown key 'arena' at [gains]"),
])
def test_loader_refuses_bad_gains(gains, words):
    with pytest.raises(InvalidInputError) as info:
        _load(gains=gains)
    assert words in str(info.value)


def test_loader_reads_good_values_and_lists():
    sc = _load(center=[0.5, -0.5, 0.2], gains={"k_x": [1.0, 2.0, 3.0], "l_d": 2.0, "compensation": False})
    assert sc.center == (0.5, -0.5, 0.2) and sc.gains["k_x"] == (1.0, 2.0, 3.0)
    assert sc.gains["l_d"] == (2.0,) * 4 and sc.gains["compensation"] is False
    for name in ("marciano-circle", "marciano-lemniscate", "marciano-front-to-over"):
        assert load_scenario(name).name == name


def test_huge_duration_is_refused_up_front_naming_the_key():
    with pytest.raises(ResourceLimitError, match="my.toml: duration_s / control_period_s needs 3.33e"):
        _load(duration_s=1e9)
    # a scenario changed after loading (as the CLI does) is checked again when run
    sc = dataclasses.replace(_load(), duration_s=1e9)
    with pytest.raises(ResourceLimitError, match="duration_s"):
        simulate_ugv_uav(sc)
    with pytest.raises(InvalidInputError, match="mocap_noise_m = nan must be finite"):
        simulate_ugv_uav(dataclasses.replace(_load(), mocap_noise_m=float("nan")))
