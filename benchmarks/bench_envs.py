"""Learning environments: env steps per second of one scenario on NumPy and JAX.

Three drivers of the one functional core (:mod:`quatform.envs`), zero residual actions,
measurement noise on (``--noise-m``):

* ``gymnasium`` - ``gymnasium.make("quatform/Formation-v0")``, one world, ``env.step``;
* ``vector`` - ``gymnasium.make_vec(..., num_envs=N, vectorization_mode="vector_entry_point")``,
  N worlds on one batch axis (NumPy), ``N`` env steps a call;
* ``jax`` - ``jax.jit(jax.vmap(core.step))`` over ``B`` keys (float64), called from Python,
  and ``jax.lax.scan`` of ``--scan`` such steps in one call (the policy-free rollout an
  evolution strategy runs); compiled before the timing.

Agent steps (robot-steps) are env steps times the scenario's robots.

Usage: ``python benchmarks/bench_envs.py [--scenario team-tetrahedron-helix] [--num-envs 64]
[--batch 1024] [--scan 100] [--repeat 3]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import best_of, machine_description, optional_import


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="team-tetrahedron-helix")
    ap.add_argument("--num-envs", type=int, default=64)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--scan", type=int, default=100)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--noise-m", type=float, default=0.002)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    gymnasium = optional_import("gymnasium")
    import quatform.envs  # noqa: F401  (registers quatform/Formation-v0)
    from quatform.envs import compiler_options, functional, key

    print("\n".join(machine_description({name: optional_import(name) is not None
                                         for name in ("gymnasium", "pettingzoo", "jax")})))
    core = functional(args.scenario, noise_m=args.noise_m)
    n_rob = core.layout.n
    rows = []
    if gymnasium is not None:
        env = gymnasium.make("quatform/Formation-v0", scenario=args.scenario, noise_m=args.noise_m).unwrapped
        zero = np.zeros(env.action_space.shape)

        def run_single():
            env.reset(seed=0)
            for _ in range(args.steps):
                env.step(zero)

        t = best_of(run_single, args.repeat) / args.steps
        rows.append(("gymnasium Env (NumPy)", 1, 1 / t))
        venv = gymnasium.make_vec("quatform/Formation-v0", num_envs=args.num_envs,
                                  vectorization_mode="vector_entry_point", scenario=args.scenario,
                                  noise_m=args.noise_m)
        zeros = np.zeros(venv.action_space.shape)

        def run_vector():
            venv.reset(seed=0)
            for _ in range(args.steps // 4):
                venv.step(zeros)

        t = best_of(run_vector, args.repeat) / (args.steps // 4)
        rows.append((f"gymnasium VectorEnv (NumPy, N = {args.num_envs})", args.num_envs, args.num_envs / t))
    jax = optional_import("jax")
    if jax is not None:
        import jax.numpy as jnp

        B = args.batch
        with jax.enable_x64(True):
            p = jax.tree_util.tree_map(jnp.asarray, core.default_params)
            keys = jnp.asarray(np.stack([key(s) for s in range(B)]))
            options = compiler_options(jax)
            reset = jax.jit(jax.vmap(core.reset, in_axes=(0, None)), compiler_options=options)
            step = jax.jit(jax.vmap(core.step, in_axes=(0, 0, 0, None)), compiler_options=options)
            act = jnp.zeros((B, core.n_u))
            _, s0 = reset(keys, p)
            out = step(keys, s0, act, p)
            jax.block_until_ready(out)

            def run_jax():
                s = s0
                for j in range(args.steps // 4):
                    s = step(keys + np.uint32(j), s, act, p)[1]
                jax.block_until_ready(s)

            t = best_of(run_jax, args.repeat) / (args.steps // 4)
            rows.append((f"JAX jit(vmap(step)), B = {B}", B, B / t))

            def body(s, j):
                o, s, r, *_ = jax.vmap(core.step, in_axes=(0, 0, 0, None))(keys + j.astype(jnp.uint32), s, act, p)
                return s, r

            scan = jax.jit(lambda s: jax.lax.scan(body, s, jnp.arange(args.scan))[1], compiler_options=options)
            jax.block_until_ready(scan(s0))
            t = best_of(lambda: jax.block_until_ready(scan(s0)), args.repeat) / args.scan
            rows.append((f"JAX jit(scan(vmap(step))), B = {B}", B, B / t))
    print(f"scenario {args.scenario}: {n_rob} robots, {core.n_obs} observations, {core.n_u} commands")
    print(f"{'driver':48s} {'env steps/s':>14s} {'agent steps/s':>14s}")
    for name, _, rate in rows:
        print(f"{name:48s} {rate:14.4g} {rate * n_rob:14.4g}")


if __name__ == "__main__":
    main()
