"""Shared hypothesis strategies and numerical helpers for the test suite."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings, strategies as st
from hypothesis.extra import numpy as hnp

from quatform.control.contract import Controller, Step

#: The fake rclpy of the ROS 2 bridge's tests.
FAKE_RCLPY = Path(__file__).parent / "fake_rclpy"

settings.register_profile("default", max_examples=60, deadline=None)
settings.load_profile("default")

batch_shapes = hnp.array_shapes(min_dims=0, max_dims=2, min_side=1, max_side=4)
finite = st.floats(-5.0, 5.0, allow_nan=False, allow_infinity=False)


@st.composite
def quaternions(draw, shape=None, min_norm=1e-2):
    """Arbitrary (non-unit) quaternions of norm >= min_norm, shape (*shape, 4)."""
    shape = draw(batch_shapes) if shape is None else shape
    q = draw(hnp.arrays(np.float64, tuple(shape) + (4,), elements=finite))
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(n < min_norm, np.array([1.0, 0.0, 0.0, 0.0]), q)


@st.composite
def unit_quaternions(draw, shape=None):
    q = draw(quaternions(shape=shape, min_norm=1e-2))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@st.composite
def vectors(draw, shape=None, scale=5.0):
    shape = draw(batch_shapes) if shape is None else shape
    el = st.floats(-scale, scale, allow_nan=False, allow_infinity=False)
    return draw(hnp.arrays(np.float64, tuple(shape) + (3,), elements=el))


@st.composite
def unit_dual_quaternions(draw, shape=None):
    from quatform.algebra import dq_from_pose

    shape = draw(batch_shapes) if shape is None else shape
    return dq_from_pose(draw(unit_quaternions(shape=shape)), draw(vectors(shape=shape)))


def numeric_jacobian(f, x, h=1e-6):
    """Central-difference Jacobian of f: R^n -> R^m at x (1-D), shape (m, n)."""
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h))
    return np.stack(cols, axis=-1)


def random_unit_quaternions(n, seed=0):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@st.composite
def same_shape(draw, *makers):
    """Draw one batch shape and one value per strategy factory with that shape."""
    shape = draw(batch_shapes)
    return tuple(draw(m(shape=shape)) for m in makers)


@dataclass(frozen=True)
class Constant(Controller):
    """The same command every tick (a test's controller: no feedback)."""

    u: tuple
    name = "constant"

    @property
    def command_names(self):
        return tuple(f"u{i}" for i in range(len(self.u)))

    def signal_columns(self):
        return {}

    def update(self, t, measured, reference, state):
        return Step(np.array(self.u, dtype=float), state, {})


#: The channels a compute backend's log must equal NumPy's on, and the tolerance.
BACKEND_CHANNELS = ("state", "measured", "command", "cluster", "error", "raw_finite")
BACKEND_TOL = 1e-9


def short_scenario(name, duration_s=0.6):
    """A built-in scenario cut to ``duration_s`` with its metrics from t = 0."""
    import dataclasses

    from quatform.scenarios import load_scenario

    return dataclasses.replace(load_scenario(name), duration_s=duration_s, metrics_from_s=0.0)


def assert_logs_equal(a, b):
    """Two logs' :data:`BACKEND_CHANNELS` equal within :data:`BACKEND_TOL`."""
    for key in BACKEND_CHANNELS:
        assert a[key].shape == b[key].shape, key
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=BACKEND_TOL, err_msg=key)


def noisy_batch(exp, B=3, seed=1, spread=0.02, sigma=0.003):
    """``exp`` as a batch of ``B`` worlds: starts moved by ``spread``, ``sigma`` of noise, one
    tick of latency, 10 % dropped frames; the identity finish (the raw loop's log)."""
    import dataclasses

    from quatform.sim.trial_measurement import TickMeasurement

    rng = np.random.default_rng(seed)
    T = len(exp.times)
    x0 = exp.x0[None] + spread * rng.standard_normal((B, exp.x0.size))
    noise = sigma * rng.standard_normal((T, B, exp.x0.size))
    return dataclasses.replace(exp, x0=x0, measurement=TickMeasurement(noise, 1, rng.random((T, B)) < 0.1),
                               finish=lambda log: log)


def assert_metrics_equal(ma, mb, skip=()):
    """Two runs' metrics dicts: the same keys, finite floats within :data:`BACKEND_TOL` of
    their own scale with a floor of one unit (m, rad, s: an error metric near zero is the
    difference of quantities of that size, so two computation orders differ by their rounding,
    not by its own), lists of floats the same way, the rest (NaN, None, flags, strings) equal;
    keys in ``skip`` only present."""
    assert ma.keys() == mb.keys()
    for key, value in ma.items():
        if key in skip:
            continue
        if isinstance(value, float) and np.isfinite(value):
            assert abs(mb[key] - value) <= BACKEND_TOL * max(1.0, abs(value)), (key, value, mb[key])
        elif isinstance(value, (list, tuple)) and value and all(isinstance(v, float) for v in value):
            np.testing.assert_allclose(mb[key], value, rtol=BACKEND_TOL, atol=BACKEND_TOL, err_msg=key)
        else:
            assert mb[key] == value or (isinstance(value, float) and np.isnan(value) and np.isnan(mb[key])), key


def pair_separation(r):
    """Distance between the two robots of seed 000's pair states ``r`` ``(..., 8)``, m."""
    from quatform.formations import RobotSpace

    return RobotSpace().layout.separations(np.asarray(r, dtype=float))[..., 0]


def pair_robot_error(a, b) -> float:
    """Largest difference of two pair states, their yaws mod 2 pi."""
    from quatform.formations import RobotSpace
    from quatform.formations import geometry as g

    d = np.asarray(a, float) - np.asarray(b, float)
    yaw = list(RobotSpace().layout.yaw_indices)
    d[..., yaw] = g.wrap(d[..., yaw])
    return float(np.abs(d).max())


@pytest.fixture
def fake_ros(monkeypatch):
    """The fake rclpy (``tests/fake_rclpy``, which refuses what rclpy refuses) on sys.path and its
    message packages in sys.modules (both undone after)."""
    monkeypatch.syspath_prepend(str(FAKE_RCLPY))
    for name in [n for n in sys.modules if n == "rclpy" or n.startswith("rclpy.") or n == "fake_messages"]:
        monkeypatch.delitem(sys.modules, name)
    import fake_messages
    import rclpy

    fake_messages.install(monkeypatch)
    rclpy.fake_bus.BUS.reset()
    yield rclpy
    rclpy.fake_bus.BUS.reset()
    for name in [n for n in sys.modules if n == "rclpy" or n.startswith("rclpy.")]:
        del sys.modules[name]
