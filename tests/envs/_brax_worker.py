"""Run by tests/envs/test_adapters.py in a subprocess: BraxHUAUV inside Brax's own training wrappers
against our env, with and without Brax's domain-randomisation wrapper, then Brax's own SAC trainer
(PPO too with --ppo), unchanged, for a few steps with a randomization_fn.

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
    from docrl_jax.envs import randomization
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
    # No randomization_fn and the default dr_* ranges: every slot runs the nominal plant.
    nominal = jax.device_get(randomization.nominal_plant(benv.params))
    for a, b in zip(jax.tree.leaves(s0.pipeline_state.sim.plant), jax.tree.leaves(nominal)):
        np.testing.assert_array_equal(a, np.broadcast_to(b, a.shape))
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


DR_ENVS = 4
# The true mass (the controller assumes the nominal one) and the rotors' thrust limit in air drawn:
# hovering, a slot sinks or climbs by its own plant, in air or in water.
DR_KW = {"scenario": 1, "wind": False, "dr_mass_scale": (0.5, 2.0), "dr_thrust_air_scale": (0.1, 1.0)}


def check_randomization() -> dict:
    """BraxHUAUV under brax.envs.training.wrap(..., randomization_fn=make_randomization_fn(env)), the
    way Brax's trainers pass it (functools.partial with rng of shape (num_envs, 2)), hovering: each
    slot runs the plant drawn for it, through the time-out and Brax's auto-reset, and its numbers are
    our env's reset with that plant. Raises AssertionError on any difference; returns what the test
    reports."""
    import jax
    import jax.numpy as jnp
    import brax.envs
    import docrl_jax.envs as envs
    from docrl_jax.envs.brax_env import BraxHUAUV, make_randomization_fn

    benv = BraxHUAUV(episode_length=LIMIT, **DR_KW)
    nominal = benv.sys
    rngs = jax.random.split(jax.random.PRNGKey(5), DR_ENVS)
    fn = functools.partial(make_randomization_fn(benv), rng=rngs)
    wrapped = brax.envs.training.wrap(benv, episode_length=LIMIT, action_repeat=1, randomization_fn=fn)
    plants, in_axes = fn(nominal)
    assert all(a == 0 for a in jax.tree.leaves(in_axes)) and type(in_axes).__name__ == "Plant"
    keys = jax.random.split(jax.random.PRNGKey(12), DR_ENVS)
    hover = jnp.zeros((STEPS, DR_ENVS, 3), jnp.float32)

    @jax.jit
    def run(keys, actions):
        s0 = wrapped.reset(keys)

        def body(s, a):
            s = wrapped.step(s, a)
            return s, (s.obs, s.done, s.pipeline_state.sim.plant, s.pipeline_state.info["position"])
        return s0, jax.lax.scan(body, s0, actions)[1]

    ours = envs.make(**DR_KW)

    @jax.jit
    def reference(keys, plants, actions):
        def one(key, plant, acts):
            r0 = ours.reset(key, plant=plant)

            def body(s, a):
                s = ours.step(s, a)
                return s, (s.obs, s.done)
            return r0, jax.lax.scan(body, r0, acts)[1]
        return jax.vmap(one, in_axes=(0, 0, 1))(keys, plants, actions)

    s0, (obs, done, plant_t, pos) = jax.device_get(run(keys, hover))
    r0, (r_obs, r_done) = jax.device_get(reference(keys, plants, hover))
    # Leaving the wrapper put the nominal plant back: the bare env draws from its dr_* ranges again.
    assert benv._plant is None and benv.sys is nominal
    plants, nominal = jax.device_get((plants, nominal))
    thrust, mass = plants.thrust_air, plants.mass_scale
    assert len(set(np.round(thrust, 6))) == len(set(np.round(mass, 6))) == DR_ENVS, (thrust, mass)  # one per env
    assert np.all((thrust >= 0.1 * nominal.thrust_air - 1e-4) & (thrust <= nominal.thrust_air + 1e-4))
    assert np.all((mass >= 0.5) & (mass <= 2.0)) and nominal.mass_scale == 1.0
    for name, leaf in plants._asdict().items():
        # The slot's plant at reset and at every step, through the time-out and the auto-reset.
        np.testing.assert_array_equal(getattr(s0.pipeline_state.sim.plant, name), leaf, err_msg=name)
        np.testing.assert_array_equal(getattr(plant_t, name), np.broadcast_to(leaf, getattr(plant_t, name).shape),
                                      err_msg=name)
        np.testing.assert_array_equal(getattr(r0.sim.plant, name), leaf, err_msg=name)
    np.testing.assert_allclose(s0.obs, r0.obs, atol=1e-5)
    for i in range(DR_ENVS):   # our env with the slot's plant, until its episode ends
        live = LIMIT - 1 if not r_done[i, :LIMIT - 1].any() else int(np.argmax(r_done[i]))
        np.testing.assert_allclose(obs[:live, i], r_obs[i, :live], atol=1e-5)
    # Hovering under different plants: the slots drift apart (vertical displacement after 3 steps).
    drift = pos[LIMIT - 2, :, 2] - s0.pipeline_state.info["position"][:, 2]
    assert np.ptp(drift) > 1e-2, drift

    # Without a randomization_fn the env draws its own plant per slot from the same ranges, keyed by
    # the slot's reset key (our env's reset), and Brax's VmapWrapper leaves sys alone.
    plain = jax.jit(brax.envs.training.wrap(benv, episode_length=LIMIT, action_repeat=1).reset)(keys)
    own = jax.jit(jax.vmap(ours.reset))(keys).sim.plant
    for a, b in zip(jax.tree.leaves(plain.pipeline_state.sim.plant), jax.tree.leaves(own)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    return {"ok": True, "mass_scale": [float(x) for x in mass], "thrust_air": [float(x) for x in thrust],
            "drift": [float(x) for x in drift]}


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

    from docrl_jax.envs.brax_env import make_randomization_fn

    # Domain randomisation as Playground passes it; counted, to show the trainer built its training
    # and its eval envs with it.
    draws = []
    plants_for = make_randomization_fn(env)

    def randomize(sys, rng):
        draws.append(int(rng.shape[0]))
        return plants_for(sys, rng)

    progress = []
    record = lambda step, metrics: progress.append((int(step), {k: float(v) for k, v in metrics.items()}))
    common = dict(num_timesteps=32, episode_length=env.episode_length, num_envs=4, num_eval_envs=2, num_evals=1,
                  seed=0, progress_fn=record, randomization_fn=randomize)
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
            "eval_episode_reward": last.get("eval/episode_reward", math.nan), "randomized_envs": draws}


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
    try:
        out["randomization"] = check_randomization()
    except Exception:
        out["randomization"] = {"error": traceback.format_exc()}
    env = brax.envs.get_environment("docrl_huauv", scenario=1, episode_length=5, wind=False,
                                    dr_thrust_air_scale=(0.9, 1.0), dr_hull_volume_scale=(0.9, 1.1))
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
