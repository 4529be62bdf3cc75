"""The Brax and Gymnasium adapters (docrl_jax/envs/brax_env.py, gym_env.py) against our own env.

Each adapter must give our env's numbers for the same keys and actions, end episodes where ours does
with the right terminated/truncated split, and auto-reset as its library expects. The Brax parts
(the env inside Brax's own training wrappers, with and without its domain-randomisation wrapper, and
Brax's SAC trainer for a few steps) run
in a subprocess, tests/envs/_brax_worker.py, started with this module so that it compiles on the second
core while the Gymnasium tests run here.

The Gymnasium reference is `conftest.env_fns(1, wind=False)` (scenario 1, no wind, step limit 500),
whose compiled rollout the env contract tests share. The adapters get a step limit of 4 (Gymnasium:
our env's own `max_episode_steps`; Brax: `episode_length`), so their 4th step is a time-out: the
reference's numbers there plus the paper's -10 time-out reward.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from docrl_jax.envs import OBS_LAYOUT, gym_env, randomization
from docrl_jax.envs.brax_env import BraxHUAUV, make_randomization_fn, randomization_fn
from docrl_jax.envs.physics import Plant
from docrl_jax.envs.gym_env import ENV_ID, HUAUVGymEnv, HUAUVVectorEnv

from _adapter_settings import FAST_COMPILE, GYM_KW, LIMIT, NUM_ENVS

STEPS = 6                 # steps run: 3 inside the episode, the time-out, 2 into the next episode
TIMEOUT_REWARD = -10.0
WORKER = Path(__file__).with_name("_brax_worker.py")


@pytest.fixture(scope="module", autouse=True)
def brax_worker():
    """Starts Brax's trainers in a subprocess before the first test of this module."""
    proc = subprocess.Popen([sys.executable, str(WORKER)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    yield proc
    if proc.poll() is None:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def ref(env_fns):
    """(env, jitted reset, rollout) of the reference env."""
    env, _, rollout = env_fns(1, wind=False)
    return env, jax.jit(env.reset, compiler_options=FAST_COMPILE), rollout


def _key_after(key, steps: int):
    """Our env's PRNG key after `steps` steps (each step keeps the first of split(key, 4))."""
    for _ in range(steps):
        key = jax.random.split(key, 4)[0]
    return key


def _reference_rollouts(ref, keys, actions):
    """Per env i: the reference's reset state from keys[i] and its rollout under actions[:, i]."""
    env, reset, rollout = ref
    out = []
    for i in range(keys.shape[0]):
        s0 = reset(keys[i])
        _, (obs, reward, done, info) = rollout(s0, jnp.asarray(actions[:, i]))
        obs, reward, done, info = jax.device_get((obs, reward, done, info))
        # The test's episodes must run to the time-out (random starts keep 1 m from obstacles; 4 steps
        # of 0.2 s move well under that).
        assert not done[:LIMIT].any(), "reference episode ended before the time-out; pick other keys"
        out.append((s0, obs, reward, info))
    return out


# ---------------------------------------------------------------------------------------------- core


def test_core_package_imports_without_brax_or_gymnasium():
    code = ("import sys; sys.modules['brax'] = None; sys.modules['gymnasium'] = None\n"
            "import docrl_jax, docrl_jax.envs, docrl_jax.evaluate\n"
            "for mod, extra in (('brax_env', 'brax'), ('gym_env', 'gym')):\n"
            "    try:\n"
            "        __import__('docrl_jax.envs.' + mod)\n"
            "    except ImportError as e:\n"
            "        assert f'.[{extra}]' in str(e), e\n"
            "    else:\n"
            "        raise AssertionError(mod + ' imported without its extra')\n"
            "print('ok')\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.strip().endswith("ok"), res.stdout + res.stderr


# ---------------------------------------------------------------------------------------------- Brax


def test_brax_env_refuses_our_own_truncation_and_auto_reset():
    with pytest.raises(ValueError, match="episode_length"):
        BraxHUAUV(scenario=1, max_episode_steps=100)
    with pytest.raises(ValueError, match="AutoResetWrapper"):
        BraxHUAUV(scenario=1, auto_reset=True)


def test_brax_sys_is_the_nominal_plant_and_randomization_fn_draws_one_per_env():
    env = BraxHUAUV(scenario=1, dr_thrust_air_scale=(0.1, 1.0))
    nominal = env.sys
    assert isinstance(nominal, Plant)
    for a, b in zip(nominal, randomization.nominal_plant(env.params)):
        np.testing.assert_array_equal(a, b)
    # Brax's signature, as its trainers call it: fn(sys, rng=keys of shape (num_envs, 2)).
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    plants, in_axes = make_randomization_fn(env)(nominal, rng=keys)
    assert isinstance(plants, Plant) and isinstance(in_axes, Plant) and set(in_axes) == {0}
    expected = jax.vmap(lambda k: randomization.sample_plant(k, env.params))(keys)
    for name, leaf in plants._asdict().items():
        assert leaf.shape == (4,) + np.shape(getattr(nominal, name)), name
        np.testing.assert_array_equal(leaf, getattr(expected, name), err_msg=name)
    assert len(set(np.asarray(plants.thrust_air).round(6))) == 4
    np.testing.assert_array_equal(plants.buoyancy, np.full(4, nominal.buoyancy))   # a range not drawn
    same, _ = randomization_fn(nominal, keys, params=env.params)
    np.testing.assert_array_equal(same.thrust_air, plants.thrust_air)
    # Assigning a plant overrides; None, or the nominal plant read back (what Brax's wrapper restores
    # on leaving), returns to drawing from the dr_* ranges.
    one = jax.tree.map(lambda x: x[1], plants)
    env.sys = one
    assert env.sys is one and env._plant is one
    env.sys = nominal
    assert env._plant is None and env.sys is nominal
    env.sys = one
    env.sys = None
    assert env._plant is None
    with pytest.raises(TypeError, match="Plant"):
        env.sys = {"thrust_air": 1.0}
    with pytest.raises(TypeError, match="params"):
        randomization_fn(nominal, keys)
    with pytest.raises(ValueError, match="num_envs"):
        make_randomization_fn(env)(nominal, jax.random.PRNGKey(0))


# ---------------------------------------------------------------------------------------------- Gymnasium


def test_gym_vector_env_matches_ours_with_same_step_auto_reset(ref):
    venv = HUAUVVectorEnv(NUM_ENVS, **GYM_KW)
    assert venv.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.SAME_STEP
    assert venv.single_observation_space.shape == (26,) and venv.observation_space.shape == (NUM_ENVS, 26)
    assert venv.single_action_space.shape == (3,) and venv.action_space.shape == (NUM_ENVS, 3)
    obs0, info0 = venv.reset(seed=7)
    # The keys reset(seed=7) draws: from the env's seeded NumPy generator.
    keys = gym_env._keys(gymnasium.utils.seeding.np_random(7)[0], NUM_ENVS)
    actions = np.random.default_rng(1).uniform(-1, 1, (STEPS, NUM_ENVS, 3)).astype(np.float32)
    results, keys_after = [], []
    for a in actions:
        results.append(venv.step(a))
        keys_after.append(np.asarray(venv.state.sim.key))
    refs = _reference_rollouts(ref, keys, actions)
    env, reset, _ = ref
    assert obs0.dtype == np.float32 and obs0 in venv.observation_space and info0["_step"].all()
    for i, (r0, r_obs, r_reward, r_info) in enumerate(refs):
        np.testing.assert_allclose(obs0[i], np.asarray(r0.obs), atol=1e-5)
        for t in range(LIMIT - 1):
            obs, reward, terminated, truncated, info = results[t]
            np.testing.assert_allclose(obs[i], r_obs[t], atol=1e-5)
            assert reward[i] == pytest.approx(r_reward[t], abs=1e-5)
            assert not terminated[i] and not truncated[i] and "final_obs" not in info
            np.testing.assert_allclose(info["position"][i], r_info["position"][t], atol=1e-5)
            # The episode's PRNG key runs as in our env.step (wind, noise and goals would match too).
            np.testing.assert_array_equal(keys_after[t][i], np.asarray(_key_after(r0.sim.key, t + 1)))
        # The time-out step: truncated, not terminated; reward as ours plus the time-out reward; the
        # true next observation in final_obs; obs and info already the new episode's (SAME_STEP),
        # whose reset key comes from the env's own key stream as in our AutoResetWrapper.
        obs, reward, terminated, truncated, info = results[LIMIT - 1]
        assert truncated[i] and not terminated[i]
        assert reward[i] == pytest.approx(r_reward[LIMIT - 1] + TIMEOUT_REWARD, abs=1e-5)
        assert info["_final_obs"][i] and info["_final_info"][i]
        np.testing.assert_allclose(info["final_obs"][i], r_obs[LIMIT - 1], atol=1e-5)
        assert info["final_info"]["step"][i] == LIMIT and info["final_info"]["truncated"][i]
        np.testing.assert_allclose(info["final_info"]["position"][i], r_info["position"][LIMIT - 1], atol=1e-5)
        k_reset = jax.random.split(_key_after(r0.sim.key, LIMIT))[1]
        np.testing.assert_allclose(obs[i], np.asarray(reset(k_reset).obs), atol=1e-5)
        assert info["step"][i] == 0 and np.all(obs[i][OBS_LAYOUT["prev_action"]] == 0.0)
        for t in (LIMIT, LIMIT + 1):
            _, _, terminated, truncated, info = results[t]
            assert info["step"][i] == t - LIMIT + 1 and not terminated[i] and not truncated[i]


def test_gym_make_vec_loop_runs():
    envs_ = gymnasium.make_vec(ENV_ID, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point",
                               **GYM_KW)
    assert isinstance(envs_.unwrapped, HUAUVVectorEnv)
    obs, _ = envs_.reset(seed=0)
    envs_.action_space.seed(0)
    ends = 0
    for _ in range(2 * LIMIT):
        obs, reward, terminated, truncated, info = envs_.step(envs_.action_space.sample())
        assert obs.shape == (NUM_ENVS, 26) and obs.dtype == np.float32 and obs in envs_.observation_space
        assert reward.shape == terminated.shape == truncated.shape == (NUM_ENVS,)
        assert terminated.dtype == truncated.dtype == np.bool_
        ends += int((terminated | truncated).sum())
    assert ends >= NUM_ENVS   # every env ends at least once (the step limit is 4)
    with pytest.raises(ValueError, match="expected"):
        envs_.step(np.zeros((NUM_ENVS + 1, 3), np.float32))
    envs_.close()


def test_gym_single_env_passes_check_env_and_ends_episodes():
    # Registered: gymnasium.make builds our env under Gymnasium's own time limit. It keeps max_episode_steps
    # for that limit, so the env inside has our default step limit: stepping it would compile a second program
    # for the same code, so the checks below run on one env with the test's limit.
    made = gymnasium.make(ENV_ID, **GYM_KW)
    assert isinstance(made.unwrapped, HUAUVGymEnv) and made.spec.max_episode_steps == LIMIT
    env = HUAUVGymEnv(**GYM_KW)
    check_env(env)
    obs, info = env.reset(seed=3)
    assert obs.shape == (26,) and info["step"] == 0
    for t in range(LIMIT):
        obs, reward, terminated, truncated, info = env.step(np.zeros(3, np.float32))
        assert isinstance(reward, float) and not terminated
    assert truncated and info["step"] == LIMIT and np.all(obs[OBS_LAYOUT["prev_action"]] == 0.0)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3, np.float32))


# ---------------------------------------------------------------------------------------------- Brax trainers


@pytest.fixture(scope="module")
def brax_result(brax_worker) -> dict:
    try:
        log, _ = brax_worker.communicate(timeout=600)
    except subprocess.TimeoutExpired:
        brax_worker.kill()
        raise
    assert brax_worker.returncode == 0, log[-4000:]
    return json.loads(next(line for line in log.splitlines() if line.startswith("RESULT "))[len("RESULT "):])


def test_brax_env_matches_ours_truncates_and_auto_resets(brax_result):
    """BraxHUAUV in Brax's Vmap -> Episode -> AutoReset wrappers, with sensor noise and wind, against
    our env for the same keys and actions (tests/envs/_brax_worker.py, check_env_semantics): equal obs
    and rewards; at episode_length a truncation (done 1, truncation 1) with our time-out reward and
    the slot's first observation; counters restart; the PRNG key runs on through the reset."""
    assert brax_result["env"] == "ok", brax_result["env"]


def test_brax_domain_randomization_wrapper_runs_one_plant_per_env(brax_result):
    """BraxHUAUV(scenario=1, dr_mass_scale=(0.5, 2), dr_thrust_air_scale=(0.1, 1)) in
    brax.envs.training.wrap(..., randomization_fn=make_randomization_fn(env)) for 4 envs, hovering
    (tests/envs/_brax_worker.py, check_randomization): each slot's plant is its own draw, stays the
    same at every step through the time-out and the auto-reset, and its numbers are our env's reset
    with that plant; the slots' heights drift apart. Brax's plain VmapWrapper leaves the env's own
    per-slot draws (our env's reset), and with the default ranges every slot runs the nominal plant
    (check_env_semantics)."""
    r = brax_result["randomization"]
    assert "error" not in r, r["error"]
    assert np.ptp(r["drift"]) > 0.1, r


def test_brax_sac_trains_on_our_env(brax_result):
    # The shim: jax 0.10 lacks device_put_replicated, importing the adapter defines it.
    assert not brax_result["jax_had_device_put_replicated"] and brax_result["jax_has_device_put_replicated"]
    for name in ("sac",):   # PPO: tests/envs/_brax_worker.py --ppo, and benchmarks/peers.py --smoke
        r = brax_result[name]
        assert "error" not in r, r.get("error")
        assert r["progress_steps"] and r["progress_steps"][-1] >= 32, (name, r)
        assert r["params_finite"] and r["action_shape"] == [3] and r["action_in_range"], (name, r)
        # Brax's evaluator ran whole episodes of the episode_length given (5 steps, no collisions).
        assert r["eval_episode_length"] == pytest.approx(5.0), (name, r)
        # It took the randomization_fn: plants for its 4 training envs and its 2 eval envs.
        assert r["randomized_envs"] == [4, 2], (name, r)
