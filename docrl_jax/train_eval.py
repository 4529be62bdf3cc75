"""Deterministic evaluation between training chunks (learning curves in metrics.csv).

`make_evaluate(config, act)` returns a pure `evaluate(actor_params, key) -> metrics`: `eval_episodes`
episodes run in parallel with the deterministic policy (TD3/DDPG: actor output; SAC: tanh(mean)),
each until the goal is reached (success), a collision or bound ends it, or the step limit
(env.max_episode_steps) truncates it. Starts and goals follow the training distribution; with
`train.eval_paper_pairs` the paper's air-to-water and water-to-air pairs (`envs.eval_pair`) are run
too, with a random start yaw. The full protocol of the paper (100 trials, times in air/water) is the
evaluator's job, not this module's.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

import docrl_jax.envs as envs
from docrl_jax.config import Config, env_kwargs


def make_evaluate(config: Config, act, init_carry, memory: bool):
    env = envs.make(config.env.scenario, auto_reset=False, **{**env_kwargs(config), "terminate_on_arrival": True})
    n, horizon = config.train.eval_episodes, env.params.max_episode_steps

    def run(actor_params, states, m):
        """Runs m episodes in parallel until all have ended (at most the step limit); returns
        per-episode (success, return). Stopping when the last episode ends, instead of always running
        the full step limit, makes an evaluation of a trained policy several times cheaper."""
        def body(c):
            i, st, carry, alive, ret, success = c
            carry = carry if memory else init_carry((m,))
            carry, action = act(actor_params, carry, st.obs)
            st = jax.vmap(env.step)(st, action)
            ret = ret + jnp.where(alive, st.reward, 0.0)
            success = success | (alive & st.info["arrived"])
            alive = alive & ~st.done
            return i + 1, st, carry, alive, ret, success

        init = (jnp.zeros((), jnp.int32), states, init_carry((m,)), jnp.ones(m, bool), jnp.zeros(m),
                jnp.zeros(m, bool))
        _, _, _, _, ret, success = jax.lax.while_loop(lambda c: (c[0] < horizon) & jnp.any(c[3]), body, init)
        return success.astype(jnp.float32), ret

    def evaluate(actor_params, key):
        k_rand, k_pairs = jax.random.split(key)
        groups = [jax.vmap(env.reset)(jax.random.split(k_rand, n))]
        names = ["success_rate"]
        if config.train.eval_paper_pairs:
            for direction, k in zip(("air_to_water", "water_to_air"), jax.random.split(k_pairs)):
                start, goal = envs.eval_pair(config.env.scenario, direction)
                k_yaw, k_reset = jax.random.split(k)
                yaws = jax.random.uniform(k_yaw, (n,), minval=-jnp.pi, maxval=jnp.pi)
                groups.append(jax.vmap(lambda kk, y: env.reset_to(kk, jnp.array(start), y, jnp.array(goal)))(
                    jax.random.split(k_reset, n), yaws))
                names.append(f"success_{direction}")
        # One batch of all groups: the env step is compiled once.
        states = jax.tree.map(lambda *xs: jnp.concatenate(xs), *groups)
        success, ret = run(actor_params, states, n * len(groups))
        out = {name: jnp.mean(success[i * n:(i + 1) * n]) for i, name in enumerate(names)}
        out["episode_return"] = jnp.mean(ret[:n])
        return out

    return evaluate
