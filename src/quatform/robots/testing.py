"""The robot-model contract test: one function that checks any registered :class:`~.model.RobotModel`.

Robots layer (test support). ``check_robot_model(model)`` checks what every model promises
(``tests/test_robot_models.py`` runs it over :data:`~.model.ROBOT_MODELS`, so a new model is
checked as soon as its module is imported): its point has the size of its ``point_kind``;
``actuate`` gives one command per command column and a batch equals a loop; ``saturate``
turns a non-finite command into a stop; ``step`` keeps the state's shape; ``brake`` stops
it (the actuation and the batch for a team member, a model with ``n_rate``); a team
file's entry builds it (``from_file`` of each of its ``file_names`` with no
limits given); its ROS 2 conversions turn a pose into a state of its columns; every column
has a unit; its point map (:attr:`~.model.RobotModel.point_map`, for the separation barrier)
gives a velocity of 3 entries (z 0 for a planar point) whose commands are the commands it
came from, and a limit factor in ``[0, 1]``; its ``physics_kind`` is a name or None.
"""

from __future__ import annotations

import numpy as np

from ..formations.layout import POINT_KINDS
from .model import RobotModel

__all__ = ["check_robot_model"]


class _Pose:
    """A measured pose (:class:`quatform.ros2.robot_io.PoseSample`'s fields)."""

    def __init__(self, position, quaternion, twist=None):
        self.t, self.position, self.quaternion, self.twist = 0.0, position, quaternion, twist


def check_robot_model(model: RobotModel, rng=None) -> None:
    """Check the robot-model contract for ``model`` (see the module docstring).

    Raises
    ------
    AssertionError
        Naming the check and the model.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    name = type(model).__name__
    nx, nu = len(model.state_columns), len(model.command_columns)
    x = rng.uniform(0.1, 0.9, nx)
    p = model.point(x)
    assert p.shape == (POINT_KINDS[model.point_kind].size,), f"{name}: point shape {p.shape}"
    assert model.saturate(np.full(nu, np.nan)).tolist() == [0.0] * nu, f"{name}: a NaN command does not stop it"
    assert model.step(x, np.full(nu, 0.1), 0.01).shape == x.shape, f"{name}: step changes the state's shape"
    missing = [c for c in (*model.state_columns, *model.command_columns) if c not in model.column_units]
    assert not missing, f"{name}: column_units lacks {missing}"
    if not hasattr(model, "n_rate"):  # not a team member (the teleoperation arms: torque-commanded)
        return
    u, _ = model.actuate(x, np.full(model.n_rate, 0.3), 0.0, model.initial_memory())
    assert u.shape == (nu,), f"{name}: actuate gives {u.shape}, not ({nu},)"
    stop, _ = model.brake(x, model.initial_memory())
    assert np.all(model.saturate(stop) == 0.0) or np.all(np.isfinite(stop)), f"{name}: brake is not finite"
    X = rng.uniform(-1, 1, (4, nx))
    R = rng.uniform(-1, 1, (4, model.n_rate))
    U, _ = model.actuate(X, R, 0.0, model.initial_memory((4,)))
    for i in range(4):
        ui, _ = model.actuate(X[i], R[i], 0.0, model.initial_memory())
        np.testing.assert_allclose(U[i], ui, rtol=1e-13, atol=1e-13, err_msg=f"{name}: batch != single")
    for file_name in type(model).file_names:
        built = type(model).from_file({}, "robots.toml", "[[robots]]", file_name)
        assert isinstance(built, type(model)), f"{name}: from_file({file_name!r}) builds a {type(built).__name__}"
    _check_point_map(model, name, rng)
    kind = type(model).physics_kind
    assert kind is None or isinstance(kind, str) and kind, f"{name}: physics_kind {kind!r}"
    io = type(model).ros_io
    if io is not None:
        assert io.natural_frame in ("world", "body"), f"{name}: ros_io.natural_frame {io.natural_frame!r}"
        pose = _Pose(np.array([0.3, -0.2, 1.0]), np.array([np.cos(0.2), 0.0, 0.0, np.sin(0.2)]),
                     (np.zeros(3), np.zeros(3)))
        state = io.state(model, pose, None)
        assert np.shape(state) == (nx,), f"{name}: ros_io.state gives {np.shape(state)}, not ({nx},)"
        lin, ang = io.body_twist(model, u, state, pose.quaternion)
        assert np.shape(lin) == np.shape(ang) == (3,), f"{name}: ros_io.body_twist shapes"


def _check_point_map(model, name: str, rng) -> None:
    """The point map's velocity and commands invert each other, instantaneous and held 0.05 s."""
    m = type(model).point_map
    if m is None:
        return
    nx = len(model.state_columns)
    X = rng.uniform(-1, 1, (4, nx))
    U = model.saturate(0.5 * rng.uniform(-1, 1, (4, len(model.command_columns))))
    for dt in (None, 0.05):
        V = np.asarray(m.velocity(model, X, U, dt))
        assert V.shape == (4, 3), f"{name}: point_map.velocity gives {V.shape}, not (4, 3)"
        assert not m.planar or np.all(V[:, 2] == 0.0), f"{name}: a planar point's velocity has a z entry"
        back = m.commands(model, X, U, V, dt)
        np.testing.assert_allclose(back, U, rtol=1e-9, atol=1e-12, err_msg=f"{name}: point_map.commands(velocity) != u")
        s = np.asarray(m.factor(model, X, back, V, dt))
        assert s.shape == (4,) and np.all((s >= 0.0) & (s <= 1.0)), f"{name}: point_map.factor {s}"
        np.testing.assert_allclose(m.scaled(model, X, back, V, np.ones(4), dt), back, rtol=1e-9, atol=1e-12,
                                   err_msg=f"{name}: point_map.scaled by 1 changes the commands")
