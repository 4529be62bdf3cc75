"""The memory arms beside the LSTM: an MLP actor reading stacked observations (agent.frames) and critics
that read the actor's carry (agent.critic_carry), against hand computation; their config and export
refusals."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import _agent_references as ref   # the hand computations of tests/algorithms/

from docrl_jax.algorithms import make_agent, sac
from docrl_jax.algorithms.common import split_batch
from docrl_jax.config import ConfigError, config_from_dict
from docrl_jax.memory import carry_size
from docrl_jax.networks import make_critic, unroll

B, OBS, FRAMES = 4, 26, 3


def _config(**agent):
    return config_from_dict({"env": {"num_envs": 2},
                             "agent": {"algo": "sac", "actor": "mlp", "actor_hidden": [4], "critic_hidden": [5],
                                       "frames": FRAMES, **agent},
                             "replay": {"buffer_size": 100, "batch_size": B, "seq_len": 1, "burn_in": 0}})


def test_stacked_actor_reads_the_last_frames_and_starts_each_episode_from_zeros():
    c = _config()
    assert c.agent.recurrent and carry_size(c) == (FRAMES - 1) * OBS
    agent = make_agent(c)
    params = agent.init(jax.random.PRNGKey(0)).actor
    T = 5
    obs = np.asarray(jax.random.normal(jax.random.PRNGKey(1), (T, B, OBS)))
    reset = np.zeros((T, B), bool)
    reset[0] = True
    reset[3, 1] = True  # row 1 starts a new episode at step 3
    _, (means, _), _, _ = unroll(agent.actor, params, agent.actor.init_carry((B,)), jnp.asarray(obs),
                                 jnp.asarray(reset))
    for t in range(T):
        for b in range(B):
            first = max(k for k in range(t + 1) if reset[k, b])
            frames = [obs[k, b] if k >= first else np.zeros(OBS) for k in range(t - FRAMES + 1, t + 1)]
            mean, _ = ref.gauss_head(jax.tree.map(np.asarray, params), np.concatenate(frames))
            np.testing.assert_allclose(np.asarray(means)[t, b], mean, rtol=1e-5, atol=1e-6)


def test_sac_critics_that_see_the_carry_by_hand():
    c = _config(critic_carry=True)
    agent = make_agent(c)
    state = agent.init(jax.random.PRNGKey(2))
    state = state.replace(critic_target=jax.tree.map(lambda x: x + 0.1, state.critic_target),
                          log_alpha=jnp.asarray(math.log(0.3)))
    ks = jax.random.split(jax.random.PRNGKey(3), 5)
    batch = {"obs": jax.random.normal(ks[0], (B, 1, OBS)), "next_obs": jax.random.normal(ks[1], (B, 1, OBS)),
             "action": jax.random.uniform(ks[2], (B, 1, 3), minval=-1, maxval=1),
             "reward": jax.random.normal(ks[3], (B, 1)), "terminated": jnp.array([[True], [False], [False], [False]]),
             "truncated": jnp.zeros((B, 1), bool), "start": jnp.zeros((B, 1), bool), "mask": jnp.ones((B, 1), bool),
             "carry": (jax.random.normal(ks[4], (B, 1, (FRAMES - 1) * OBS)),)}
    eps = 0.5 * jax.random.normal(jax.random.PRNGKey(4), (1, B, 3))
    critic = make_critic(c.agent)
    loss, info = sac.critic_loss(state.critic, critic, agent.actor, state, split_batch(batch, 0), eps, c.agent,
                                 memory=True)

    b, p = jax.tree.map(np.asarray, batch), jax.tree.map(np.asarray, state)
    s, a, r, s2, d = b["obs"][:, 0], b["action"][:, 0], b["reward"][:, 0], b["next_obs"][:, 0], b["terminated"][:, 0]
    past = b["carry"][0][:, 0]
    carry = np.concatenate([past, s], -1)[:, OBS:]          # the frames after reading s
    next_carry = np.concatenate([carry, s2], -1)[:, OBS:]   # ... and after reading s2
    a2, logp2 = ref.tanh_gauss(*ref.gauss_head(p.actor, np.concatenate([carry, s2], -1)), np.asarray(eps)[0])
    seen2 = np.concatenate([s2, next_carry], -1)
    y = r + 0.99 * (1 - d) * (np.minimum(ref.q(p.critic_target, seen2, a2, 0), ref.q(p.critic_target, seen2, a2, 1))
                              - 0.3 * logp2)
    seen = np.concatenate([s, carry], -1)
    np.testing.assert_allclose(float(info["target"]), y.mean(), rtol=1e-4)
    np.testing.assert_allclose(float(loss), sum(np.mean((ref.q(p.critic, seen, a, i) - y) ** 2) for i in range(2)),
                               rtol=1e-4)
    # The critics' input is obs + carry wide; without critic_carry it is the obs alone.
    assert state.critic["params"]["q"]["dense_0"]["kernel"].shape[1] == OBS + (FRAMES - 1) * OBS + 3
    plain = make_agent(_config()).init(jax.random.PRNGKey(2))
    assert plain.critic["params"]["q"]["dense_0"]["kernel"].shape[1] == OBS + 3


def test_an_lstm_actors_carry_reaches_its_critics():
    c = config_from_dict({"env": {"num_envs": 2},
                          "agent": {"algo": "sac", "actor": "lstm", "actor_hidden": [3], "critic_hidden": [5],
                                    "critic_carry": True},
                          "replay": {"buffer_size": 100, "batch_size": B, "seq_len": 3, "burn_in": 1}})
    state = make_agent(c).init(jax.random.PRNGKey(5))
    assert state.critic["params"]["q"]["dense_0"]["kernel"].shape[1] == OBS + 2 * 3 + 3  # obs, c, h, action


@pytest.mark.parametrize("agent, match", [
    ({"actor": "lstm", "actor_hidden": [8], "frames": 2}, r"agent.frames.*must be 1, or > 1 with agent.actor mlp"),
    ({"frames": 0}, r"agent.frames"),
    ({"frames": 1, "critic_carry": True}, r"agent.critic_carry.*needs agent.algo sac and a recurrent actor"),
    ({"algo": "td3", "critic_carry": True}, r"agent.critic_carry.*needs agent.algo sac"),
    ({"memory": False, "critic_carry": True}, r"agent.critic_carry"),
])
def test_memory_arm_configs_are_refused_in_one_line(agent, match):
    with pytest.raises(ConfigError, match=match) as err:
        _config(**agent)
    assert "\n" not in str(err.value)


def test_export_refuses_a_stacked_actor_before_writing(tmp_path):
    from docrl_jax.errors import ExportError
    from docrl_jax.export import export_actor
    with pytest.raises(ExportError, match="agent.frames 3: .*stacked observations is not exported"):
        export_actor(_config(), params=None, out_dir=tmp_path / "out", source={})
    assert not (tmp_path / "out").exists()
