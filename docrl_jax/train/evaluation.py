"""Deterministic evaluation between training chunks (learning curves in metrics.csv).

`make_evaluate(config, act)` returns a pure `evaluate(actor_params, key) -> metrics`: `eval_episodes`
episodes run in parallel with the deterministic policy (TD3/DDPG: actor output; SAC: tanh(mean)),
each until the goal is reached (success), a collision or bound ends it, or the step limit
(env.max_episode_steps) truncates it. Starts and goals follow the training distribution; with
`train.eval_paper_pairs` the paper's air-to-water and water-to-air pairs (`envs.eval_pair`, in the
run's scenario, or `train.eval_pair_scenario` for a procedural run, with the nominal plant) are run
too, from the evaluator's trial starts (`train.eval_pair_starts`, see `pair_starts`), and for each pair
the fractions of episodes that ended in a collision or out of bounds are reported too (the rest of the
failures are time-outs): a direction that stalls below 90 % says why in metrics.csv. The full protocol
of the paper (100 trials, times in air/water, 0.01 m range noise) is the evaluator's job, not this
module's; these episodes use the training env's settings.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

import docrl_jax.envs as envs
from docrl_jax.config import Config, env_kwargs, nominal_env_kwargs, pair_scenario
from docrl_jax.evaluate.protocol import DIRECTIONS, NOMINAL_YAW, trial_starts


def pair_starts(how: str, key: jax.Array, start, direction: str, n: int) -> tuple[jax.Array, jax.Array]:
    """Start positions (n, 3) and yaws (n,) of the paper-pair episodes of one direction.

    'paper': the evaluator's trials (`evaluate.protocol.trial_starts`: nominal yaw of the direction +-0.1 rad,
    position +-0.1 m), so the training-time score estimates the paper protocol's. 'random_yaw': the
    exact start, facing a uniformly random yaw (harder: the vehicle must first turn towards its goal)."""
    if how == "paper":
        return trial_starts(key, start, n, NOMINAL_YAW[direction])
    positions = jnp.broadcast_to(jnp.asarray(start, jnp.float32), (n, 3))
    return positions, jax.random.uniform(key, (n,), minval=-jnp.pi, maxval=jnp.pi)


def make_evaluate(config: Config, act, init_carry, memory: bool):
    env = envs.make(config.env.scenario, auto_reset=False, **{**env_kwargs(config), "terminate_on_arrival": True})
    scenario = pair_scenario(config)
    # The pairs get an env of their own only when they run and differ from the training env.
    own = config.train.eval_paper_pairs and (scenario != config.env.scenario
                                             or nominal_env_kwargs(config) != env_kwargs(config))
    pair_env = (envs.make(scenario, auto_reset=False, **{**nominal_env_kwargs(config), "terminate_on_arrival": True})
                if own else env)
    n, horizon = config.train.eval_episodes, env.params.max_episode_steps

    def run(env, actor_params, states, m):
        """Runs m episodes in parallel until all have ended (at most the step limit); returns
        per-episode (success, collision, out of bounds, return). Stopping when the last episode ends,
        instead of always running the full step limit, makes an evaluation of a trained policy
        several times cheaper."""
        def body(c):
            i, st, carry, alive, ret, success, collision, oob = c
            carry = carry if memory else init_carry((m,))
            carry, action = act(actor_params, carry, st.obs)
            st = jax.vmap(env.step)(st, action)
            ret = ret + jnp.where(alive, st.reward, 0.0)
            success = success | (alive & st.info["arrived"])
            collision = collision | (alive & st.info["collision"])
            oob = oob | (alive & st.info["out_of_bounds"] & ~st.info["collision"])  # as the evaluator counts
            alive = alive & ~st.done
            return i + 1, st, carry, alive, ret, success, collision, oob

        no = jnp.zeros(m, bool)
        init = (jnp.zeros((), jnp.int32), states, init_carry((m,)), jnp.ones(m, bool), jnp.zeros(m), no, no, no)
        _, _, _, _, ret, success, collision, oob = jax.lax.while_loop(lambda c: (c[0] < horizon) & jnp.any(c[3]),
                                                                      body, init)
        f32 = lambda x: x.astype(jnp.float32)  # noqa: E731
        return f32(success), f32(collision), f32(oob), ret

    def evaluate(actor_params, key):
        k_rand, k_pairs = jax.random.split(key)
        groups = [jax.vmap(env.reset)(jax.random.split(k_rand, n))]
        names = ["success_rate"]
        if config.train.eval_paper_pairs:
            for direction, k in zip(DIRECTIONS, jax.random.split(k_pairs)):
                start, goal = envs.eval_pair(scenario, direction)
                k_start, k_reset = jax.random.split(k)
                positions, yaws = pair_starts(config.train.eval_pair_starts, k_start, start, direction, n)
                groups.append(jax.vmap(lambda kk, p, y: pair_env.reset_to(kk, p, y, jnp.array(goal)))(
                    jax.random.split(k_reset, n), positions, yaws))
                names.append(f"success_{direction}")
        # One batch per env: the env step is compiled once for each (once when the pairs share the env).
        batches = [groups] if pair_env is env else [groups[:1], groups[1:]]
        results = []
        for run_env, batch in zip((env, pair_env), batches):
            states = jax.tree.map(lambda *xs: jnp.concatenate(xs), *batch)
            results.append(run(run_env, actor_params, states, n * len(batch)))
        success, collision, oob, ret = (jnp.concatenate(parts) for parts in zip(*results))
        part = lambda x, i: jnp.mean(x[i * n:(i + 1) * n])  # noqa: E731
        out = {name: part(success, i) for i, name in enumerate(names)}
        for i, name in enumerate(names[1:], start=1):  # the paper pairs' failures
            direction = name.removeprefix("success_")
            out[f"collision_{direction}"] = part(collision, i)
            out[f"out_of_bounds_{direction}"] = part(oob, i)
        out["episode_return"] = jnp.mean(ret[:n])
        return out

    return evaluate
