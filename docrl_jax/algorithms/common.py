"""Pieces the TD3/DDPG and SAC agents share: the agent's state, the policy-delay schedule, soft
target updates, masked means, and running the LSTM actor over sampled sequences with burn-in."""

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
    actor: Any               # online actor params
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
    mask: jax.Array
    carry: Any               # stored carry at the first step of each sequence ([B, ...])


def split_batch(batch: dict, burn_in: int) -> SeqBatch:
    tm = jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), {k: v for k, v in batch.items() if k != "carry"})
    carry0 = jax.tree.map(lambda x: x[:, 0], batch["carry"])
    b = slice(0, burn_in)
    t = slice(burn_in, None)
    return SeqBatch(burn_obs=tm["obs"][b], burn_start=tm["start"][b], obs=tm["obs"][t], start=tm["start"][t],
                    action=tm["action"][t], reward=tm["reward"][t], next_obs=tm["next_obs"][t],
                    terminated=tm["terminated"][t], mask=tm["mask"][t], carry=carry0)


def run_actor(actor, params, seq: SeqBatch, memory: bool):
    """Burn the LSTM in from the stored carry without gradient, then run it over the trained steps.
    Returns (outputs [T, B, ...], carries after each trained step's obs [T, B, ...]); the latter is
    the carry with which the actor reads that step's next obs, for the TD target."""
    carry = seq.carry
    if seq.burn_obs.shape[0] > 0:
        _, _, carry = unroll(actor, jax.lax.stop_gradient(params), carry, seq.burn_obs, seq.burn_start, memory)
        carry = jax.lax.stop_gradient(carry)
    _, outs, _, carries_out = _unroll_with_out(actor, params, carry, seq.obs, seq.start, memory)
    return outs, carries_out


def _unroll_with_out(actor, params, carry, obs, start, memory):
    zero = jax.tree.map(jnp.zeros_like, carry)

    def step(c, xs):
        o, s = xs
        c = jax.tree.map(lambda z, v: jnp.where(s.reshape(s.shape + (1,) * (v.ndim - s.ndim)), z, v), zero, c) \
            if memory else zero
        new_c, out = actor.apply(params, c, o)
        after = new_c if memory else zero  # a memoryless actor reads the next obs from a zero carry too
        return new_c, (c, out, after)

    final, (cin, outs, after) = jax.lax.scan(step, carry, (obs, start))
    return cin, outs, final, after


def adam(lr: float) -> optax.GradientTransformation:
    return optax.adam(lr)


def init_agent_state(key, actor, critic, actor_tx, critic_tx, log_alpha, alpha_tx) -> "AgentState":
    """Fresh actor and critics (targets start equal to them) with their optimiser states."""
    k_a, k_c = jax.random.split(key)
    obs, act = jnp.zeros((1, OBS_SIZE)), jnp.zeros((1, ACTION_SIZE))
    actor_params = actor.init(k_a, actor.init_carry((1,)), obs)
    critic_params = critic.init(k_c, obs, act)
    return AgentState(actor=actor_params, actor_target=actor_params, critic=critic_params,
                      critic_target=critic_params, actor_opt=actor_tx.init(actor_params),
                      critic_opt=critic_tx.init(critic_params), log_alpha=log_alpha,
                      alpha_opt=alpha_tx.init(log_alpha), updates=jnp.zeros((), jnp.int32))


def apply_gradients(tx: optax.GradientTransformation, grads, opt_state, params):
    """One optimiser step: (new params, new optimiser state)."""
    updates, opt_state = tx.update(grads, opt_state, params)
    return optax.apply_updates(params, updates), opt_state
