"""Run by tests/envs/test_adapters.py in a subprocess: BraxHUAUV inside Brax's own training wrappers
against our env, then Brax's own SAC trainer (PPO too with --ppo), unchanged, for a few steps.

A subprocess, because each part compiles programs with the MJX step inside: with XLA's cheap CPU
optimisation level (set before JAX starts, as in _sharding_worker.py) compiling takes about half as
long, and the worker runs beside the in-process tests on the second core. PPO is left out of the CI
run to keep the suite's time (it adds about a third to this worker); benchmarks/peers.py --smoke
runs both trainers.

Prints one JSON line (prefixed RESULT): per part, "ok" or the traceback, plus what the test checks."""

from __future__ import annotations

import functools
import json
import math
import os
import sys
import traceback

import numpy as np

os.environ["XLA_FLAGS"] = (f"{os.environ.get('XLA_FLAGS', '')} --xla_backend_optimization_level=0 "
                           "--xla_llvm_disable_expensive_passes=true")


LIMIT, STEPS, NUM_ENVS, TIMEOUT_REWARD = 4, 6, 2, -10.0
# Noise and wind on, so every number depends on the PRNG key stream as well.
ENV_KW = {"scenario": 1, "sensor_noise_std": 0.05, "wind": True}


def key_after(key, steps: int):
    """Our env's PRNG key after `steps` steps (each step keeps the first of split(key, 4))."""
    import jax
    for _ in range(steps):
        key = jax.random.split(key, 4)[0]
    return key


def check_env_semantics() -> str:
    """BraxHUAUV under Vmap -> Episode -> AutoReset (what Brax's trainers wrap it in) against our env
    for the same keys and actions; raises AssertionError on any difference."""
    import jax
    import jax.numpy as jnp
    import brax.envs
    import docrl_jax.envs as envs
    from docrl_jax.envs.brax_env import BraxHUAUV

    benv = BraxHUAUV(episode_length=LIMIT, **ENV_KW)
    assert (benv.observation_size, benv.action_size, benv.backend) == (26, 3, "mjx")
    wrapped = brax.envs.training.wrap(benv, episode_length=LIMIT, action_repeat=1)
    ours = envs.make(**ENV_KW)              # step limit 500: no time-out within these steps
    keys = jax.random.split(jax.random.PRNGKey(11), NUM_ENVS)
    actions = np.random.default_rng(0).uniform(-1, 1, (STEPS, NUM_ENVS, 3)).astype(np.float32)

    @jax.jit
    def run(keys, actions):
        s0 = wrapped.reset(keys)

        def body(s, a):
            s = wrapped.step(s, a)
            return s, (s.obs, s.reward, s.done, s.info["truncation"], s.info["steps"], s.info["rng"],
                       s.pipeline_state.info["step"])
        return s0, jax.lax.scan(body, s0, actions)[1]

    @jax.jit
    def reference(keys, actions):
        def one(key, acts):
            r0 = ours.reset(key)

            def body(s, a):
                s = ours.step(s, a)
                return s, (s.obs, s.reward, s.done)
            return r0, jax.lax.scan(body, r0, acts)[1]
        return jax.vmap(one, in_axes=(0, 1))(keys, actions)

    s0, (obs, reward, done, trunc, steps, rng, inner_step) = jax.device_get(run(keys, actions))
    r0, (r_obs, r_reward, r_done) = jax.device_get(reference(keys, jnp.asarray(actions)))
    assert not r_done[:, :LIMIT].any(), "reference episode ended before the time-out; pick other keys"
    last = LIMIT - 1
    for i in range(NUM_ENVS):
        np.testing.assert_allclose(s0.obs[i], r0.obs[i], atol=1e-5)
        np.testing.assert_allclose(obs[:last, i], r_obs[i, :last], atol=1e-5)
        np.testing.assert_allclose(reward[:last, i], r_reward[i, :last], atol=1e-5)
        assert not done[:last, i].any() and not trunc[:last, i].any()
        # The time-out step: Brax's EpisodeWrapper ends it as a truncation (not a terminal), with our
        # time-out reward, and Brax's AutoResetWrapper returns the slot's first observation.
        np.testing.assert_allclose(obs[last, i], s0.obs[i], atol=0)
        assert done[last, i] == 1.0 and trunc[last, i] == 1.0, (done[:, i], trunc[:, i])
        np.testing.assert_allclose(reward[last, i], r_reward[i, last] + TIMEOUT_REWARD, atol=1e-5)
        # The next episode: counters restart, nothing ends.
        assert list(steps[LIMIT:, i]) == [1, 2] and list(inner_step[LIMIT:, i]) == [1, 2], (steps, inner_step)
        assert not done[LIMIT:, i].any() and not trunc[LIMIT:, i].any()
        # The wind/noise key is not restored with the first state: it runs on through the reset.
        for k in range(STEPS):
            np.testing.assert_array_equal(rng[k, i], np.asarray(key_after(r0.sim.key[i], k + 1)))
    return "ok"


def finite(tree) -> bool:
    import jax
    return all(bool(jax.numpy.all(jax.numpy.isfinite(x))) for x in jax.tree.leaves(tree))


def train(name: str, env) -> dict:
    """A few steps of Brax's `name` trainer on `env` (tiny networks); what the test checks."""
    import jax
    from brax.training.agents.ppo import networks as ppo_networks
    from brax.training.agents.ppo import train as ppo
    from brax.training.agents.sac import networks as sac_networks
    from brax.training.agents.sac import train as sac

    progress = []
    record = lambda step, metrics: progress.append((int(step), {k: float(v) for k, v in metrics.items()}))
    common = dict(num_timesteps=32, episode_length=env.episode_length, num_envs=4, num_eval_envs=2, num_evals=1,
                  seed=0, progress_fn=record)
    if name == "sac":
        make_policy, params, _ = sac.train(
            env, batch_size=8, min_replay_size=8, max_replay_size=64, **common,
            network_factory=functools.partial(sac_networks.make_sac_networks, hidden_layer_sizes=(8, 8)))
    else:
        make_policy, params, _ = ppo.train(
            env, batch_size=2, num_minibatches=2, unroll_length=4, num_updates_per_batch=1, **common,
            network_factory=functools.partial(ppo_networks.make_ppo_networks, policy_hidden_layer_sizes=(8,),
                                              value_hidden_layer_sizes=(8,)))
    obs = env.reset(jax.random.PRNGKey(1)).obs
    action, _ = make_policy(params, deterministic=True)(obs, jax.random.PRNGKey(2))
    last = progress[-1][1] if progress else {}
    return {"progress_steps": [s for s, _ in progress], "params_finite": finite(params),
            "action_shape": list(action.shape), "action_in_range": bool(jax.numpy.all(abs(action) <= 1.0)),
            "eval_episode_length": last.get("eval/avg_episode_length"),
            "eval_episode_reward": last.get("eval/episode_reward", math.nan)}


def main() -> None:
    import jax

    had_replicated = hasattr(jax, "device_put_replicated")
    import brax.envs
    from docrl_jax.envs.brax_env import BraxHUAUV   # applies the shim, registers docrl_huauv

    out = {"jax_had_device_put_replicated": had_replicated,
           "jax_has_device_put_replicated": hasattr(jax, "device_put_replicated")}
    try:
        out["env"] = check_env_semantics()
    except Exception:  # reported to the test, which shows it
        out["env"] = traceback.format_exc()
    env = brax.envs.get_environment("docrl_huauv", scenario=1, episode_length=5, wind=False)
    assert isinstance(env, BraxHUAUV)
    for name in ("sac", "ppo") if "--ppo" in sys.argv else ("sac",):
        try:
            out[name] = train(name, env)
        except Exception:
            out[name] = {"error": traceback.format_exc()}
    print("RESULT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
    sys.exit(0)
