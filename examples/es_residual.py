"""Evolution strategies train a residual policy on a team scenario under motion-capture noise.

The environment is quatform's functional core (:func:`quatform.envs.functional`) in residual
mode: the policy's action ``a`` in ``[-1, 1]`` adds ``residual_scale * a`` (times each
command's limit) to the scenario controller's commands, so the zero policy *is* the base
controller. Every reading carries motion-capture noise (``--noise-m`` m on positions,
``--noise-rad`` rad on yaws, the core's ``noise_m``/``noise_rad``) and every episode starts
with the robots displaced from the scenario's start (``--start-noise-m``).

The policy is ``a = tanh(W z + b)`` (``--hidden 0``, linear) or a one-hidden-layer network
``a = tanh(W2 tanh(W1 z + b1) + b2)``, on the observation ``z`` standardised by the mean
and standard deviation the base controller's episodes show; its last layer starts at zero
(the base controller). It is trained with OpenAI-ES (Salimans et al. 2017, "Evolution
Strategies as a Scalable Alternative to Reinforcement Learning", Algorithm 1 with
antithetic sampling ``theta +- sigma eps`` and centred-rank fitness shaping) and Adam (Kingma
and Ba 2015, Algorithm 1) on the estimated gradient, all in ``jax.numpy``: each generation
evaluates ``--population`` perturbed policies on ``--episodes`` common training episodes
(keys of the generation), the whole population's episodes at once
(``jax.vmap`` of a ``lax.scan`` over the core's ``step``, one ``jax.jit``; with
``--episodes`` equal to ``--eval-episodes`` and a population of 2 the run compiles once).

After every generation the mean policy and the base controller run the same held-out
episodes (keys no training episode uses). The script prints and writes the learning curve
``--out/curve.csv`` (generation, mean and best training return of the population, the
policy's and the base controller's held-out return) and ``--out/curve.png``.

Usage::

    python examples/es_residual.py --generations 60 --population 32 --out es_out
    python examples/es_residual.py --help

A return is the sum of the core's per-step rewards over an episode (until it terminates),
``-(tracking + 0.01 effort + 10 separation)`` per step by default (``docs/envs.md``).

Measured (the defaults: ``team-tetrahedron-helix``'s quaternion controller, its separation
barrier filtering the policy's command too, 10 s episodes of 500 ticks, a linear policy of
1 104 parameters, 32 x 4 episodes a generation, 16 held-out episodes, 0.01 m / 0.02 rad
noise, 0.2 m start displacement; 60 generations in 33 s on the project's 2-core VM, load below 1, jax 0.10.2 on the CPU): the
held-out return goes from the base controller's -6.59 to -3.04 (seed 0), 54 % less cost, the
first generations below the base (the perturbed policies' mean starts near -110) and above it
from generation 19. The room it uses: the scenario's gains are slow (time constants up to 50 s) and the
robots start displaced, which a residual on the robots' observed error corrects faster. With
the robots starting on the reference (``--start-noise-m 0``) the base controller's -0.053 is
not beaten in 60 generations (-0.73 at the defaults, -0.068 with ``--sigma 0.002 --lr
0.001``): a memoryless policy on the noisy reading has little to add to it.
"""

from __future__ import annotations

import argparse
import csv
import functools
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np


def parse(argv=None) -> argparse.Namespace:
    """The command line's options (``--help``)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="team-tetrahedron-helix",
                    help="team or network scenario (default %(default)s)")
    ap.add_argument("--controller", default=None, help="the base controller (default: the scenario's)")
    ap.add_argument("--generations", type=int, default=60, help="ES generations (default %(default)s)")
    ap.add_argument("--population", type=int, default=32,
                    help="perturbed policies per generation, even (default %(default)s)")
    ap.add_argument("--episodes", type=int, default=4,
                    help="training episodes per policy and generation (default %(default)s)")
    ap.add_argument("--eval-episodes", type=int, default=16, help="held-out episodes (default %(default)s)")
    ap.add_argument("--episode-s", type=float, default=10.0, help="episode length, s (default %(default)s)")
    ap.add_argument("--sigma", type=float, default=0.02, help="perturbation's standard deviation (default %(default)s)")
    ap.add_argument("--lr", type=float, default=0.01, help="Adam's step size (default %(default)s)")
    ap.add_argument("--hidden", type=int, default=0, help="hidden units (0: a linear policy; default %(default)s)")
    ap.add_argument("--residual-scale", type=float, default=0.25,
                    help="residual of an action of 1, as a fraction of each command's limit (default %(default)s)")
    ap.add_argument("--noise-m", type=float, default=0.01,
                    help="motion capture's position noise, m (default %(default)s)")
    ap.add_argument("--noise-rad", type=float, default=0.02,
                    help="motion capture's yaw noise, rad (default %(default)s)")
    ap.add_argument("--start-noise-m", type=float, default=0.2,
                    help="start's displacement of the robots, m (default %(default)s)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the whole run (default %(default)s)")
    ap.add_argument("--out", default="es_out", help="folder of curve.csv and curve.png (default %(default)s)")
    args = ap.parse_args(argv)
    if args.population < 2 or args.population % 2:
        ap.error("--population is an even number >= 2 (antithetic pairs)")
    if min(args.generations, args.episodes, args.eval_episodes) < 1:
        ap.error("--generations, --episodes and --eval-episodes are >= 1")
    return args


@functools.lru_cache(maxsize=4)
def build(scenario, controller, episode_s, residual_scale, noise_m, noise_rad, start_noise_m, hidden):
    """``(core, returns, shapes, sizes)``: the functional core, the compiled
    ``returns(thetas (P, n_theta), norm (2, n_obs), keys (E, 2), params)`` giving every policy's
    episode returns ``(P, E)`` and the observations' mean and mean square over each episode
    ``(P, E, n_obs)``, and the policy's parameter shapes and sizes in the flat ``theta``
    (cached: a second run with the same options compiles nothing)."""
    import jax
    import jax.numpy as jnp

    from quatform.envs import compiler_options, functional

    core = functional(scenario, controller, action="residual", residual_scale=residual_scale, noise_m=noise_m,
                      noise_rad=noise_rad, start_noise_m=start_noise_m, duration_s=episode_s)
    n_obs, n_u = core.n_obs, core.n_u
    shapes = [(n_u, n_obs), (n_u,)] if hidden == 0 else [(hidden, n_obs), (hidden,), (n_u, hidden), (n_u,)]
    sizes = [int(np.prod(s)) for s in shapes]

    def policy(theta, z):
        parts, i = [], 0
        for s, n in zip(shapes, sizes):
            parts.append(theta[i:i + n].reshape(s))
            i += n
        if hidden:
            z = jnp.tanh(parts[0] @ z + parts[1])
            parts = parts[2:]
        return jnp.tanh(parts[0] @ z + parts[1])

    def episode(theta, norm, k, params):
        k_reset, k_steps = jax.random.split(k)
        obs, state = core.reset(k_reset, params)

        def body(carry, k_t):
            obs, state, alive, ret = carry
            z = jnp.clip((obs - norm[0]) / norm[1], -5.0, 5.0)
            obs2, state, reward, terminated, truncated, _ = core.step(k_t, state, policy(theta, z), params)
            ret = ret + jnp.where(alive, reward, 0.0)
            return (obs2, state, alive & ~(terminated | truncated), ret), obs

        carry = (obs, state, jnp.asarray(True), jnp.asarray(0.0))
        (_, _, _, ret), seen = jax.lax.scan(body, carry, jax.random.split(k_steps, core.T - 1))
        return ret, jnp.mean(seen, axis=0), jnp.mean(seen * seen, axis=0)

    per_key = jax.vmap(episode, in_axes=(None, None, 0, None))
    returns = jax.jit(jax.vmap(per_key, in_axes=(0, None, None, None)), compiler_options=compiler_options(jax))
    return core, returns, shapes, sizes


def initial_theta(shapes, sizes, key):
    """Flat parameters: a hidden layer drawn ``N(0, 1/n_obs)``, every other entry 0."""
    import jax
    import jax.numpy as jnp

    theta = jnp.zeros(sum(sizes))
    if len(shapes) == 4:
        w1 = jax.random.normal(key, shapes[0]) / np.sqrt(shapes[0][1])
        theta = theta.at[:sizes[0]].set(w1.ravel())
    return theta


def centred_ranks(f):
    """Salimans et al. 2017's fitness shaping: ranks of ``f`` mapped to ``[-0.5, 0.5]``."""
    import jax.numpy as jnp

    ranks = jnp.argsort(jnp.argsort(f)).astype(f.dtype)
    return ranks / (f.shape[0] - 1) - 0.5


def train(args, log=print) -> list[dict]:
    """The learning curve of one run (module docstring): a row per generation (0: before any update)."""
    import jax
    import jax.numpy as jnp

    with jax.enable_x64(True):
        core, returns, shapes, sizes = build(args.scenario, args.controller, args.episode_s, args.residual_scale,
                                             args.noise_m, args.noise_rad, args.start_noise_m, args.hidden)
        params = jax.tree_util.tree_map(jnp.asarray, core.default_params)
        root = jax.random.PRNGKey(args.seed)
        k_init, k_norm, k_eval, k_train = jax.random.split(root, 4)
        eval_keys = jax.random.split(k_eval, args.eval_episodes)
        theta = initial_theta(shapes, sizes, k_init)
        zero = jnp.zeros_like(theta)
        ident = jnp.stack([jnp.zeros(core.n_obs), jnp.ones(core.n_obs)])
        # the observation's standardisation from the base controller's episodes (neither training nor held-out)
        _, mean, sq = returns(jnp.stack([zero, zero]), ident, jax.random.split(k_norm, args.eval_episodes), params)
        mu = jnp.mean(mean[0], axis=0)
        sd = jnp.sqrt(jnp.maximum(jnp.mean(sq[0], axis=0) - mu * mu, 0.0))
        norm = jnp.stack([mu, jnp.where(sd > 1e-6, sd, 1.0)])
        half = args.population // 2
        m, v = jnp.zeros_like(theta), jnp.zeros_like(theta)
        b1, b2 = 0.9, 0.999
        rows = []
        log(f"es_residual: {args.scenario}, {core.layout.n} robots, {core.T - 1} steps per episode, {theta.size} "
            f"parameters, population {args.population} x {args.episodes} episodes, noise {args.noise_m:g} m / "
            f"{args.noise_rad:g} rad")
        log(f"{'gen':>4} {'mean':>12} {'best':>12} {'policy held-out':>16} {'base held-out':>14} {'s':>7}")
        t0 = time.perf_counter()
        for gen in range(args.generations + 1):
            k_gen = jax.random.fold_in(k_train, gen)
            k_eps, k_ep = jax.random.split(k_gen)
            eps = jax.random.normal(k_eps, (half, theta.size))
            eps = jnp.concatenate([eps, -eps])
            fit, _, _ = returns(theta + args.sigma * eps, norm, jax.random.split(k_ep, args.episodes), params)
            f = jnp.mean(fit, axis=1)
            held, _, _ = returns(jnp.stack([theta, zero]), norm, eval_keys, params)
            row = {"generation": gen, "mean_return": float(jnp.mean(f)), "best_return": float(jnp.max(f)),
                   "policy_heldout": float(jnp.mean(held[0])), "base_heldout": float(jnp.mean(held[1])),
                   "wall_s": time.perf_counter() - t0}
            rows.append(row)
            log(f"{gen:>4} {row['mean_return']:>12.4g} {row['best_return']:>12.4g} {row['policy_heldout']:>16.4g} "
                f"{row['base_heldout']:>14.4g} {row['wall_s']:>7.1f}")
            if gen == args.generations:
                break
            g = centred_ranks(f) @ eps / (args.population * args.sigma)  # ascent direction
            t = gen + 1
            m = b1 * m + (1 - b1) * g
            v = b2 * v + (1 - b2) * g * g
            theta = theta + args.lr * (m / (1 - b1 ** t)) / (jnp.sqrt(v / (1 - b2 ** t)) + 1e-8)
    return rows


def write(rows, out: Path, title: str) -> None:
    """``curve.csv`` and ``curve.png`` of ``rows`` in ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    with open(out / "curve.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    gen = [r["generation"] for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
    ax.plot(gen, [r["mean_return"] for r in rows], label="population mean (training episodes)")
    ax.plot(gen, [r["best_return"] for r in rows], label="population best (training episodes)", alpha=0.6)
    ax.plot(gen, [r["policy_heldout"] for r in rows], label="policy, held-out episodes", linewidth=2)
    ax.plot(gen, [r["base_heldout"] for r in rows], "--", label="base controller, held-out episodes")
    ax.set_xlabel("generation")
    ax.set_ylabel("episode return")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.savefig(out / "curve.png", dpi=120)
    plt.close(fig)


def main(argv=None) -> list[dict]:
    args = parse(argv)
    if importlib.util.find_spec("jax") is None:
        sys.exit('es_residual: needs JAX (pip install -e ".[jax]")')
    rows = train(args)
    write(rows, Path(args.out),
          f"OpenAI-ES residual on {args.scenario}, noise {args.noise_m:g} m / {args.noise_rad:g} rad")
    print(f"wrote {Path(args.out) / 'curve.csv'} and curve.png")
    return rows


if __name__ == "__main__":
    main()
