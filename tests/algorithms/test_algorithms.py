"""TD3 and SAC losses against hand computation on tiny networks, the policy-delay schedule, the
LSTM burn-in, and that a learning rate of 0 freezes learning (the learning test's baseline)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import _agent_references as ref   # the hand computations of tests/algorithms/

from docrl_jax.algorithms import make_agent, policy_freq
from docrl_jax.algorithms import sac, td3
from docrl_jax.algorithms.common import run_actor, split_batch
from docrl_jax.config import config_from_dict
from docrl_jax.networks import Critic, expand_flag

B = 6


def _config(algo, actor="mlp", **agent):
    seq = {"seq_len": 1, "burn_in": 0} if actor == "mlp" else {"seq_len": 5, "burn_in": 2}
    return config_from_dict({"env": {"num_envs": 2},
                             "agent": {"algo": algo, "actor": actor, "actor_hidden": [4] if actor == "mlp" else [3],
                                       "critic_hidden": [5], **agent},
                             "replay": {"buffer_size": 100, "batch_size": B, **seq}})


def _batch(key, seq_len=1):
    ks = jax.random.split(key, 6)
    return {"obs": jax.random.normal(ks[0], (B, seq_len, 26)), "action": jax.random.uniform(ks[1], (B, seq_len, 3), minval=-1, maxval=1),
            "reward": jax.random.normal(ks[2], (B, seq_len)) * 5, "next_obs": jax.random.normal(ks[3], (B, seq_len, 26)),
            "terminated": jnp.array([True, False, False, True, False, False])[:, None].repeat(seq_len, 1),
            "truncated": jnp.zeros((B, seq_len), bool), "start": jax.random.uniform(ks[4], (B, seq_len)) < 0.3,
            "mask": jnp.ones((B, seq_len), bool)}


def _np(tree):
    return jax.tree.map(np.asarray, tree)


def _perturbed(state):
    """Targets different from the online nets, so using the wrong one shows."""
    return state.replace(actor_target=jax.tree.map(lambda x: 1.5 * x, state.actor_target),
                         critic_target=jax.tree.map(lambda x: x + 0.1, state.critic_target))


def test_td3_target_with_clipped_smoothing_and_critic_loss_by_hand():
    c = _config("td3", policy_noise=0.4, noise_clip=0.5)
    agent = make_agent(c)
    state = _perturbed(agent.init(jax.random.PRNGKey(0)))
    batch = _batch(jax.random.PRNGKey(1))
    batch["carry"] = (jnp.zeros((B, 1, 1)),)
    noise = jnp.array([[3.0, -3.0, 0.5]] * 3 + [[-0.2, 0.1, 2.0]] * 3)[None]  # [T=1, B, 3]  # exercises the clip
    critic = Critic(hidden=(5,), num=2)
    loss, info = td3.critic_loss(state.critic, critic, agent.actor, state, split_batch(batch, 0), noise,
                                 c.agent, memory=False)

    p, b, n = _np(state), _np(batch), np.asarray(noise)[0]
    s, a, r, s2, d = b["obs"][:, 0], b["action"][:, 0], b["reward"][:, 0], b["next_obs"][:, 0], b["terminated"][:, 0]
    a2 = np.tanh(ref.mlp({**p.actor_target["params"], "out": p.actor_target["params"]["head"]["out"]}, s2,
                      ["dense_0", "out"]))
    a2 = np.clip(a2 + np.clip(0.4 * n, -0.5, 0.5), -1, 1)
    y = r + 0.99 * (1 - d) * np.minimum(ref.q(p.critic_target, s2, a2, 0), ref.q(p.critic_target, s2, a2, 1))
    expected = sum(np.mean((ref.q(p.critic, s, a, i) - y) ** 2) for i in range(2))
    np.testing.assert_allclose(float(info["target"]), y.mean(), rtol=1e-5)
    np.testing.assert_allclose(float(loss), expected, rtol=1e-5)
    # The actor loss is -Q1 of the online actor's action under the online critic.
    a_pi = np.tanh(ref.mlp({**p.actor["params"], "out": p.actor["params"]["head"]["out"]}, s, ["dense_0", "out"]))
    got = td3.actor_loss(state.actor, agent.actor, critic, state.critic, split_batch(batch, 0), memory=False)
    np.testing.assert_allclose(float(got), -np.mean(ref.q(p.critic, s, a_pi, 0)), rtol=1e-5)


def test_sac_losses_by_hand():
    c = _config("sac", target_entropy=-3.0)
    agent = make_agent(c)
    state = _perturbed(agent.init(jax.random.PRNGKey(2))).replace(log_alpha=jnp.asarray(math.log(0.3)))
    batch = _batch(jax.random.PRNGKey(3))
    batch["carry"] = (jnp.zeros((B, 1, 1)),)
    seq = split_batch(batch, 0)
    # Moderate noise: near |a| = 1 the log(1 - a^2 + 1e-6) term amplifies float32 rounding of tanh.
    eps_next = 0.5 * jax.random.normal(jax.random.PRNGKey(4), (1, B, 3))
    eps_pi = 0.5 * jax.random.normal(jax.random.PRNGKey(5), (1, B, 3))
    critic = Critic(hidden=(5,), num=2)

    loss, info = sac.critic_loss(state.critic, critic, agent.actor, state, seq, eps_next, c.agent, memory=False)
    p, b = _np(state), _np(batch)
    s, a, r, s2, d = b["obs"][:, 0], b["action"][:, 0], b["reward"][:, 0], b["next_obs"][:, 0], b["terminated"][:, 0]
    mean2, log_std2 = ref.gauss_head(p.actor, s2)
    a2, logp2 = ref.tanh_gauss(mean2, log_std2, np.asarray(eps_next)[0])
    qmin2 = np.minimum(ref.q(p.critic_target, s2, a2, 0), ref.q(p.critic_target, s2, a2, 1))
    y = r + 0.99 * (1 - d) * (qmin2 - 0.3 * logp2)
    np.testing.assert_allclose(float(info["target"]), y.mean(), rtol=1e-4)
    np.testing.assert_allclose(float(loss), sum(np.mean((ref.q(p.critic, s, a, i) - y) ** 2) for i in range(2)),
                               rtol=1e-4)

    a_loss, logp = sac.actor_loss(state.actor, agent.actor, critic, state.critic, state.log_alpha, seq, eps_pi,
                                  c.agent, memory=False)
    mean, log_std = ref.gauss_head(p.actor, s)
    a_pi, logp_pi = ref.tanh_gauss(mean, log_std, np.asarray(eps_pi)[0])
    qmin = np.minimum(ref.q(p.critic, s, a_pi, 0), ref.q(p.critic, s, a_pi, 1))
    np.testing.assert_allclose(float(a_loss), np.mean(0.3 * logp_pi - qmin), rtol=1e-4)
    np.testing.assert_allclose(np.asarray(logp)[0], logp_pi, rtol=1e-4)
    al = sac.alpha_loss(state.log_alpha, logp, -3.0, seq.mask)
    np.testing.assert_allclose(float(al), -np.mean(math.log(0.3) * (logp_pi - 3.0)), rtol=1e-4)
    # Deterministic evaluation action is tanh(mean).
    _, act = agent.act(state.actor, (jnp.zeros((B, 1)),), jnp.asarray(s))
    np.testing.assert_allclose(np.asarray(act), np.tanh(mean), rtol=1e-5)
    # log_std is clamped to [-20, 2] (orig): push one unit far above, one far below.
    bias = state.actor["params"]["head"]["log_std"]["bias"]
    head = {**state.actor["params"]["head"], "log_std": {**state.actor["params"]["head"]["log_std"],
                                                         "bias": bias.at[0].set(50.0).at[1].set(-50.0)}}
    _, (_, log_std) = agent.actor.apply({"params": {**state.actor["params"], "head": head}},
                                        (jnp.zeros((B, 1)),), jnp.asarray(s))
    np.testing.assert_array_equal(np.asarray(log_std[:, :2]), [[2.0, -20.0]] * B)


def test_policy_freq_schedule():
    progress = jnp.array([-0.5, 0.0, 0.3, 0.4999, 0.5, 0.6, 0.75, 0.8, 0.9, 0.95, 1.0, 3.0])
    np.testing.assert_array_equal(np.asarray(policy_freq(0, progress)), [2, 2, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6])
    # The paper's formula int(1 / (0.5 - t / (3 max_steps))) with t = max_steps * progress, in float64
    # (6 only at the very end: 1 / (0.5 - 1/3) = 6 exactly, which float64 rounds to 5.999...).
    for p in np.linspace(0.0, 1.0, 101):
        assert int(policy_freq(0, jnp.float32(p))) == int(1.0 / (0.5 - 500 * p / (3 * 500)) + 1e-9)
    assert int(policy_freq(3, jnp.float32(0.9))) == 3


def test_lstm_burn_in_starts_from_the_stored_carry_and_resets_at_episode_start():
    c = _config("td3", actor="lstm")
    agent = make_agent(c)
    state = agent.init(jax.random.PRNGKey(6))
    batch = _batch(jax.random.PRNGKey(7), seq_len=5)
    carry0 = (jax.random.normal(jax.random.PRNGKey(8), (B, 5, 3)), jax.random.normal(jax.random.PRNGKey(9), (B, 5, 3)))
    batch["carry"] = carry0
    seq = split_batch(batch, burn_in=2)
    outs, after = jax.jit(run_actor, static_argnums=(0, 3))(agent.actor, state.actor, seq, True)
    # By hand: step by step from the stored carry at t=0, zeroing it where an episode starts.
    carry = jax.tree.map(lambda x: np.asarray(x[:, 0]), carry0)
    expected = []
    apply = jax.jit(agent.actor.apply)
    for t in range(5):
        reset = np.asarray(batch["start"][:, t])[:, None]
        carry = jax.tree.map(lambda x: np.where(reset, 0.0, x), carry)
        carry, out = apply(state.actor, carry, batch["obs"][:, t])
        if t >= 2:
            expected.append(out)
            np.testing.assert_allclose(np.asarray(after[1][t - 2]), np.asarray(carry[1]), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(outs), np.asarray(jnp.stack(expected)), rtol=1e-5, atol=1e-6)
    # No gradient flows through the burn-in: only the trained steps' graph depends on the params.
    g = jax.jit(jax.grad(lambda prm: jnp.sum(run_actor(agent.actor, prm, seq, True)[0])))(state.actor)

    def manual(prm):
        cc = jax.tree.map(lambda x: x[:, 0], carry0)
        total = 0.0
        for t in range(5):
            pp = prm if t >= 2 else jax.lax.stop_gradient(prm)
            reset = batch["start"][:, t][:, None]
            cc = jax.tree.map(lambda x: jnp.where(reset, 0.0, x), cc)
            cc, out = agent.actor.apply(pp, cc, batch["obs"][:, t])
            if t >= 2:  # burn-in steps 0-1 only advance the carry
                total = total + out.sum()
        return total
    g2 = jax.jit(jax.grad(manual))(state.actor)
    jax.tree.map(lambda x, y: np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-4, atol=1e-6), g, g2)


@pytest.mark.parametrize("algo", ["td3", "sac"])
def test_learning_rate_zero_freezes_the_networks(algo):
    c = _config(algo, actor_lr=0.0, critic_lr=0.0, alpha_lr=0.0, policy_freq=1)
    agent = make_agent(c)
    state = agent.init(jax.random.PRNGKey(10))
    batch = _batch(jax.random.PRNGKey(11))
    batch["carry"] = (jnp.zeros((B, 1, 1)),)
    new, metrics = jax.jit(agent.update)(state, batch, jax.random.PRNGKey(12), jnp.float32(0.0))
    assert float(metrics["actor_updated"]) == 1.0
    for name in ("actor", "critic", "log_alpha"):
        jax.tree.map(lambda x, y: np.testing.assert_array_equal(np.asarray(x), np.asarray(y)),
                     getattr(state, name), getattr(new, name))
    # The targets start equal to the networks, and a Polyak step (1 - tau) t + tau t returns t up to
    # float rounding (1 ulp under XLA's unoptimised CPU code, exactly under its default): frozen to that.
    for name in ("actor_target", "critic_target"):
        jax.tree.map(lambda x, y: np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-6, atol=1e-7),
                     getattr(state, name), getattr(new, name))


def test_expand_flag_broadcasts_a_row_flag_over_trailing_axes():
    flag = jnp.array([True, False])
    assert expand_flag(flag, jnp.zeros((2, 3, 4))).shape == (2, 1, 1)
    assert expand_flag(flag, jnp.zeros((2,))).shape == (2,)
    picked = jnp.where(expand_flag(flag, jnp.ones((2, 3))), 0.0, jnp.ones((2, 3)))
    np.testing.assert_array_equal(picked, [[0, 0, 0], [1, 1, 1]])


@pytest.mark.parametrize("algo", ["td3", "sac"])
def test_sequence_unroll_changes_the_loop_not_what_an_update_computes(algo):
    # The actor's replay-sequence loop rolled (1 step per iteration, or 2) or unrolled whole (0): one
    # update, actor included, from the same state and batch gives the same networks up to float rounding.
    seq_len = 5
    batch = _batch(jax.random.PRNGKey(21), seq_len)
    batch["carry"] = jax.tree.map(lambda z: jnp.full((B, seq_len) + z.shape[1:], 0.1),
                                  make_agent(_config(algo, actor="lstm")).actor.init_carry((B,)))
    updated = []
    for k in (0, 1, 2):
        agent = make_agent(_config(algo, actor="lstm", policy_freq=1, sequence_unroll=k))
        assert agent.actor.sequence_unroll == k
        state = _perturbed(agent.init(jax.random.PRNGKey(20)))
        new, metrics = jax.jit(agent.update)(state, batch, jax.random.PRNGKey(22), jnp.float32(0.3))
        assert float(metrics["actor_updated"]) == 1.0
        updated.append(new)
    moved = [not np.array_equal(x, y) for x, y in zip(jax.tree.leaves(_np(state.actor)),
                                                      jax.tree.leaves(_np(updated[0].actor)))]
    assert any(moved)   # the update trained the actor: the comparison below is not of untouched networks
    for other in updated[1:]:
        jax.tree.map(lambda x, y: np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-5, atol=1e-6),
                     updated[0], other)
