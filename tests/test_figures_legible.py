"""Figures a reader of the seeds recognises: seed 002's paths by alpha (a legend naming each
alpha, one equal x-y scale) and the replay's commands (units on the axes, the commands drawn
over the noisy measured rate)."""

from __future__ import annotations

import numpy as np
import pytest

from quatform.planning import load_plan_spec, make_plan
from quatform.report.plan_plots import plot_alpha_panels
from quatform.report.replay_plots import column_unit, replay_commands_figure
from quatform.robots import HolonomicRobot, Team


@pytest.fixture(scope="module")
def two_bodies():
    import dataclasses

    spec = load_plan_spec("belta-kumar-2002-two-bodies")
    return {a: make_plan(dataclasses.replace(spec, options={**spec.options, "alpha": a}))[0] for a in (0.99, 0.5, 0.2)}


def test_paths_by_alpha_names_each_alpha_on_one_equal_scale(two_bodies):
    fig = plot_alpha_panels(two_bodies, "seed 002 Fig. 3")
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 3
    named = [t.get_text() for ax in axes for t in ax.get_legend().get_texts()]
    assert named == ["α = 0.2", "α = 0.5", "α = 0.99"]  # the seed's order: 0.2 on top
    for ax in axes:
        assert ax.get_aspect() == 1.0  # one metre is as long on x as on y
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
        assert ax.get_xlim() == axes[0].get_xlim() and ax.get_ylim() == axes[0].get_ylim()
    shared = [t.get_text() for t in fig.legends[0].get_texts()]
    assert shared[:2] == ["robot 1 (m = 1 kg), geodesic of the shaped metric",
                          "robot 2 (m = 2 kg), geodesic of the shaped metric"]
    assert "optimal rigid motion (SE(2))" in shared
    fig.canvas.draw()  # draws (constrained layout with equal aspect) without error


def _replay_figure(noise=0.002):
    team = Team.uniform(HolonomicRobot(), 2)
    t = np.arange(0.0, 3.0, 0.01)
    rng = np.random.default_rng(0)
    u = np.zeros((t.size, 8))
    u[:, 1] = u[:, 5] = 0.1  # v_y of both robots
    x = np.zeros((t.size, 8))
    x[:, 1] = x[:, 5] = 0.1 * t
    x[:, 2] = x[:, 6] = 2.0
    x = x + rng.normal(0.0, noise, x.shape)
    held = np.zeros(t.size, dtype=bool)
    held[100:120] = True
    names = ["u_x1", "u_y1", "u_z1", "u_theta1", "u_x2", "u_y2", "u_z2", "u_theta2"]
    return replay_commands_figure(t, x, u, held, ["r1", "r2"], team.robots, team.state_slices, team.command_slices,
                                  names)


def test_replay_commands_have_units_and_lie_over_the_measured_rate():
    fig = _replay_figure()
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 8  # per robot: m, rad | m/s, rad/s
    units = sorted(ax.get_ylabel().split("[")[-1].rstrip("]") for ax in axes)
    assert units == ["m", "m", "m/s", "m/s", "rad", "rad", "rad/s", "rad/s"]
    assert all(ax.get_xlabel() == "time since the first tick [s]" for ax in axes[-2:])
    for ax in axes:
        if "command" not in ax.get_ylabel():
            continue
        lines = {g: [ln for ln in ax.get_lines() if ln.get_gid() == g]
                 for g in ("command", "measured rate", "measured rate mean")}
        assert lines["command"] and len(lines["measured rate"]) == len(lines["command"])
        for cmd, raw, mean in zip(lines["command"], lines["measured rate"], lines["measured rate mean"]):
            assert cmd.get_zorder() > mean.get_zorder() > raw.get_zorder()
            assert raw.get_alpha() < 0.5 and raw.get_linewidth() < cmd.get_linewidth()
            assert cmd.get_alpha() in (None, 1.0)
        # the y-range follows the commands and the rate's mean, not the per-tick noise
        lo, hi = ax.get_ylim()
        raw = np.concatenate([ln.get_ydata() for ln in lines["measured rate"]])
        assert hi - lo < 0.5 * (raw.max() - raw.min())
        cmd = np.concatenate([ln.get_ydata() for ln in lines["command"]])
        assert lo <= cmd.min() and cmd.max() <= hi


def test_column_units():
    assert [column_unit(c) for c in ("x", "theta", "v_x", "omega_z", "v", "omega", "u_psi", "psi_dot")] == [
        "m", "rad", "m/s", "rad/s", "m/s", "rad/s", "-", "rad/s"]
