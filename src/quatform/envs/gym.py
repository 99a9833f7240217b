"""Gymnasium's ``Env`` and batched ``VectorEnv`` of a scenario, on the functional core (envs layer).

``gymnasium.make("quatform/Formation-v0", scenario=...)`` builds :class:`FormationEnv` and
``gymnasium.make_vec("quatform/Formation-v0", num_envs=N, vectorization_mode="vector_entry_point",
scenario=...)`` builds :class:`FormationVectorEnv`: one :class:`~.core.FormationCore` steps
the ``N`` worlds at once on a leading batch axis (not ``N`` copies), resetting a world the
step after its episode ended (gymnasium's next-step autoreset). Both draw each episode's key
from the generator ``reset(seed=...)`` seeds (world ``i`` of a vector env from ``seed + i``,
as the ``i``-th of ``N`` single envs), and split it at every step (:func:`~.core.split`), so a
seed reproduces its episode, the measurement noise included (``docs/envs.md``).

gymnasium is imported here only (``pip install -e ".[envs]"``).
"""

from __future__ import annotations

import numpy as np

from ..checks import short
from ..errors import InvalidInputError, MissingDependencyError
from ..sim.loop import tree_map
from .core import OBS_BOUND, Rebuilt, functional, host_action, split

try:
    import gymnasium
    from gymnasium.utils import seeding
    from gymnasium.vector import AutoresetMode, VectorEnv
    from gymnasium.vector.utils import batch_space
except ImportError:
    raise MissingDependencyError('the learning environments need gymnasium: pip install -e ".[envs]"') from None

__all__ = ["FormationEnv", "FormationVectorEnv", "ENV_ID"]

#: The registered id (:mod:`quatform.envs` registers it on import).
ENV_ID = "quatform/Formation-v0"


def _spaces(core):
    obs = gymnasium.spaces.Box(-OBS_BOUND, OBS_BOUND, (core.n_obs,), np.float64)
    act = gymnasium.spaces.Box(-1.0, 1.0, (core.n_u,), np.float64)
    return obs, act


def _episode_key(rng) -> np.ndarray:
    """An episode's key ``uint32 (2,)`` drawn from the env's generator."""
    return rng.integers(0, 2 ** 32, size=2, dtype=np.uint32)


def _info(info: dict) -> dict:
    return {k: np.asarray(v) for k, v in info.items()}


class FormationEnv(Rebuilt, gymnasium.Env):
    """One world of a team or network scenario (:func:`~.core.functional`'s arguments).

    Observation ``Box(-OBS_BOUND, OBS_BOUND, (n_obs,), float64)``, action ``Box(-1, 1, (n_u,), float64)``
    (:class:`~.core.FormationCore`); ``info`` holds the reward's terms, the smallest
    separation, the position error and why an episode ended.
    """

    metadata = {"render_modes": []}
    _episode = ("_np_random", "_np_random_seed", "_key", "_state", "observation_space", "action_space")

    def __init__(self, scenario: str = "team-tetrahedron-helix", controller: str | None = None,
                 action: str = "residual", render_mode=None, **options):
        self._init = ((), dict(scenario=scenario, controller=controller, action=action, render_mode=render_mode,
                               **options))
        self.core = functional(scenario, controller, action=action, **options)
        self.params = self.core.default_params
        self.observation_space, self.action_space = _spaces(self.core)
        self.render_mode = render_mode
        self._key = None
        self._state = None

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._key = _episode_key(self.np_random)
        self._key, first = split(self._key)
        obs, self._state = self.core.reset(first, self.params)
        return obs, {}

    def step(self, action):
        if self._state is None:
            raise InvalidInputError("FormationEnv.step: call reset() before step()")
        self._key, now = split(self._key)
        a = host_action(action, (self.core.n_u,), "FormationEnv.step")
        obs, self._state, reward, terminated, truncated, info = self.core.step(now, self._state, a, self.params)
        return obs, float(reward), bool(terminated), bool(truncated), _info(info)


class FormationVectorEnv(Rebuilt, VectorEnv):
    """``num_envs`` worlds of one scenario stepped as one batch by the functional core.

    Autoreset: gymnasium's next-step mode (``metadata["autoreset_mode"]``): the step after a
    world's episode ended resets it (its action is ignored; reward 0, not terminated, not
    truncated). ``info`` holds each term as an array ``(num_envs, ...)`` with its ``_name``
    mask, as gymnasium's ``SyncVectorEnv`` batches single envs' infos: a world reset at this
    step has no terms (mask False, entries 0); a step that resets every world has ``{}``.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    _episode = ("_rngs", "_keys", "_state", "_ended", "observation_space", "action_space", "single_observation_space",
                "single_action_space")

    def __init__(self, num_envs: int = 1, scenario: str = "team-tetrahedron-helix", controller: str | None = None,
                 action: str = "residual", render_mode=None, **options):
        self._init = ((), dict(num_envs=num_envs, scenario=scenario, controller=controller, action=action,
                               render_mode=render_mode, **options))
        self.core = functional(scenario, controller, action=action, **options)
        self.params = self.core.default_params
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise InvalidInputError(f"FormationVectorEnv: num_envs = {short(num_envs)} must be a whole number >= 1")
        self.num_envs = int(num_envs)
        self.single_observation_space, self.single_action_space = _spaces(self.core)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = render_mode
        self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        self._keys = self._state = None
        self._ended = np.zeros(self.num_envs, dtype=bool)

    def _seeds(self, seed) -> list:
        """The worlds' seeds of ``reset(seed=...)``: ``seed + i`` of a whole number, or one per
        world (whole numbers or ``None``), else a one-line error."""
        def whole(s):
            return isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s >= 0

        if whole(seed):
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed) if isinstance(seed, (list, tuple, np.ndarray)) else None
        if seeds is None or len(seeds) != self.num_envs or not all(s is None or whole(s) for s in seeds):
            raise InvalidInputError(f"FormationVectorEnv.reset: seed = {short(seed)} must be a whole number >= 0 or "
                                    f"{self.num_envs} of them (one per world, None for an unseeded one)")
        return [None if s is None else int(s) for s in seeds]

    def _draw(self, which) -> np.ndarray:
        """New episode keys ``(num_envs, 2)`` of the worlds ``which`` (bool) from their generators."""
        keys = np.zeros((self.num_envs, 2), dtype=np.uint32) if self._keys is None else self._keys.copy()
        for i in np.flatnonzero(which):
            keys[i] = _episode_key(self._rngs[i])
        return keys

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._rngs = [seeding.np_random(s)[0] for s in self._seeds(seed)]
        self._keys = self._draw(np.ones(self.num_envs, dtype=bool))
        self._keys, first = split(self._keys)
        obs, self._state = self.core.reset(first, self.params)
        self._ended[:] = False
        return obs, {}

    def step(self, actions):
        if self._state is None:
            raise InvalidInputError("FormationVectorEnv.step: call reset() before step()")
        self._keys, now = split(self._keys)
        a = host_action(actions, (self.num_envs, self.core.n_u), "FormationVectorEnv.step")
        obs, state, reward, terminated, truncated, info = self.core.step(now, self._state, a, self.params)
        ended = self._ended
        if ended.any():  # next-step autoreset: these worlds start again
            fresh, first = split(self._draw(ended))  # the other worlds' keys go on as they are
            self._keys = np.where(ended[:, None], fresh, self._keys)
            obs0, state0 = self.core.reset(first, self.params)
            state = tree_map(lambda a0, a1: _select(ended, a0, a1), state0, state)
            obs = np.where(ended[:, None], obs0, obs)
            reward = np.where(ended, 0.0, reward)
            terminated, truncated = terminated & ~ended, truncated & ~ended
        self._state = state
        self._ended = np.asarray(terminated | truncated)
        out = {}
        if not ended.all():  # gymnasium's SyncVectorEnv: a reset world's info is its reset's ({})
            for k, v in _info(info).items():
                out[k], out["_" + k] = _select(ended, np.zeros_like(v), v), ~ended
        return obs, np.asarray(reward, dtype=np.float64), np.asarray(terminated), np.asarray(truncated), out


def _select(mask, a, b):
    """``a`` where ``mask`` (``(num_envs,)``) else ``b``, over the trailing axes."""
    a, b = np.asarray(a), np.asarray(b)
    return np.where(mask.reshape(mask.shape + (1,) * (max(a.ndim, b.ndim) - 1)), a, b)
