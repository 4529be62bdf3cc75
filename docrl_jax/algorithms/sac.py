"""DoCRL-S (paper Algorithm 2): SAC with a tanh-Gaussian LSTM (or MLP) actor, twin critics and a
learned temperature alpha (orig: log alpha from 0, target entropy -3).

Per gradient update, on a batch of sequences (see `common.split_batch`):
  target   a' ~ pi(.|s') (online actor; SAC has no target actor), with log-prob logp'
           y  = r + gamma * (1 - terminated) * (min_i Q'_i(s', a') - alpha * logp')
           (with agent.n_step > 1, the n-step return of `common.nstep_targets` of that bootstrap)
  critics  sum_i mean_mask (Q_i(s, a) - y)^2
  actor    every policy_freq critic updates: mean_mask(alpha * logp(a|s) - min_i Q_i(s, a)), a ~ pi(.|s)
  alpha    same steps: -mean_mask(log_alpha * (logp + target_entropy)); then soft critic targets.
With agent.critic_carry every Q reads (s, the actor's carry after s) (`common.critic_view`): the critics
see the memory the actor acts on.
log pi(a|s) of a = tanh(u), u = mean + std * eps: sum(log N(u; mean, std) - log(1 - a^2 + 1e-6)) (orig).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from docrl_jax.algorithms.common import (Agent, AgentState, HParams, SeqBatch, adam, apply_gradients, average_rate,
                                         critic_regression, critic_view, init_agent_state, lr_scale_delta, masked_mean,
                                         critic_step, delayed_policy_step, nstep_targets, run_actor, soft_update,
                                         split_batch)
from docrl_jax.config import Config, observation_size
from docrl_jax.envs import ACTION_SIZE
from docrl_jax.networks import make_actor, make_critic

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


def sample_action(mean, log_std, eps):
    """Reparameterised tanh-Gaussian sample and its log-probability (summed over action dims)."""
    u = mean + jnp.exp(log_std) * eps
    a = jnp.tanh(u)
    logp = jnp.sum(-0.5 * eps ** 2 - log_std - _HALF_LOG_2PI - jnp.log(1.0 - a ** 2 + 1e-6), axis=-1)
    return a, logp


def critic_loss(critic_params, critic, actor, state: AgentState, seq: SeqBatch, eps, a_cfg, memory, hp=None):
    hp = HParams.from_agent_config(a_cfg) if hp is None else hp
    alpha = jnp.exp(state.log_alpha)
    seen = a_cfg.critic_carry
    _, carries_after = run_actor(actor, jax.lax.stop_gradient(state.actor), seq, memory)
    next_carry, (mean, log_std) = actor.apply(state.actor, carries_after, seq.next_obs)
    next_a, next_logp = sample_action(mean, log_std, eps)
    q_next = jnp.min(critic.apply(state.critic_target, critic_view(seq.next_obs, next_carry, seen), next_a),
                     axis=0) - alpha * next_logp
    y = jax.lax.stop_gradient(nstep_targets(seq.reward, seq.terminated, seq.truncated, q_next, hp.gamma,
                                            a_cfg.n_step, hp.discounts))
    q = critic.apply(critic_params, critic_view(seq.obs, carries_after, seen), seq.action)
    return critic_regression(q, y, seq.mask), {"q": masked_mean(q[0], seq.mask), "target": masked_mean(y, seq.mask)}


def actor_loss(actor_params, actor, critic, critic_params, log_alpha, seq: SeqBatch, eps, a_cfg, memory):
    (mean, log_std), carries_after = run_actor(actor, actor_params, seq, memory)
    a, logp = sample_action(mean, log_std, eps)
    q = jnp.min(critic.apply(critic_params, critic_view(seq.obs, carries_after, a_cfg.critic_carry), a), axis=0)
    return masked_mean(jnp.exp(log_alpha) * logp - q, seq.mask), logp


def alpha_loss(log_alpha, logp, target_entropy, mask):
    return -masked_mean(log_alpha * jax.lax.stop_gradient(logp + target_entropy), mask)


def make_sac(config: Config) -> Agent:
    a_cfg, memory = config.agent, config.agent.recurrent
    obs_size = observation_size(config)
    actor = make_actor(a_cfg, obs_size, stochastic=True)
    critic = make_critic(a_cfg)
    # adam(1.0): the learning rates are applied in apply_gradients from HParams (traceable in a sweep)
    actor_tx = critic_tx = alpha_tx = adam(1.0)
    burn_in = config.replay.burn_in
    hparams = HParams.from_agent_config(a_cfg)

    def init(key, hp=None):
        hp = hparams if hp is None else hp
        log_alpha = jnp.asarray(hp.log_init_alpha, jnp.float32)
        return init_agent_state(key, obs_size, actor, critic, actor_tx, critic_tx, log_alpha, alpha_tx,
                                a_cfg.critic_carry)

    def init_noise(num_envs):
        return jnp.zeros((num_envs, ACTION_SIZE))  # unused: SAC explores by sampling

    def act(actor_params, carry, obs):
        """Deterministic action for evaluation: tanh(mean) (orig)."""
        carry, (mean, _) = actor.apply(actor_params, carry, obs)
        return carry, jnp.tanh(mean)

    def explore(state, carry, noise, obs, start, key, progress, hp=None):
        carry, (mean, log_std) = actor.apply(state.actor, carry, obs)
        action, _ = sample_action(mean, log_std, jax.random.normal(key, mean.shape))
        return carry, noise, action

    def update(state: AgentState, batch: dict, key, progress, hp=None):
        hp = hparams if hp is None else hp
        seq = split_batch(batch, burn_in)
        k_next, k_pi = jax.random.split(key)
        eps_next = jax.random.normal(k_next, seq.action.shape)
        eps_pi = jax.random.normal(k_pi, seq.action.shape)
        scale = lr_scale_delta(hp.lr_decay, progress)
        state, c_loss, c_info = critic_step(state, critic_loss, critic_tx, scale, hp.critic_lr,
                                            critic, actor, state, seq, eps_next, a_cfg, memory, hp)

        def policy_step(s: AgentState):
            (a_loss, logp), a_grads = jax.value_and_grad(actor_loss, has_aux=True)(
                s.actor, actor, critic, s.critic, s.log_alpha, seq, eps_pi, a_cfg, memory)
            actor_params, actor_opt = apply_gradients(actor_tx, a_grads, s.actor_opt, s.actor, scale, hp.actor_lr)
            al_loss, al_grad = jax.value_and_grad(alpha_loss)(s.log_alpha, logp, hp.target_entropy, seq.mask)
            log_alpha, alpha_opt = apply_gradients(alpha_tx, al_grad, s.alpha_opt, s.log_alpha, lr=hp.alpha_lr)
            s = s.replace(actor=actor_params, actor_opt=actor_opt, log_alpha=log_alpha, alpha_opt=alpha_opt,
                          actor_average=soft_update(s.actor_average, actor_params, *average_rate(hp, progress)),
                          critic_target=soft_update(s.critic_target, s.critic, hp.tau, hp.tau_keep))
            return s, (a_loss, al_loss)

        state, (a_loss, al_loss), freq, do_policy = delayed_policy_step(state, policy_step, a_cfg.policy_freq,
                                                                        progress, (jnp.zeros(()), jnp.zeros(())))
        metrics = {"critic_loss": c_loss, "actor_loss": a_loss, "alpha_loss": al_loss, "q": c_info["q"],
                   "alpha": jnp.exp(state.log_alpha), "policy_freq": freq,
                   "actor_updated": do_policy.astype(jnp.float32)}
        return state, metrics

    return Agent(actor=actor, init=init, init_noise=init_noise, explore=explore, act=act, update=update,
                 hparams=hparams)
