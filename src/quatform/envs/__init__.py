"""Learning environments over the team and network scenarios (envs layer, beside runs and cli).

* :func:`functional` - the pure functional core (:class:`~.core.FormationCore`:
  ``reset(key, params)``, ``step(key, state, action, params)``) on NumPy or JAX;
* ``gymnasium.make("quatform/Formation-v0", scenario=...)`` and ``gymnasium.make_vec(...)``
  (registered when gymnasium is installed: ``pip install -e ".[envs]"``);
* :func:`parallel_env` - the PettingZoo ``ParallelEnv``, one agent per robot.

``docs/envs.md`` documents observations, actions, rewards and the episode's end.
"""

from __future__ import annotations

from .core import (ACTION_MODES, ActionController, EnvParams, EnvState, FormationCore, functional, key, normal,
                   split)

__all__ = ["ACTION_MODES", "ActionController", "EnvParams", "EnvState", "FormationCore", "functional", "key",
           "normal", "split"]
