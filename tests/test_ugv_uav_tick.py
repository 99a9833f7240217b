"""The UGV-UAV controller's one pure tick (seed 001 §4.3-4.4, Fig. 18, with the lab's filters).

A scripted run of five worlds, each in other branches at other ticks (good, dropped and
glitched frames, no frame yet, lost odometry, a hold longer than ``max_hold_s`` and its stop, a
NaN reference, the restricted description's robot-space fallback, an arena wall, an emergency
stop and its release): the batched tick equals the per-world ``update``, the run's numbers equal
the recorded ones (the per-world controller with Python branches it replaces), and ``jax.jit``
of the tick equals NumPy within 1e-9.
"""

from __future__ import annotations

import numpy as np
import pytest

from quatform.control.base import Reference
from quatform.control.ugv_uav import UgvUavController
from quatform.formations import UgvUavQuaternion, UgvUavRestricted, UgvUavSpherical

DESCRIPTIONS = {"quaternion": UgvUavQuaternion, "spherical": UgvUavSpherical, "restricted": UgvUavRestricted}
T, B, DT = 60, 5, 0.03
STOP_AT, RELEASE_AT = 30, 40
#: Sums over the scripted run of the per-world controller that branches in Python (the
#: commands, and the signals with NaN read as 0), recorded from it: ``_sums(_per_world(kind))``;
#: ``no_frame`` adds its 3 ticks of a world without a good frame yet.
RECORDED = {
    "quaternion": (89.34088143336737, 3973.997374258469),
    "spherical": (97.93343758941002, 4218.804770778785),
    "restricted": (94.04958378212689, 3740.4253345302136),
}


def _inputs(F, seed=0):
    """``(t (T,), measured (T, B, 11), c (T, B, n_c), c_dot (T, B, n_c))``: five worlds."""
    rng = np.random.default_rng(seed)
    ts = DT * np.arange(T)
    ms, cs, cds = np.zeros((T, B, 11)), np.zeros((T, B, F.n_c)), np.zeros((T, B, F.n_c))
    for k, t in enumerate(ts):
        t2 = t + 0.5
        rd = np.array([0.3 * np.cos(0.5 * t2), 0.3 * np.sin(0.5 * t2), 0.0, 0.3 * np.cos(0.5 * t2) + 0.5,
                       0.3 * np.sin(0.5 * t2) + 0.4, 1.3])
        c = F.forward(rd)
        for w in range(B):
            xp_, yp = 0.3 * np.cos(0.5 * t + w), 0.3 * np.sin(0.5 * t + w)
            xb, yb, zb = xp_ + 0.4 + 0.1 * np.sin(t), yp + 0.3, 1.2 + 0.2 * np.cos(t)
            if w == 2:  # at the arena's wall (x_max - margin = 2.7 m)
                xp_, xb = 2.6 + 0.1 * np.sin(t), 2.75
            if w == 3 and 20 <= k < 30:  # the UAV below the platform: the restricted fallback
                zb = -0.3
            m = np.array([xp_, yp, 0.5 * t + w + np.pi / 2, xb, yb, zb, 0.5 * t, 0.3 * np.sin(t), 0.1, 0.05, 0.2])
            m[:7] += 0.002 * rng.standard_normal(7)
            if w == 1 and (k % 7 == 3 or 42 <= k < 56):  # dropped frames, then a loss past max_hold_s
                m[:7] = np.nan
            if w == 0 and k % 11 == 5:  # a glitch: rejected
                m[3] += 2.0
            if w == 4 and k % 5 == 2:  # the Bebop's odometry lost
                m[7:9] = np.nan
            if w == 4 and k < 3:  # no frame yet
                m[:] = np.nan
            ms[k, w] = m
            cs[k, w] = np.nan if (w == 3 and 10 <= k < 15) else c  # w 3: a hold
            cds[k, w] = 0.05 * np.sin(np.arange(F.n_c) + t) * (0.0 if isinstance(F, UgvUavQuaternion) else 1.0)
    return ts, ms, cs, cds


def _per_world(kind):
    """Every world alone through ``update`` (batch ``()``): ``(u (T, B, 6), signals {k: (T, B, w)})``."""
    ctrl = UgvUavController(DESCRIPTIONS[kind](), max_hold_s=0.3)
    ts, ms, cs, cds = _inputs(ctrl.formation)
    us, sig = np.zeros((T, B, 6)), {}
    for w in range(B):
        st = ctrl.init()
        for k, t in enumerate(ts):
            if k == STOP_AT:
                st = ctrl.emergency_stop(st, "joystick")
            if k == RELEASE_AT:
                st = ctrl.release(st)
            s = ctrl.update(float(t), ms[k, w], Reference(cs[k, w], cds[k, w]), st)
            st = s.state
            us[k, w] = s.u
            for name, v in s.signals.items():
                sig.setdefault(name, np.zeros((T, B, len(v))))[k, w] = v
    return us, sig


def _sums(run):
    us, sig = run
    return float(us.sum()), float(sum(np.nan_to_num(v).sum() for v in sig.values()))


def _batched(kind, tick=None):
    """All worlds in one state through ``update`` (or ``tick`` on ``reference_arrays``)."""
    ctrl = UgvUavController(DESCRIPTIONS[kind](), max_hold_s=0.3)
    ts, ms, cs, cds = _inputs(ctrl.formation)
    st = ctrl.init((B,))
    us, sig, states = np.zeros((T, B, 6)), {}, []
    for k, t in enumerate(ts):
        if k == STOP_AT:
            st = ctrl.emergency_stop(st, "joystick")
        if k == RELEASE_AT:
            st = ctrl.release(st)
        if tick is None:
            s = ctrl.update(float(t), ms[k], Reference(cs[k], cds[k]), st)
        else:
            s = tick(st, ms[k], ctrl.reference_arrays(Reference(cs[k], cds[k])), t)
            assert not np.any(np.asarray(s.code))
        st = s.state
        states.append(st)
        us[k] = np.asarray(s.u)
        for name, v in s.signals.items():
            sig.setdefault(name, np.zeros((T, B, np.shape(v)[-1])))[k] = np.asarray(v)
    return (us, sig), states


@pytest.mark.parametrize("kind", list(DESCRIPTIONS))
def test_batched_tick_equals_each_world_alone_and_the_recorded_run(kind):
    one = _per_world(kind)
    (us, sig), states = _batched(kind)
    np.testing.assert_array_equal(us, one[0])
    for name in sig:
        np.testing.assert_array_equal(sig[name], one[1][name], err_msg=name)
    assert _sums(one) == pytest.approx(RECORDED[kind], rel=1e-12)
    # every branch ran: good, dropped and rejected frames, held frames, no frame yet, a hold
    frame = sig["frame"][..., 0]
    assert set(np.unique(frame)) == {0.0, 1.0, 2.0}
    assert sig["held"][:, 1].sum() > 0 and sig["held"][:, 0].sum() > 0
    assert np.all(np.isnan(sig["used"][:3, 4])) and np.all(sig["raw_finite"][:3, 4] == 0)
    assert np.all(np.isnan(sig["error"][10:15, 3])) and np.all(sig["robot_rates"][10:15, 3] == 0)
    assert np.all(us[10:15, 3, 0:2] == 0)  # the hold brakes the UGV
    if kind == "restricted":  # the fallback: robot space, no cluster state
        out = sig["outside"][:, 3, 0] == 1  # once the jump below the platform is plausible
        assert out.sum() >= 3 and np.all(np.isnan(sig["cluster"][out, 3]))
        assert np.all(np.isfinite(sig["robot_rates"][out, 3])) and np.any(sig["robot_rates"][out, 3] != 0)
    # the wall: no rate toward it from the UGV at 2.6 m +- 0.1 (x_max - margin = 2.7 m)
    assert np.all(sig["robot_rates"][:, 2, 0] <= 1.0 * np.maximum(0.0, 2.7 - sig["used"][:, 2, 0]) + 1e-12)
    # the emergency stop holds every world until it is released; the screen's stop stays
    stopped = sig["stopped"][..., 0]
    assert np.all(stopped[STOP_AT:RELEASE_AT] == 1) and not np.any(stopped[:STOP_AT, [0, 2, 3, 4]])
    assert np.all(stopped[RELEASE_AT:, [0, 2, 3, 4]] == 0) and stopped[-1, 1] == 1
    reasons = states[-1].stop_reason
    assert reasons.shape == (B,) and list(reasons[[0, 2, 3, 4]]) == [""] * 4
    assert reasons[1].startswith("motion capture: no good frame for 0.33 s (more than max_hold_s = 0.3 s)")
    assert list(states[STOP_AT].stop_reason) == ["joystick"] * B


def test_state_is_arrays_and_its_stop_reason_words():
    ctrl = UgvUavController(max_hold_s=0.2)
    st = ctrl.init((2, 3))
    assert st.good.shape == (2, 3, 11) and st.stopped.shape == (2, 3) and st.memory[1].v_r.shape == (2, 3, 4)
    one = ctrl.init()
    assert one.stop_reason == "" and ctrl.emergency_stop(one, "joystick").stop_reason == "joystick"
    both = ctrl.emergency_stop(ctrl.emergency_stop(one, "a"), "b")
    assert both.stop_reason == "b" and ctrl.emergency_stop(one, "a").stop_reason == "a"
    assert ctrl.release(both).stop_reason == "" and not ctrl.release(both).stopped
    assert ctrl.stop_reason(1.0, 0.5) == ("motion capture: no good frame for 0.5 s (more than max_hold_s = 0.2 s) "
                                          "from t = 0.5 s; both robots stopped")


def test_reference_arrays_checks_on_the_host_and_keeps_one_structure():
    from quatform.errors import InvalidInputError, NonFiniteError, UnreachableError

    ctrl = UgvUavController(UgvUavQuaternion())
    none = ctrl.reference_arrays(None)
    c = UgvUavQuaternion().from_chart(np.array([0.0, 0, 0, 1.0, 0.3, 0.5]))
    some = ctrl.reference_arrays(Reference(c, np.zeros(10)))
    assert none.keys() == some.keys() and np.all(np.isnan(none["c"]))
    bad = c.copy()
    bad[3] = 2.0  # not a unit quaternion: refused as the forward map's hint refuses it
    with pytest.raises(InvalidInputError, match="near_c"):
        ctrl.reference_arrays(Reference(bad, np.zeros(10)))
    with pytest.raises(NonFiniteError, match="reference.c_dot"):
        ctrl.reference_arrays(Reference(c, np.full(10, np.inf)))
    ctrl.reference_arrays(Reference(np.full(10, np.nan), np.full(10, np.nan)))  # a hold: nothing to check
    with pytest.raises(InvalidInputError, match="Reference"):
        ctrl.reference_arrays(c)
    # the restricted fallback with a reference it cannot invert: code 1, the description's words
    R = UgvUavRestricted()
    ctrl = UgvUavController(R)
    c_out = np.array([0.0, 0, 0, 1.0, 1.2, 0.1])  # alpha_f = 69 deg: outside the range
    m = np.array([0.0, 0, 0, 0.3, 0.2, -0.5, 0, 0, 0, 0, 0])  # the UAV below the platform: fallback
    ref = ctrl.reference_arrays(Reference(c_out, np.zeros(6)))
    assert not ref["invertible"]
    assert ctrl.tick(ctrl.init(), m, ref, 0.0).code == 1
    with pytest.raises(UnreachableError, match="alpha_f = 68.8 deg is outside") as err:
        ctrl.update(0.0, m, Reference(c_out, np.zeros(6)), ctrl.init())
    assert "\n" not in str(err.value)
    m_in = np.array([0.0, 0, 0, 0.3, 0.2, 1.0, 0, 0, 0, 0, 0])  # expressible: the reference is not inverted
    assert np.all(np.isfinite(ctrl.update(0.0, m_in, Reference(c_out, np.zeros(6)), ctrl.init()).u))


@pytest.mark.parametrize("kind", list(DESCRIPTIONS))
def test_jit_tick_equals_numpy(kind):
    jax = pytest.importorskip("jax")
    ctrl = UgvUavController(DESCRIPTIONS[kind](), max_hold_s=0.3)
    from quatform.control.contract import Tick

    def fields(*args):  # a Tick's fields (Tick itself is not a pytree)
        k = ctrl.tick(*args)
        return k.state, k.u, dict(k.signals), k.code

    compiled = jax.jit(fields)

    def tick(*args):
        return Tick(*compiled(*args))

    with jax.enable_x64(True):
        (us, sig), states = _batched(kind, tick)
        leaves = jax.tree_util.tree_leaves(states[-1])
    (us0, sig0), states0 = _batched(kind)
    assert len(leaves) == 11
    np.testing.assert_allclose(us, us0, rtol=0, atol=1e-9)
    for name in sig:
        np.testing.assert_array_equal(np.isnan(sig[name]), np.isnan(sig0[name]), err_msg=name)
        np.testing.assert_allclose(sig[name], sig0[name], rtol=0, atol=1e-9, err_msg=name)
    assert list(states[-1].stop_reason) == list(states0[-1].stop_reason)
    np.testing.assert_allclose(np.asarray(states[-1].v_dot), states0[-1].v_dot, rtol=0, atol=1e-9)


#: A robot model's arrays ordered by its columns: a subscript of one with a hand-written
#: number is a hand-written entry however it is written.
_COLUMN_ARRAYS = ("max_velocity", "k_u", "k_v", "l_d")


def _literal_entries(fn) -> list:
    """The subscripts of ``fn``'s source that pick entries after the leading axes with
    hand-written numbers (``x[..., 3:6]``, ``u[:, 2]``, ``m[:, [0, 1]]``), and any subscript
    with a number of a robot model's column-ordered array (``bebop.max_velocity[0:3]``,
    :data:`_COLUMN_ARRAYS`); ``[:, 0]`` of a one-column channel and ``None`` (a new axis)
    are not entries."""
    import ast
    import inspect
    import textwrap

    def literal(e):
        if isinstance(e, ast.Slice):
            return any(isinstance(b, ast.Constant) and isinstance(b.value, int) for b in (e.lower, e.upper))
        if isinstance(e, ast.List):
            return any(isinstance(v, ast.Constant) for v in e.elts)
        return isinstance(e, ast.Constant) and isinstance(e.value, int) and e.value != 0

    out = []
    for node in ast.walk(ast.parse(textwrap.dedent(inspect.getsource(fn)))):
        if not isinstance(node, ast.Subscript):
            continue
        if isinstance(node.slice, ast.Tuple):
            if any(literal(e) for e in node.slice.elts[1:]):
                out.append(ast.unparse(node))
        elif isinstance(node.value, ast.Attribute) and node.value.attr in _COLUMN_ARRAYS and (
                literal(node.slice) or isinstance(node.slice, ast.Constant)):
            out.append(ast.unparse(node))
    return out


def test_the_literal_entry_check_sees_what_it_forbids():
    """The source check finds hand-written entries, and lets a channel's one column, a new
    axis and named entries through."""

    def bad(x, m, u, bebop):
        return x[..., 3:6], u[:, 2], m[:, [0, 1]], bebop.max_velocity[0:3], bebop.k_u[0]

    def fine(x, log, bebop, UGV_XY, PSI_P):
        return x[..., UGV_XY], x[..., PSI_P, None], log["frame"][:, 0], x[..., :UGV_XY.stop], bebop.max_speed

    assert _literal_entries(bad) == ["x[..., 3:6]", "u[:, 2]", "m[:, [0, 1]]", "bebop.max_velocity[0:3]",
                                     "bebop.k_u[0]"]
    assert _literal_entries(fine) == []


def test_pioneer_bebop_entries_are_named():
    """The tick, the finish and the metrics read the Pioneer-Bebop state, commands and the
    descriptions' variables through named entries derived from the robot models' columns, the
    team's slices and the layout, never hand-written numbers."""
    from quatform.control import ugv_uav as ctrl
    from quatform.robots import Bebop, Pioneer
    from quatform.scenarios import ugv_uav as scen
    from quatform.sim.measurement import MotionCapture
    from quatform.sim.plants.ugv_uav import PioneerBebopPlant

    fns = (UgvUavController.__init__, UgvUavController.tick, UgvUavController.measured_points,
           UgvUavController.reference_arrays, scen._measured_robots, scen._finish, scen.ugv_uav_metrics,
           scen._cluster_jumps, scen.UgvUavScenario.e_reference, MotionCapture.init, MotionCapture.read,
           MotionCapture.frame_pose, MotionCapture._orientation, PioneerBebopPlant.initial_state,
           PioneerBebopPlant.output, PioneerBebopPlant.step)
    found = {f"{fn.__module__}.{fn.__qualname__}": _literal_entries(fn) for fn in fns}
    assert found == {name: [] for name in found}
    names = ctrl.UGV_UAV_MEASURED_NAMES
    assert MotionCapture.columns is names and PioneerBebopPlant.output_columns is names
    # a frame's pose is the measured values' first entries, in the order MotionCapture.frame_pose writes them
    assert ctrl.MOCAP_PART.start == 0
    assert names[ctrl.MOCAP_PART] == (*names[ctrl.UGV_XY], names[ctrl.PSI_P], *names[ctrl.UAV_XYZ], names[ctrl.PSI_B])
    assert names[ctrl.PSI_P] == "psi_p" and names[ctrl.PSI_B] == "psi_b"
    assert names[ctrl.UGV_XY] == ("x_p", "y_p") and names[ctrl.UAV_XYZ] == ("x_b", "y_b", "z_b")
    assert names[ctrl.ODOMETRY_PART] == tuple(c + "_b" for c in Bebop.state_columns[4:])
    assert ctrl.UGV_UAV_COMMAND_NAMES[ctrl.BEBOP_COMMAND] == tuple(c + "_b" for c in Bebop.command_columns)
    assert ctrl.UGV_UAV_COMMAND_NAMES[ctrl.V_P] == Pioneer.command_columns[0] + "_p"


@pytest.mark.parametrize("kind", sorted(DESCRIPTIONS))
def test_a_measured_position_beyond_the_magnitude_limit_names_its_robot_and_column(kind):
    """One world and a batch: the error names the robot, its state column, the value and unit,
    the world of a batch, and the fix."""
    from quatform.errors import InvalidInputError

    ctrl = UgvUavController(DESCRIPTIONS[kind]())
    good = np.array([0.0, 0.0, 0.0, 0.5, 0.4, 1.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    for entry, words in ((5, r"measured bebop z = 1e\+200 m"), (0, r"measured pioneer x = -3e\+160 m")):
        bad = good.copy()
        bad[entry] = 1e200 if entry == 5 else -3e160
        fix = r"is beyond the 1e\+150 quatform accepts .*; express the state in larger units or nearer the origin"
        with pytest.raises(InvalidInputError, match=rf"^{kind} controller: {words} {fix}$"):
            ctrl.step(0.0, bad)
        with pytest.raises(InvalidInputError, match=rf"^{kind} controller: {words} in world \(1,\) {fix}$"):
            ctrl.step(0.0, np.stack([good, bad, bad]))
