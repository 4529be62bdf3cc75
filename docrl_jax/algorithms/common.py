"""Pieces the TD3/DDPG and SAC agents share: the agent's state, the policy-delay schedule, soft
target updates, masked means, n-step TD targets inside sampled sequences, the learning-rate decay,
and running the LSTM actor over sampled sequences with burn-in."""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import optax
from flax import struct

from docrl_jax.envs import ACTION_SIZE, OBS_SIZE
from docrl_jax.networks import unroll


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


class Agent(NamedTuple):
    """What the trainer needs from an algorithm; every function is pure."""
    actor: Any                                   # flax module: carry, out = actor.apply(params, carry, obs)
    init: Callable                               # key -> AgentState
    init_noise: Callable                         # num_envs -> exploration-noise state
    explore: Callable                            # (state, carry, noise, obs, start, key, progress) -> (carry, noise, action)
    act: Callable                                # (actor_params, carry, obs) -> (carry, action), deterministic
    update: Callable                             # (state, batch, key, progress) -> (state, metrics)


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


def soft_update(target, online, tau: float):
    return jax.tree.map(lambda t, o: (1.0 - tau) * t + tau * o, target, online)


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


def nstep_targets(reward, terminated, truncated, bootstrap, gamma: float, n: int):
    """n-step TD targets inside one sampled window of trained steps (time on axis 0, [T, B]).

    bootstrap[t] is the value of step t's next obs (min of the target critics at the next action,
    SAC's entropy term included). For each t the return sums the rewards of steps t .. t+m-1 and
    bootstraps from step t+m-1's next obs, where m = min(n, steps left in the window, steps until the
    episode ends): a terminated step ends the sum with no bootstrap, a truncated one ends it and
    bootstraps from its true final obs. So no return crosses an episode boundary or the window end
    (the last steps of a window use fewer than n rewards), and n = 1 is the one-step target
        y_t = r_t + gamma (1 - terminated_t) bootstrap_t.
    The rewards come from the behaviour policy, uncorrected, as in D4PG, R2D2 and FastTD3."""
    not_term = 1.0 - terminated.astype(jnp.float32)
    if n == 1:
        return reward + gamma * not_term * bootstrap
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
        partial = partial + jnp.where(valid, gamma ** k * shift(reward, k), 0.0)
        stop = valid & (shift(done, k) | (k == n - 1) | (t_index + k == T - 1))
        boot = gamma ** (k + 1) * shift(not_term, k) * shift(bootstrap, k)
        target = target + jnp.where(stop, partial + boot, 0.0)
        running = valid & ~stop
    return target


def lr_scale(end_scale: float, progress: jax.Array) -> jax.Array:
    """Learning-rate multiplier: 1 at the start of training, falling linearly in env-step progress to
    `end_scale` at the end (1 = constant, the paper's). A decayed rate lets the final policy settle
    instead of swinging between consecutive evaluations."""
    return 1.0 + (end_scale - 1.0) * jnp.clip(progress, 0.0, 1.0)


def adam(lr: float) -> optax.GradientTransformation:
    return optax.adam(lr)


def init_agent_state(key, actor, critic, actor_tx, critic_tx, log_alpha, alpha_tx) -> "AgentState":
    """Fresh actor and critics (targets start equal to them) with their optimiser states."""
    k_a, k_c = jax.random.split(key)
    obs, act = jnp.zeros((1, OBS_SIZE)), jnp.zeros((1, ACTION_SIZE))
    actor_params = actor.init(k_a, actor.init_carry((1,)), obs)
    critic_params = critic.init(k_c, obs, act)
    return AgentState(actor=actor_params, actor_average=actor_params, actor_target=actor_params, critic=critic_params,
                      critic_target=critic_params, actor_opt=actor_tx.init(actor_params),
                      critic_opt=critic_tx.init(critic_params), log_alpha=log_alpha,
                      alpha_opt=alpha_tx.init(log_alpha), updates=jnp.zeros((), jnp.int32))


def apply_gradients(tx: optax.GradientTransformation, grads, opt_state, params, scale=1.0):
    """One optimiser step: (new params, new optimiser state). `scale` multiplies the step, which for
    Adam is exactly a learning rate times `scale` (the decay of `lr_scale`) with the same state."""
    updates, opt_state = tx.update(grads, opt_state, params)
    updates = jax.tree.map(lambda u: u * scale, updates)
    return optax.apply_updates(params, updates), opt_state


def critic_regression(q: jax.Array, target: jax.Array, mask: jax.Array) -> jax.Array:
    """sum over critic heads of the masked mean squared TD error; q [num, T, B], target [T, B]."""
    m = mask.astype(q.dtype)
    return jnp.sum((q - target[None]) ** 2 * m[None]) / jnp.maximum(jnp.sum(m), 1.0)
