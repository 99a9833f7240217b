"""PettingZoo's ``ParallelEnv`` of a scenario: one agent per robot, on the functional core (envs layer).

Agent ``robot_i`` acts with its own commands (a residual on the scenario controller's, or the
commands themselves: the core's ``action``) and observes, in order: its measured point, its
error against its desired point (yaws wound), its neighbours (``slots`` rows of ``(valid, dx,
dy, dz, age_s)``: a neighbour's position relative to its own) and the episode's elapsed
fraction. Its neighbours are

* in a network scenario, what its inbox delivered at the last tick through the links
  (delays, losses, stale messages, radio range: :meth:`NetworkedController.received`): the
  sender's position when it sent, the message's age; a slot without a valid message reads 0;
* in any other team scenario, its ``neighbours`` nearest robots by measured position (age 0).

Its reward is its own share of the core's: ``-(w_t |e_i|^2 + w_e |u_i|^2 + w_s sum_j max(0,
d_sep - d_ij)^2 / 2)``, or ``-loss_penalty`` where the loop failed. The episode ends for every
agent at once (collision, loss, the scenario's duration). pettingzoo is imported here only
(``pip install -e ".[envs]"``).
"""

from __future__ import annotations

import functools

import numpy as np

from ..checks import short
from ..errors import InvalidInputError, MissingDependencyError
from ..formations.team_chart import team_positions
from .core import OBS_BOUND, Rebuilt, bounded, functional, host_action, split

try:
    import gymnasium
    from pettingzoo import ParallelEnv
except ImportError:
    raise MissingDependencyError('the multi-agent environment needs pettingzoo and gymnasium: '
                                 'pip install -e ".[envs]"') from None

__all__ = ["FormationParallelEnv"]


class FormationParallelEnv(Rebuilt, ParallelEnv):
    """One agent per robot of a team or network scenario (module docstring; the arguments of
    :func:`~.core.functional`, and ``neighbours``: how many nearest robots a team scenario's
    agent observes)."""

    metadata = {"render_modes": [], "name": "quatform_formation_v0", "is_parallelizable": True}
    _episode = ("_rng", "_key", "_state", "agents", "_spaces")

    def __init__(self, scenario: str = "team-tetrahedron-helix", controller: str | None = None,
                 action: str = "residual", neighbours: int | None = None, render_mode=None, **options):
        self._init = ((), dict(scenario=scenario, controller=controller, action=action, neighbours=neighbours,
                               render_mode=render_mode, **options))
        self.core = core = functional(scenario, controller, action=action, **options)
        self.params = core.default_params
        team, L = core.team, core.layout
        self.possible_agents = [f"robot_{i}" for i in range(L.n)]
        self.agents = []
        self.render_mode = render_mode
        base = core.controller.base
        self.networked = hasattr(base, "received") and hasattr(base, "links")
        if self.networked:
            if neighbours is not None:
                raise InvalidInputError(f"parallel_env: neighbours = {short(neighbours)} is for a team scenario; a "
                                        "network scenario's agent observes its in-neighbours of the graph (drop it)")
            self.slots = int(base.slot_weights.shape[-1])  # the largest in-degree
        else:
            neighbours = 3 if neighbours is None else neighbours
            if not (isinstance(neighbours, (int, np.integer)) and not isinstance(neighbours, bool) and neighbours >= 1):
                raise InvalidInputError(f"parallel_env: neighbours = {short(neighbours)} must be a whole number >= 1")
            self.slots = min(int(neighbours), L.n - 1)
        self._points = [np.arange(L.slice(i).start, L.slice(i).stop) for i in range(L.n)]
        self._commands = [np.arange(s.start, s.stop) for s in team.command_slices]
        self._key = self._state = None

    # -- spaces (one object per agent, held by the env: a seeded space stays seeded) -----------
    @functools.cached_property
    def _spaces(self) -> dict:
        """``{agent: (observation space, action space)}`` of this env (built once, freed with it)."""
        out = {}
        for i, agent in enumerate(self.possible_agents):
            n = 2 * len(self._points[i]) + 5 * self.slots + 1
            out[agent] = (gymnasium.spaces.Box(-OBS_BOUND, OBS_BOUND, (n,), np.float64),
                          gymnasium.spaces.Box(-1.0, 1.0, (len(self._commands[i]),), np.float64))
        return out

    def observation_space(self, agent):
        return self._spaces[self._agent(agent)][0]

    def action_space(self, agent):
        return self._spaces[self._agent(agent)][1]

    def _agent(self, agent) -> str:
        """``agent`` if it is one of this env's, else a one-line error."""
        if not isinstance(agent, str) or agent not in self._spaces:
            raise InvalidInputError(f"parallel_env: no agent {short(agent)}; the agents are robot_0 .. "
                                    f"robot_{len(self.possible_agents) - 1}")
        return agent

    # -- the episode ------------------------------------------------------------------------
    def reset(self, seed=None, options=None):
        if seed is not None or not hasattr(self, "_rng"):
            self._rng = np.random.default_rng(seed)
        self._key, first = split(self._rng.integers(0, 2 ** 32, size=2, dtype=np.uint32))
        _, self._state = self.core.reset(first, self.params)
        self.agents = list(self.possible_agents)
        return self._observe(), {a: {} for a in self.agents}

    def step(self, actions):
        if self._state is None:
            raise InvalidInputError("parallel_env.step: call reset() before step()")
        if not self.agents:
            return {}, {}, {}, {}, {}
        u = np.zeros(self.core.n_u)
        for a, act in actions.items():
            cols = self._commands[self.possible_agents.index(self._agent(a))]
            u[cols] = host_action(act, (len(cols),), f"parallel_env.step: {a}")
        self._key, now = split(self._key)
        _, state, _, terminated, truncated, info = self.core.step(now, self._state, u, self.params)
        self._state = state
        per = info["robot_rewards"]
        rewards = {a: float(per[i]) for i, a in enumerate(self.possible_agents)}
        obs = self._observe()
        done_t, done_tr = bool(terminated), bool(truncated)
        agents = self.agents
        terms = {a: done_t for a in agents}
        truncs = {a: done_tr for a in agents}
        infos = {a: {"min_separation_m": float(info["min_separation_m"]), "reason": int(info["reason"])}
                 for a in agents}
        out = ({a: obs[a] for a in agents}, {a: rewards[a] for a in agents}, terms, truncs, infos)
        if done_t or done_tr:
            self.agents = []
        return out

    # -- what an agent reads ------------------------------------------------------------------
    def _neighbours(self, state, m):
        """``(N, slots, 5)``: each robot's neighbour rows ``(valid, dx, dy, dz, age_s)``."""
        core = self.core
        p = team_positions(core.layout, m)
        if self.networked:
            base = core.controller.base
            k = max(int(state.k) - 1, 0)
            links = {key: np.asarray(v)[k] for key, v in self.params.refs[1].items()}
            t = float(self.params.times[k])
            box, sender, _ = base.received(state.ctrl["links"], links, p, t)
            valid = np.asarray(box["valid"], dtype=bool) & (int(state.k) > 0)  # no tick yet: nothing delivered
            rel = np.where(valid[..., None], np.asarray(sender) - p[:, None, :], 0.0)
            age = np.where(valid, t - np.where(valid, np.asarray(box["stamps"]), 0.0), 0.0)
            return np.concatenate([valid[..., None].astype(float), rel, age[..., None]], axis=-1)
        d = np.linalg.norm(p[None, :, :] - p[:, None, :], axis=-1)
        np.fill_diagonal(d, np.inf)  # a robot is not its own neighbour
        near = np.argsort(d, axis=-1, kind="stable")[:, :self.slots]
        rel = p[near] - p[:, None, :]
        return np.concatenate([np.ones(near.shape + (1,)), rel, np.zeros(near.shape + (1,))], axis=-1)

    def _observe(self) -> dict:
        core, state = self.core, self._state
        _, e_r, m, frac = core.observed(state, self.params, chart=False)
        rows = self._neighbours(state, m)
        return {a: bounded(np, np.concatenate([m[self._points[i]], e_r[self._points[i]], rows[i].ravel(), frac]))
                for i, a in enumerate(self.possible_agents)}

    def state(self):
        """The plant state of every robot ``(n_x,)`` (the global state)."""
        return np.asarray(self._state.x, dtype=float)
