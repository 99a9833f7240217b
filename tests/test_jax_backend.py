"""The jax compute backend: the same closed loop as NumPy, within 1e-9.

Each test runs a short piece of a built-in pair scenario on both backends (one world and
batches, perfect and TickMeasurement measurement) and compares every channel of the logs;
the refusals name what the backend runs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from conftest import BACKEND_TOL as TOL  # noqa: E402
from conftest import assert_logs_equal, short_scenario  # noqa: E402

from quatform.errors import InvalidInputError, MissingDependencyError
from quatform.scenarios import kind_of, load_scenario
from quatform.scenarios.pair import PAIR
from quatform.sim.backends import SIM_BACKENDS, simulator

CONTROLLERS = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")


@pytest.mark.parametrize("scenario", ["mas-kitts-helix", "mas-kitts-spiral", "mas-kitts-yaw-step"])
@pytest.mark.parametrize("controller", CONTROLLERS)
def test_one_world_equals_numpy(scenario, controller):
    ex = PAIR.experiment(short_scenario(scenario), controller=controller)
    assert_logs_equal(ex.run(backend="numpy"), ex.run(backend="jax"))



@pytest.mark.parametrize("controller", CONTROLLERS)
def test_the_half_turn_step_turns_the_same_way(controller):
    """Seed 000 Fig. 4's 180 deg yaw step (t = 1 s) is a tie between the two ways round: a
    backend that rounds ``d / 2 pi`` or ``atan2`` apart would turn the other way (the
    dual-quaternion robots did, 2 pi apart); the tie rule (algebra.angles.TIE_TURNS) turns
    both the same way."""
    ex = PAIR.experiment(short_scenario("mas-kitts-yaw-step", 1.3), controller=controller)
    assert_logs_equal(ex.run(backend="numpy"), ex.run(backend="jax"))


def test_metrics_equal_on_the_experiment():
    ex = PAIR.experiment(short_scenario("mas-kitts-helix", 1.0), controller="cluster-space")
    a, b = ex.metrics(ex.run(backend="numpy")), ex.metrics(ex.run(backend="jax"))
    for key, value in a.items():
        if isinstance(value, float):
            assert b[key] == pytest.approx(value, abs=TOL), key
        else:
            assert b[key] == value, key



@pytest.mark.parametrize(("scenario", "choice"), [("marciano-circle", {"formation": "quaternion", "physics": "mujoco"})])
def test_refuses_what_it_does_not_run(scenario, choice):
    if choice.get("physics") == "mujoco":
        pytest.importorskip("mujoco")
    sc = load_scenario(scenario)
    ex = kind_of(sc).experiment(sc, **choice)
    with pytest.raises(InvalidInputError, match=r"the jax backend runs the seed-000 pair experiments.*"
                                                r"runs on numpy \(--compute numpy\)"):
        ex.run(backend="jax")


def test_unknown_backend_names_jax():
    with pytest.raises(InvalidInputError, match="unknown compute backend 'jaks'.*jax"):
        simulator("jaks")
    assert "jax" in SIM_BACKENDS


def test_missing_jax_names_the_extra(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_jax(name, *args, **kwargs):
        if name == "jax" or name.startswith("jax."):
            raise ImportError("No module named 'jax'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_jax)
    ex = PAIR.experiment(short_scenario("mas-kitts-spiral", 0.1), controller="quaternion")
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[jax\]"'):
        ex.run(backend="jax")



def test_global_x64_setting_left_alone():
    before = jax.config.jax_enable_x64
    ex = PAIR.experiment(short_scenario("mas-kitts-spiral", 0.1), controller="robot-space")
    log = ex.run(backend="jax")
    assert log["state"].dtype == np.float64
    assert jax.config.jax_enable_x64 == before


def test_equal_configurations_share_one_compilation_key():
    from quatform.sim.jax_loop import config_key

    sc = short_scenario("mas-kitts-helix", 0.1)
    a, b = (PAIR.experiment(sc, controller="quaternion") for _ in range(2))
    assert a.controller is not b.controller
    assert config_key(a.plant, a.controller) == config_key(b.plant, b.controller)
    other = PAIR.experiment(dataclasses.replace(sc, gains={"quaternion": {"k_x": [1, 1, 1]}}), controller="quaternion")
    assert config_key(other.plant, other.controller) != config_key(a.plant, a.controller)
