"""Pieces the TD3/DDPG and SAC agents share: the agent's state, the policy-delay schedule, soft
target updates, masked means, n-step TD targets inside sampled sequences, the learning-rate decay,
and running the LSTM actor over sampled sequences with burn-in."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import optax
from flax import struct

from docrl_jax.envs import ACTION_SIZE
from docrl_jax.networks import carry_features, unroll


@struct.dataclass
class AgentState:
    actor: Any               # online actor params (the one trained)
    actor_average: Any       # Polyak average of `actor` (agent.policy_average_tau): the run's policy
    actor_target: Any        # TD3/DDPG target actor (SAC: unused copy, kept for one layout)
    critic: Any              # online critics
    critic_target: Any
    actor_opt: Any
    critic_opt: Any
    log_alpha: jax.Array     # () SAC temperature (TD3: unused)
    alpha_opt: Any
    updates: jax.Array       # () int32 critic updates done


@struct.dataclass
class HParams:
    """The agent's hyperparameters that shape no array: what `docrl_jax.sweep` passes as traced
    inputs, so that runs differing only in them share one compiled program.

    Each leaf is the exact constant the update uses, computed on the host in double precision
    (e.g. `tau_keep` = 1 - tau, `discounts` = gamma ** k): built from a config with Python floats
    (`from_agent_config`), the default path constant-folds the same numbers it did before; stacked
    into float32 arrays (`stack`), a traced program computes with bit-identical values."""
    actor_lr: Any
    critic_lr: Any
    alpha_lr: Any
    lr_decay: Any            # lr_end_scale - 1: the rate multiplier is 1 + lr_decay * progress
    gamma: Any
    discounts: tuple         # gamma ** k, k = 0 .. n_step (n-step targets)
    tau: Any
    tau_keep: Any            # 1 - tau
    average_tau: Any         # policy_average_tau
    average_keep: Any        # 1 - policy_average_tau
    average_rise: Any        # log(policy_average_tau_start / policy_average_tau); 0 = a constant rate
    policy_noise: Any
    noise_clip: Any
    ou_theta: Any
    ou_sigma: Any
    ou_sigma_delta: Any      # ou_sigma_final - ou_sigma
    target_entropy: Any
    log_init_alpha: Any

    @staticmethod
    def from_agent_config(a) -> "HParams":
        return HParams(actor_lr=a.actor_lr, critic_lr=a.critic_lr, alpha_lr=a.alpha_lr, lr_decay=a.lr_end_scale - 1.0,
                       gamma=a.gamma, discounts=tuple(a.gamma ** k for k in range(a.n_step + 1)), tau=a.tau,
                       tau_keep=1.0 - a.tau, average_tau=a.policy_average_tau, average_keep=1.0 - a.policy_average_tau,
                       average_rise=math.log(a.policy_average_tau_start / a.policy_average_tau)
                       if a.policy_average_tau_start > 0 else 0.0,
                       policy_noise=a.policy_noise, noise_clip=a.noise_clip, ou_theta=a.ou_theta, ou_sigma=a.ou_sigma,
                       ou_sigma_delta=a.ou_sigma_final - a.ou_sigma, target_entropy=a.target_entropy,
                       log_init_alpha=math.log(a.init_alpha))

    @staticmethod
    def stack(hparams: list["HParams"]) -> "HParams":
        """One float32 array per leaf, the runs on the leading axis (rounded once, from double)."""
        import numpy as np
        return jax.tree.map(lambda *xs: np.asarray(xs, np.float64).astype(np.float32), *hparams)


# The config keys HParams carries (docrl_jax.sweep traces these).
HPARAM_KEYS = ("actor_lr", "critic_lr", "alpha_lr", "lr_end_scale", "gamma", "tau", "policy_average_tau",
               "policy_average_tau_start",
               "policy_noise", "noise_clip", "ou_theta", "ou_sigma", "ou_sigma_final", "target_entropy", "init_alpha")


def hparams_neutral(agent_config):
    """The agent config with every HPARAM_KEYS field at its schema default: two configs that differ
    only in those fields become equal (one traced program serves both)."""
    from docrl_jax.config import AgentConfig
    defaults = AgentConfig()
    return dataclasses.replace(agent_config, **{k: getattr(defaults, k) for k in HPARAM_KEYS})


class Agent(NamedTuple):
    """What the trainer needs from an algorithm; every function is pure. `hp` (HParams) defaults
    to `hparams`, the config's values as Python constants; a sweep passes traced ones."""
    actor: Any                                   # flax module: carry, out = actor.apply(params, carry, obs)
    init: Callable                               # (key, hp=None) -> AgentState
    init_noise: Callable                         # num_envs -> exploration-noise state
    explore: Callable                            # (state, carry, noise, obs, start, key, progress, hp=None) -> (carry, noise, action)
    act: Callable                                # (actor_params, carry, obs) -> (carry, action), deterministic
    update: Callable                             # (state, batch, key, progress, hp=None) -> (state, metrics)
    hparams: HParams = None                      # the config's values (Python floats)


def policy_freq(fixed: int, progress: jax.Array) -> jax.Array:
    """Critic updates per actor update. fixed > 0: that constant. fixed == 0: the paper's
    int(1 / (0.5 - t / (3 * max_steps))) with t = max_steps * progress, progress = env steps done /
    total_env_steps clipped to [0, 1]; the denominator stays >= 1/6, so the result is 2, 3 (from 50%),
    4 (from 75%), 5 (from 90%), 6 on the very last step, and never divides by zero or goes negative.
    The 1e-6 keeps float32 rounding from turning an exact 3.0 into 2."""
    if fixed > 0:
        return jnp.asarray(fixed, jnp.int32)
    p = jnp.clip(progress, 0.0, 1.0)
    return jnp.floor(1.0 / (0.5 - p / 3.0) + 1e-6).astype(jnp.int32)


def soft_update(target, online, tau: float, keep=None):
    """(1 - tau) target + tau online; `keep` is 1 - tau when given (HParams holds it, exact)."""
    keep = 1.0 - tau if keep is None else keep
    return jax.tree.map(lambda t, o: keep * t + tau * o, target, online)


def masked_mean(x: jax.Array, mask: jax.Array) -> jax.Array:
    mask = mask.astype(x.dtype)
    return jnp.sum(x * mask) / jnp.maximum(jnp.sum(mask), 1.0)


class SeqBatch(NamedTuple):
    """A sampled batch, time-major ([T, B, ...]), split into burn-in and trained parts."""
    burn_obs: jax.Array
    burn_start: jax.Array
    obs: jax.Array
    start: jax.Array
    action: jax.Array
    reward: jax.Array
    next_obs: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    mask: jax.Array
    carry: Any               # stored carry at the first step of each sequence ([B, ...])


def split_batch(batch: dict, burn_in: int) -> SeqBatch:
    tm = jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), {k: v for k, v in batch.items() if k != "carry"})
    carry0 = jax.tree.map(lambda x: x[:, 0], batch["carry"])
    b = slice(0, burn_in)
    t = slice(burn_in, None)
    return SeqBatch(burn_obs=tm["obs"][b], burn_start=tm["start"][b], obs=tm["obs"][t], start=tm["start"][t],
                    action=tm["action"][t], reward=tm["reward"][t], next_obs=tm["next_obs"][t],
                    terminated=tm["terminated"][t], truncated=tm["truncated"][t], mask=tm["mask"][t],
                    carry=carry0)


def run_actor(actor, params, seq: SeqBatch, memory: bool):
    """Burn the LSTM in from the stored carry without gradient, then run it over the trained steps.
    Returns (outputs [T, B, ...], carries after each trained step's obs [T, B, ...]); the latter is
    the carry with which the actor reads that step's next obs, for the TD target."""
    carry = seq.carry
    if seq.burn_obs.shape[0] > 0:
        _, _, carry, _ = unroll(actor, jax.lax.stop_gradient(params), carry, seq.burn_obs, seq.burn_start, memory)
        carry = jax.lax.stop_gradient(carry)
    _, outs, _, carries_after = unroll(actor, params, carry, seq.obs, seq.start, memory)
    return outs, carries_after


def critic_view(obs, carry, sees_carry: bool):
    """What the critics read: the observation, and with agent.critic_carry the actor's carry after it
    (`carries_after` of `run_actor`), its gradient stopped so that no critic loss trains the actor."""
    if not sees_carry:
        return obs
    return jnp.concatenate([obs, jax.lax.stop_gradient(carry_features(carry))], axis=-1)


def nstep_targets(reward, terminated, truncated, bootstrap, gamma: float, n: int, discounts=None):
    """n-step TD targets inside one sampled window of trained steps (time on axis 0, [T, B]).

    bootstrap[t] is the value of step t's next obs (min of the target critics at the next action,
    SAC's entropy term included). For each t the return sums the rewards of steps t .. t+m-1 and
    bootstraps from step t+m-1's next obs, where m = min(n, steps left in the window, steps until the
    episode ends): a terminated step ends the sum with no bootstrap, a truncated one ends it and
    bootstraps from its true final obs. So no return crosses an episode boundary or the window end
    (the last steps of a window use fewer than n rewards), and n = 1 is the one-step target
        y_t = r_t + gamma (1 - terminated_t) bootstrap_t.
    The rewards come from the behaviour policy, uncorrected, as in D4PG, R2D2 and FastTD3.
    `discounts` (gamma ** k for k = 0 .. n, HParams.discounts) replaces the powers of gamma when given."""
    g = [gamma ** k for k in range(n + 1)] if discounts is None else discounts
    not_term = 1.0 - terminated.astype(jnp.float32)
    if n == 1:
        return reward + g[1] * not_term * bootstrap
    T = reward.shape[0]
    done = terminated | truncated
    t_index = jnp.arange(T).reshape((T,) + (1,) * (reward.ndim - 1))

    def shift(x, k):  # x[t + k], padded past the window's end (those entries are never used)
        return jnp.concatenate([x[k:], jnp.zeros((k,) + x.shape[1:], x.dtype)]) if k else x

    target = jnp.zeros_like(reward)
    partial = jnp.zeros_like(reward)
    running = jnp.ones(reward.shape, bool)
    for k in range(n):
        valid = running & (t_index + k < T)
        partial = partial + jnp.where(valid, g[k] * shift(reward, k), 0.0)
        stop = valid & (shift(done, k) | (k == n - 1) | (t_index + k == T - 1))
        boot = g[k + 1] * shift(not_term, k) * shift(bootstrap, k)
        target = target + jnp.where(stop, partial + boot, 0.0)
        running = valid & ~stop
    return target


def lr_scale(end_scale: float, progress: jax.Array) -> jax.Array:
    """Learning-rate multiplier: 1 at the start of training, falling linearly in env-step progress to
    `end_scale` at the end (1 = constant, the paper's). A decayed rate lets the final policy settle
    instead of swinging between consecutive evaluations."""
    return lr_scale_delta(end_scale - 1.0, progress)


def lr_scale_delta(decay, progress: jax.Array) -> jax.Array:
    """`lr_scale` from decay = end_scale - 1 (HParams.lr_decay)."""
    return 1.0 + decay * jnp.clip(progress, 0.0, 1.0)


def average_rate(hp: HParams, progress: jax.Array):
    """(tau, 1 - tau) of the policy average's next step (agent.policy_average_tau_start): tau falls
    geometrically from the start rate to policy_average_tau as env-step progress goes from 0 to 1, so
    early in a run the policy the trainer evaluates and keeps is close to the improving actor, not
    ~1/tau actor updates behind it. A constant rate is the config's exact constants."""
    rise = hp.average_rise
    if isinstance(rise, float) and rise == 0.0:   # the config's Python floats, no schedule
        return hp.average_tau, hp.average_keep
    tau = hp.average_tau * jnp.exp(rise * (1.0 - jnp.clip(progress, 0.0, 1.0)))
    return tau, jnp.where(rise == 0.0, hp.average_keep, 1.0 - tau)   # (traced: exp(0) is exactly 1)


def adam(lr: float) -> optax.GradientTransformation:
    return optax.adam(lr)


def init_agent_state(key, obs_size: int, actor, critic, actor_tx, critic_tx, log_alpha, alpha_tx,
                     critic_carry: bool = False) -> "AgentState":
    """Fresh actor and critics for observations of `obs_size` floats (targets start equal to them) with
    their optimiser states; with `critic_carry` the critics read the actor's carry beside the obs."""
    k_a, k_c = jax.random.split(key)
    obs, act, carry = jnp.zeros((1, obs_size)), jnp.zeros((1, ACTION_SIZE)), actor.init_carry((1,))
    actor_params = actor.init(k_a, carry, obs)
    critic_params = critic.init(k_c, critic_view(obs, carry, critic_carry), act)
    return AgentState(actor=actor_params, actor_average=actor_params, actor_target=actor_params, critic=critic_params,
                      critic_target=critic_params, actor_opt=actor_tx.init(actor_params),
                      critic_opt=critic_tx.init(critic_params), log_alpha=log_alpha,
                      alpha_opt=alpha_tx.init(log_alpha), updates=jnp.zeros((), jnp.int32))


def apply_gradients(tx: optax.GradientTransformation, grads, opt_state, params, scale=1.0, lr=None):
    """One optimiser step: (new params, new optimiser state). `scale` multiplies the step, which for
    Adam is exactly a learning rate times `scale` (the decay of `lr_scale`) with the same state.
    `lr` (with tx = adam(1.0)) is the learning rate, a Python float or a traced value: adam(1.0)
    negates Adam's direction exactly, so (-d * lr) * scale has the bits adam(lr)'s (d * -lr) * scale
    had, and the optimiser state's layout (hence checkpoints) is the one adam(lr) has."""
    updates, opt_state = tx.update(grads, opt_state, params)
    if lr is not None:
        updates = jax.tree.map(lambda u: u * lr, updates)
    updates = jax.tree.map(lambda u: u * scale, updates)
    return optax.apply_updates(params, updates), opt_state


def critic_step(state, loss_fn, tx: optax.GradientTransformation, scale, lr, *args):
    """One gradient step of the twin critics on `loss_fn(critic params, *args) -> (loss, info)`, the
    update counted. Returns (state, loss, info)."""
    (loss, info), grads = jax.value_and_grad(loss_fn, has_aux=True)(state.critic, *args)
    params, opt_state = apply_gradients(tx, grads, state.critic_opt, state.critic, scale, lr)
    return state.replace(critic=params, critic_opt=opt_state, updates=state.updates + 1), loss, info


def delayed_policy_step(state, policy_step: Callable, fixed_freq: int, progress, skipped):
    """The delayed policy update (TD3's, also DoCRL-S's): `policy_step(state) -> (state, out)` runs on
    every `policy_freq`-th critic update, otherwise the state stays and `skipped` (zeros shaped like
    `out`) stands for its output. Returns (state, out, the frequency, whether it ran)."""
    freq = policy_freq(fixed_freq, progress)
    run = (state.updates % freq) == 0
    state, out = jax.lax.cond(run, policy_step, lambda s: (s, skipped), state)
    return state, out, freq, run


def critic_regression(q: jax.Array, target: jax.Array, mask: jax.Array) -> jax.Array:
    """sum over critic heads of the masked mean squared TD error; q [num, T, B], target [T, B]."""
    m = mask.astype(q.dtype)
    return jnp.sum((q - target[None]) ** 2 * m[None]) / jnp.maximum(jnp.sum(m), 1.0)
