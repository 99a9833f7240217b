"""Seed 003 closed loop, free motion: the slave follows the master the hand moves."""

from __future__ import annotations

import numpy as np

from quatform.sim.teleop import TeleopSetup, simulate_teleop


def test_free_motion_slave_follows_and_errors_converge():
    run = simulate_teleop(TeleopSetup(duration_s=4.0))
    assert np.all(run.tau_finite)
    moved = np.linalg.norm(run.p_m[-1] - run.p_m[0])
    assert moved > 0.06  # the hand moved the master ~7 cm
    err = np.linalg.norm(run.p_s - run.p_m, axis=1)
    after = run.t >= run.setup.move_time_s + 0.5
    assert err[-1] < 0.005 and err[-1] < err[after][0]  # position error small and shrinking
    peak = run.angle.max()
    assert 0.05 < peak < 0.5 and run.angle[-1] < 0.6 * peak  # orientation error converging
    # the slave's tool moved as much as the master's (in the slave's workspace)
    np.testing.assert_allclose(np.linalg.norm(run.p_s[-1] - run.p_s[0]), moved, atol=0.005)
