"""DoCRL-D (paper Algorithm 1): TD3 with an LSTM (or MLP) actor. With algo "ddpg" the same code is
the paper's "Det." row: one critic, no target smoothing, actor updated on every critic update.

Per gradient update, on a batch of sequences (see `common.split_batch`):
  target   a' = clip(pi'(s') + clip(N(0, policy_noise), -noise_clip, noise_clip), -1, 1)
           y  = r + gamma * (1 - terminated) * min_i Q'_i(s', a')      (truncated steps bootstrap)
           (with agent.n_step > 1, the n-step return of `common.nstep_targets`)
  critics  sum_i mean_mask (Q_i(s, a) - y)^2                          (paper: MSE; orig: Huber)
  actor    every policy_freq critic updates: -mean_mask Q_1(s, pi(s)), then soft updates of the
           target actor and critics with tau (paper: inside the delayed branch).
Exploration: Ornstein-Uhlenbeck noise per env, reset at episode start, scale decayed linearly from
ou_sigma to ou_sigma_final over training.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from docrl_jax.algorithms.common import (Agent, AgentState, HParams, SeqBatch, adam, apply_gradients, average_rate,
                                         critic_regression, init_agent_state, lr_scale_delta, masked_mean,
                                         critic_step, delayed_policy_step, nstep_targets, run_actor, soft_update,
                                         split_batch)
from docrl_jax.config import Config, observation_size
from docrl_jax.envs import ACTION_SIZE
from docrl_jax.networks import make_actor, make_critic


def target_values(critic, critic_target_params, next_action, seq: SeqBatch, noise, a_cfg, hp=None):
    """TD targets y [T, B] from the target actor's raw next actions and a standard-normal `noise`
    sample; `hp` (HParams) defaults to a_cfg's values."""
    hp = HParams.from_agent_config(a_cfg) if hp is None else hp
    smooth = jnp.clip(hp.policy_noise * noise, -hp.noise_clip, hp.noise_clip)
    next_action = jnp.clip(next_action + smooth, -1.0, 1.0)
    q_next = jnp.min(critic.apply(critic_target_params, seq.next_obs, next_action), axis=0)
    return nstep_targets(seq.reward, seq.terminated, seq.truncated, q_next, hp.gamma, a_cfg.n_step, hp.discounts)


def critic_loss(critic_params, critic, actor, state: AgentState, seq: SeqBatch, noise, a_cfg, memory, hp=None):
    next_raw, _ = _target_next_action(actor, state.actor_target, seq, memory)
    y = jax.lax.stop_gradient(target_values(critic, state.critic_target, next_raw, seq, noise, a_cfg, hp))
    q = critic.apply(critic_params, seq.obs, seq.action)                     # [num, T, B]
    return critic_regression(q, y, seq.mask), {"q": masked_mean(q[0], seq.mask), "target": masked_mean(y, seq.mask)}


def _target_next_action(actor, params, seq: SeqBatch, memory):
    _, carries_after = run_actor(actor, params, seq, memory)
    _, next_action = actor.apply(params, carries_after, seq.next_obs)
    return next_action, carries_after


def actor_loss(actor_params, actor, critic, critic_params, seq: SeqBatch, memory):
    action, _ = run_actor(actor, actor_params, seq, memory)
    return -masked_mean(critic.head(critic_params, seq.obs, action, 0), seq.mask)


def make_td3(config: Config) -> Agent:
    a_cfg, memory = config.agent, config.agent.recurrent
    ddpg = a_cfg.algo == "ddpg"
    obs_size = observation_size(config)
    actor = make_actor(a_cfg, obs_size, stochastic=False)
    critic = make_critic(a_cfg)
    # adam(1.0): the learning rates are applied in apply_gradients from HParams (traceable in a sweep)
    actor_tx = critic_tx = adam(1.0)
    burn_in = config.replay.burn_in
    hparams = HParams.from_agent_config(a_cfg)

    def init(key, hp=None):  # TD3/DDPG have no temperature: a constant log_alpha with a frozen optimiser
        return init_agent_state(key, obs_size, actor, critic, actor_tx, critic_tx, jnp.zeros(()), adam(0.0))

    def init_noise(num_envs):
        return jnp.zeros((num_envs, ACTION_SIZE))

    def act(actor_params, carry, obs):
        return actor.apply(actor_params, carry, obs)

    def explore(state, carry, noise, obs, start, key, progress, hp=None):
        """OU noise (orig 5.1): x <- x + theta (0 - x) + sigma N(0, 1), zeroed at episode start."""
        hp = hparams if hp is None else hp
        carry, action = act(state.actor, carry, obs)
        sigma = hp.ou_sigma + hp.ou_sigma_delta * jnp.clip(progress, 0.0, 1.0)
        noise = jnp.where(start[:, None], 0.0, noise)
        noise = noise - hp.ou_theta * noise + sigma * jax.random.normal(key, noise.shape)
        return carry, noise, jnp.clip(action + noise, -1.0, 1.0)

    def update(state: AgentState, batch: dict, key, progress, hp=None):
        hp = hparams if hp is None else hp
        seq = split_batch(batch, burn_in)
        noise = jax.random.normal(key, seq.action.shape) if not ddpg else jnp.zeros(seq.action.shape)
        scale = lr_scale_delta(hp.lr_decay, progress)
        state, c_loss, c_info = critic_step(state, critic_loss, critic_tx, scale, hp.critic_lr,
                                            critic, actor, state, seq, noise, a_cfg, memory, hp)

        def policy_step(s: AgentState):
            a_loss, a_grads = jax.value_and_grad(actor_loss)(s.actor, actor, critic, s.critic, seq, memory)
            new_actor, actor_opt = apply_gradients(actor_tx, a_grads, s.actor_opt, s.actor, scale, hp.actor_lr)
            s = s.replace(actor=new_actor, actor_opt=actor_opt,
                          actor_average=soft_update(s.actor_average, new_actor, *average_rate(hp, progress)),
                          actor_target=soft_update(s.actor_target, new_actor, hp.tau, hp.tau_keep),
                          critic_target=soft_update(s.critic_target, s.critic, hp.tau, hp.tau_keep))
            return s, a_loss

        state, a_loss, freq, do_policy = delayed_policy_step(state, policy_step, a_cfg.policy_freq, progress,
                                                             jnp.zeros(()))
        metrics = {"critic_loss": c_loss, "actor_loss": a_loss, "q": c_info["q"], "policy_freq": freq,
                   "actor_updated": do_policy.astype(jnp.float32)}
        return state, metrics

    return Agent(actor=actor, init=init, init_noise=init_noise, explore=explore, act=act, update=update,
                 hparams=hparams)
