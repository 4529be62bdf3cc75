"""The pieces of the packaged learner recipe that the paper does not have, each against an
independent reference: n-step TD targets (a plain Python loop over the window), the LayerNorm critic
ensemble (NumPy), the learning-rate decay (Adam's first step by hand) and the Polyak-averaged policy
(the average after one update, by hand; tau = 1 is the trained actor; the falling rate of
policy_average_tau_start at several points of the run)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import yaml

from docrl_jax.algorithms import make_agent
from docrl_jax.algorithms.common import adam, apply_gradients, lr_scale, nstep_targets
from docrl_jax.config import ConfigError, config_from_dict, packaged_configs_dir
from docrl_jax.networks import Critic


def _nstep_reference(reward, terminated, truncated, bootstrap, gamma, n):
    """For each (t, b): sum rewards forward until n rewards, the window's end or the episode's end;
    bootstrap from the last step's next obs unless that step terminated."""
    T, B = reward.shape
    out = np.zeros((T, B))
    for b in range(B):
        for t in range(T):
            ret, k = 0.0, 0
            while True:
                s = t + k
                ret += gamma ** k * reward[s, b]
                if terminated[s, b]:
                    break
                if truncated[s, b] or k == n - 1 or s == T - 1:
                    ret += gamma ** (k + 1) * bootstrap[s, b]
                    break
                k += 1
            out[t, b] = ret
    return out


@pytest.mark.parametrize("n", [1, 2, 5, 8])
def test_nstep_targets_match_a_python_loop(n):
    rng = np.random.default_rng(n)
    T, B = 8, 32
    reward = rng.normal(size=(T, B)).astype(np.float32)
    bootstrap = rng.normal(size=(T, B)).astype(np.float32) * 10
    terminated = rng.uniform(size=(T, B)) < 0.1
    truncated = (rng.uniform(size=(T, B)) < 0.1) & ~terminated
    got = nstep_targets(jnp.asarray(reward), jnp.asarray(terminated), jnp.asarray(truncated),
                        jnp.asarray(bootstrap), 0.9, n)
    want = _nstep_reference(reward, terminated, truncated, bootstrap, 0.9, n)
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-5, atol=1e-5)
    if n == 1:  # the one-step target of the paper, written out
        np.testing.assert_allclose(np.asarray(got), reward + 0.9 * (1 - terminated) * bootstrap, rtol=1e-5, atol=1e-6)


def test_nstep_by_hand_on_one_episode_boundary():
    # rewards 1, 2, 3, 4; step 1 terminates; bootstraps 10, 20, 30, 40; gamma 0.5, n 3.
    r = jnp.array([[1.0], [2.0], [3.0], [4.0]])
    term = jnp.array([[False], [True], [False], [False]])
    trunc = jnp.zeros((4, 1), bool)
    boot = jnp.array([[10.0], [20.0], [30.0], [40.0]])
    y = np.asarray(nstep_targets(r, term, trunc, boot, 0.5, 3))[:, 0]
    # t0: 1 + .5*2 (terminal, no bootstrap); t1: 2; t2: 3 + .5*4 + .25*40 (window end); t3: 4 + .5*40
    np.testing.assert_allclose(y, [2.0, 2.0, 15.0, 24.0])


@pytest.mark.parametrize("dtype, tol", [(jnp.float32, 1e-4), (jnp.bfloat16, 3e-2)])
def test_layer_norm_critic_ensemble_matches_numpy(dtype, tol):
    critic = Critic(hidden=(7, 5), num=2, layer_norm=True, dtype=dtype)
    obs, act = jax.random.normal(jax.random.PRNGKey(0), (4, 26)), jax.random.normal(jax.random.PRNGKey(1), (4, 3))
    params = critic.init(jax.random.PRNGKey(2), obs, act)
    # Non-trivial LayerNorm scales and offsets, so a skipped or misplaced norm shows.
    params = jax.tree_util.tree_map_with_path(
        lambda path, x: x + 0.3 * jax.random.normal(jax.random.PRNGKey(len(str(path))), x.shape)
        if "norm" in str(path) else x, params)
    q = np.asarray(critic.apply(params, obs, act))
    assert q.shape == (2, 4) and q.dtype == np.float32
    assert all(x.dtype == jnp.float32 for x in jax.tree.leaves(params))  # bf16 activations, fp32 parameters
    p = jax.tree.map(np.asarray, params)["params"]["q"]
    x0 = np.concatenate([np.asarray(obs), np.asarray(act)], -1)
    for head in range(2):
        x = x0
        for i in range(2):
            x = x @ p[f"dense_{i}"]["kernel"][head] + p[f"dense_{i}"]["bias"][head]
            mu, var = x.mean(-1, keepdims=True), x.var(-1, keepdims=True)
            x = (x - mu) / np.sqrt(var + 1e-6) * p[f"norm_{i}"]["scale"][head] + p[f"norm_{i}"]["bias"][head]
            x = np.maximum(x, 0.0)
        want = (x @ p["out"]["kernel"][head] + p["out"]["bias"][head])[:, 0]
        np.testing.assert_allclose(q[head], want, rtol=tol, atol=tol / 10)
        # one head alone (the TD3 actor loss) is that head of the ensemble: another XLA program, so equal up
        # to rounding (bitwise on one CPU, 1 ulp apart on another), and the heads differ far more (below)
        np.testing.assert_allclose(np.asarray(critic.head(params, obs, act, head)), q[head], rtol=tol, atol=tol / 10)
    assert not np.allclose(q[0], q[1], rtol=tol, atol=tol / 10)  # independent heads, apart beyond the tolerance


def test_the_default_td3_recipe_trains_bf16_critics_and_keeps_fp32_state():
    """td3_lstm's critics run in bfloat16 on a GPU (agent.critic_dtype auto, resolved here for a GPU
    and traced on the CPU); parameters, targets and losses stay float32, and the paper config keeps
    float32 throughout."""
    def dots(name):
        c = config_from_dict(yaml.safe_load((packaged_configs_dir() / f"{name}.yaml").read_text()),
                             {"env.num_envs": 2, "replay.buffer_size": 64, "replay.batch_size": 4}, backend="gpu")
        agent = make_agent(c)
        state = agent.init(jax.random.PRNGKey(0))
        B, L = c.replay.batch_size, c.replay.seq_len
        batch = {"obs": jnp.zeros((B, L, 26)), "action": jnp.zeros((B, L, 3)), "reward": jnp.zeros((B, L)),
                 "next_obs": jnp.zeros((B, L, 26)), "terminated": jnp.zeros((B, L), bool),
                 "truncated": jnp.zeros((B, L), bool), "start": jnp.zeros((B, L), bool), "mask": jnp.ones((B, L), bool),
                 "carry": agent.actor.init_carry((B, L))}
        traced = jax.make_jaxpr(agent.update)(state, batch, jax.random.PRNGKey(1), jnp.float32(0.5))
        assert all(a.dtype in (jnp.float32, jnp.int32) for a in traced.out_avals)
        return str(traced).count("bf16[")
    assert dots("td3_lstm") > 0
    assert dots("td3_lstm_paper") == 0


def test_learning_rate_decays_linearly_and_scales_adams_step():
    assert float(lr_scale(0.1, jnp.float32(0.0))) == 1.0
    assert float(lr_scale(0.1, jnp.float32(0.5))) == pytest.approx(0.55)
    assert float(lr_scale(0.1, jnp.float32(1.0))) == pytest.approx(0.1)
    assert float(lr_scale(0.1, jnp.float32(3.0))) == pytest.approx(0.1)  # clipped past the end
    assert float(lr_scale(1.0, jnp.float32(0.7))) == 1.0                   # 1 = the paper's constant rate
    # Adam's first step is -lr * g / (|g| + eps) per coordinate, so the scaled step is lr * scale.
    params = {"w": jnp.array([1.0, -2.0, 3.0])}
    grads = {"w": jnp.array([0.5, -4.0, 0.0])}
    tx = adam(1e-2)
    new, _ = apply_gradients(tx, grads, tx.init(params), params, scale=0.25)
    np.testing.assert_allclose(np.asarray(new["w"]), [1.0 - 2.5e-3, -2.0 + 2.5e-3, 3.0], rtol=1e-5)


def _agent_config(algo, tau_avg, tau_start=0.0):
    return config_from_dict({"env": {"num_envs": 2},
                             "agent": {"algo": algo, "actor": "mlp", "actor_hidden": [4], "critic_hidden": [5],
                                       "policy_freq": 1, "policy_average_tau": tau_avg,
                                       "policy_average_tau_start": tau_start},
                             "replay": {"buffer_size": 100, "batch_size": 6, "seq_len": 1, "burn_in": 0}})


def _batch():
    ks = jax.random.split(jax.random.PRNGKey(3), 4)
    B = 6
    return {"obs": jax.random.normal(ks[0], (B, 1, 26)), "action": jax.random.uniform(ks[1], (B, 1, 3), minval=-1),
            "reward": jax.random.normal(ks[2], (B, 1)), "next_obs": jax.random.normal(ks[3], (B, 1, 26)),
            "terminated": jnp.zeros((B, 1), bool), "truncated": jnp.zeros((B, 1), bool),
            "start": jnp.zeros((B, 1), bool), "mask": jnp.ones((B, 1), bool), "carry": (jnp.zeros((B, 1, 1)),)}


@pytest.mark.parametrize("algo", ["td3", "sac"])
def test_policy_average_is_a_polyak_average_of_the_trained_actor(algo):
    """The average after one update at env-step progress p, by hand. Constant rates: tau = 1 is the
    trained actor. A falling one, policy_average_tau_start 0.4 to policy_average_tau 0.1: the rate is
    0.1 * 4 ** (1 - p), 0.4 at the start, 0.2 halfway, 0.1 at the end and after it (float32's exp: a
    looser tolerance)."""
    batch = _batch()
    cases = [(1.0, 0.0, 0.0, 1.0, 1e-6), (0.25, 0.0, 0.0, 0.25, 1e-6),
             (0.1, 0.4, 0.0, 0.4, 1e-5), (0.1, 0.4, 0.5, 0.2, 1e-5), (0.1, 0.4, 1.0, 0.1, 1e-5), (0.1, 0.4, 1.5, 0.1, 1e-5)]
    for tau_avg, tau_start, progress, tau, rtol in cases:
        agent = make_agent(_agent_config(algo, tau_avg, tau_start))
        state = agent.init(jax.random.PRNGKey(0))
        # Start the average away from the actor, so the update rule shows.
        state = state.replace(actor_average=jax.tree.map(lambda x: x + 1.0, state.actor_average))
        new, m = jax.jit(agent.update)(state, batch, jax.random.PRNGKey(1), jnp.float32(progress))
        assert float(m["actor_updated"]) == 1.0
        changed = [not np.allclose(a, b) for a, b in zip(jax.tree.leaves(state.actor), jax.tree.leaves(new.actor))]
        assert any(changed)  # the trained actor moved
        want = jax.tree.map(lambda avg, a: (1 - tau) * avg + tau * a, state.actor_average, new.actor)
        jax.tree.map(lambda x, y: np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=rtol, atol=rtol / 10),
                     new.actor_average, want)


def test_policy_average_rate_traced_as_a_sweep_passes_it():
    """A sweep's float32 rows: a constant rate uses the row's own 1 - tau bit for bit (as a plain run's
    constants do), a falling one the schedule."""
    from docrl_jax.algorithms.common import HParams, average_rate
    rows = HParams.stack([HParams.from_agent_config(_agent_config("td3", 0.001).agent),
                          HParams.from_agent_config(_agent_config("td3", 0.001, 0.01).agent)])
    row = lambda i: jax.tree.map(lambda x: x[i], rows)  # noqa: E731
    tau, keep = jax.jit(average_rate)(row(0), jnp.float32(0.3))
    assert float(tau) == np.float32(0.001) and float(keep) == np.float32(0.999)
    tau, keep = jax.jit(average_rate)(row(1), jnp.float32(0.5))
    assert float(tau) == pytest.approx(0.001 * 10 ** 0.5, rel=1e-5) and float(keep) == pytest.approx(1 - float(tau))


@pytest.mark.parametrize("start", [0.0005, 1.5, -0.1])
def test_policy_average_tau_start_outside_tau_1_is_rejected(start):
    with pytest.raises(ConfigError, match="policy_average_tau_start"):
        _agent_config("td3", 0.001, start)


@pytest.mark.parametrize("tau", [0.0, 1.5])
def test_policy_average_tau_outside_0_1_is_rejected(tau):
    with pytest.raises(ConfigError, match="policy_average_tau"):
        _agent_config("td3", tau)


def test_compile_cache_folder_default_env_flag_and_off(monkeypatch, tmp_path):
    from docrl_jax.train import program_store as cli
    saved = jax.config.jax_compilation_cache_dir
    try:
        monkeypatch.delenv("DOCRL_JAX_COMPILE_CACHE", raising=False)
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
        assert cli.enable_compile_cache(None) == str(tmp_path / "xdg" / "docrl_jax" / "jax")
        assert jax.config.jax_compilation_cache_dir == str(tmp_path / "xdg" / "docrl_jax" / "jax")
        monkeypatch.setenv("DOCRL_JAX_COMPILE_CACHE", str(tmp_path / "env"))
        assert cli.enable_compile_cache(None) == str(tmp_path / "env") and (tmp_path / "env").is_dir()
        assert cli.enable_compile_cache(str(tmp_path / "flag")) == str(tmp_path / "flag")  # --compile-cache wins
        assert cli.enable_compile_cache("off") is None
    finally:
        jax.config.update("jax_compilation_cache_dir", saved)


def test_the_no_progress_eta_reads_as_a_duration():
    from docrl_jax.train.metrics import duration
    assert [duration(s) for s in (12.4, 250, 3600 * 37 + 125)] == ["12 s", "4 min 10 s", "37 h 02 min"]
