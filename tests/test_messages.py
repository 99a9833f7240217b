"""ROS 2 message conversions (quatform.messages) and the compute-backend registry."""

import numpy as np
import pytest

from quatform import messages
from quatform.errors import InvalidInputError
from quatform.sim.backends import SIM_BACKENDS, simulator
from quatform.sim.simulate import simulate


def _roundtrip(msg):
    ts = messages.typestore()
    return ts.deserialize_cdr(ts.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


def test_pose_stamped_reorders_the_quaternion_and_round_trips_through_cdr():
    q = np.array([0.5, -0.5, 0.5, 0.5])
    msg = _roundtrip(messages.pose_stamped(12.345678901, [1.0, -2.0, 3.5], q, "world"))
    assert msg.pose.orientation.w == 0.5 and msg.pose.orientation.x == -0.5  # (x, y, z, w) by name
    t, p, q2, frame = messages.pose_from_msg(msg)
    assert abs(t - 12.345678901) < 1e-9 and frame == "world"
    np.testing.assert_array_equal(p, [1.0, -2.0, 3.5])
    np.testing.assert_array_equal(q2, q)


def test_twist_round_trips_and_stamps_carry_nanoseconds():
    lin, ang = messages.twist_from_msg(_roundtrip(messages.twist_stamped(0.1, [1, 2, 3], [4, 5, 6])))
    np.testing.assert_array_equal(lin, [1, 2, 3])
    np.testing.assert_array_equal(ang, [4, 5, 6])
    s = messages.stamp(1.999999999)
    assert (s.sec, s.nanosec) == (1, 999999999)
    assert messages.seconds(messages.stamp(3.0)) == 3.0


@pytest.mark.parametrize("bad", [dict(t=float("nan")), dict(t=-1.0), dict(position=[np.inf, 0, 0]),
                                 dict(quaternion=[1, 0, 0])])
def test_bad_poses_are_one_line(bad):
    args = {"t": 0.0, "position": [0, 0, 0], "quaternion": [1, 0, 0, 0], **bad}
    with pytest.raises(InvalidInputError):
        messages.pose_stamped(args["t"], args["position"], args["quaternion"])


def test_unknown_message_type_names_the_nearest():
    with pytest.raises(InvalidInputError, match="PoseStamped"):
        messages.msg_type("geometry_msgs/msg/PoseStampd")


def test_numpy_is_the_default_backend_and_unknown_ones_name_the_valid():
    assert simulator() is simulate and "numpy" in SIM_BACKENDS
    with pytest.raises(InvalidInputError, match="numpy"):
        simulator("numpi")


def test_tick_measurement_delays_adds_noise_and_holds_dropped_frames():
    from quatform.sim.trial_measurement import TickMeasurement

    T, k = 5, 2
    noise = np.arange(T * 3 * k, dtype=float).reshape(T, 3, k) * 1e-3
    dropped = np.zeros((T, 3), bool)
    dropped[3, 1] = True
    m = TickMeasurement(noise, delay_ticks=1, dropped=dropped)
    y = [np.full((3, k), float(j)) for j in range(T)]
    sched = m.schedule(np.arange(T) * 0.1, 0.1, 1, (3,))
    state = m.init(y[0], (3,), sched)
    out = []
    for j in range(T):
        state, read = m.read(state, {key: v[j] for key, v in sched.items()})
        out.append(read)
        state = m.observe(state, y[j + 1] if j + 1 < T else y[-1], 0)
    # tick k reads y at tick k - 1 (y0 before), plus its noise
    np.testing.assert_allclose(out[0], y[0] + noise[0])
    np.testing.assert_allclose(out[2], y[1] + noise[2])
    np.testing.assert_allclose(out[3][1], out[2][1])  # world 1's frame 3 lost: holds frame 2
    np.testing.assert_allclose(out[3][0], y[2][0] + noise[3][0])
