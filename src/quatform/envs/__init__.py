"""Learning environments over the team and network scenarios (envs layer, beside runs and cli).

* :func:`functional` - the pure functional core (:class:`~.core.FormationCore`:
  ``reset(key, params)``, ``step(key, state, action, params)``) on NumPy or JAX;
* ``gymnasium.make("quatform/Formation-v0", scenario=...)`` and ``gymnasium.make_vec(...)``
  (registered when gymnasium is installed: ``pip install -e ".[envs]"``);
* :func:`parallel_env` - the PettingZoo ``ParallelEnv``, one agent per robot;
* :func:`compiler_options` - the ``compiler_options`` of ``jax.jit`` for the core on JAX's CPU
  (:func:`quatform.sim.jax_devices.compiler_options`).

``docs/envs.md`` documents observations, actions, rewards and the episode's end.
"""

from __future__ import annotations

from ..sim.jax_devices import compiler_options
from .core import (ACTION_MODES, OBS_BOUND, ActionController, EnvParams, EnvState, FormationCore, functional, key,
                   normal, split)

__all__ = ["ACTION_MODES", "OBS_BOUND", "ActionController", "EnvParams", "EnvState", "FormationCore", "compiler_options",
           "functional", "key", "normal", "parallel_env", "split"]


def parallel_env(scenario: str = "team-tetrahedron-helix", **options):
    """The PettingZoo ``ParallelEnv`` of ``scenario`` (:class:`.parallel.FormationParallelEnv`)."""
    from .parallel import FormationParallelEnv

    return FormationParallelEnv(scenario, **options)


def _register() -> None:
    """Register ``quatform/Formation-v0`` with gymnasium, where it is installed (entry points
    as strings: gymnasium imports :mod:`.gym` when an env is made)."""
    try:
        import gymnasium
    except ImportError:
        return
    if "quatform/Formation-v0" not in gymnasium.registry:
        gymnasium.register(id="quatform/Formation-v0", entry_point="quatform.envs.gym:FormationEnv",
                           vector_entry_point="quatform.envs.gym:FormationVectorEnv")


_register()
