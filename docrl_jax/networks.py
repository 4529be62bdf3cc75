"""Flax networks of the paper's agents (section "Network Structure", orig code section 5).

Every actor has one calling convention, so the trainer treats LSTM and MLP actors alike:

    carry, out = actor.apply(params, carry, obs)        # obs [..., 26]; carry from `init_carry`

`out` is the action in [-1, 1]^3 for a deterministic actor, or `(mean, log_std)` of the
pre-tanh Gaussian for a stochastic (SAC) actor. An MLP actor passes its 1-float placeholder carry
through unchanged, or, reading stacked observations, carries the frames before the current one. Critics
return one Q-value per critic head, stacked on axis 0.
"""

from __future__ import annotations

from typing import Any, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from docrl_jax.envs import ACTION_SIZE

LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0  # orig SAC clamp


class _Head(nn.Module):
    stochastic: bool

    @nn.compact
    def __call__(self, h):
        if not self.stochastic:
            return jnp.tanh(nn.Dense(ACTION_SIZE, name="out")(h))
        mean = nn.Dense(ACTION_SIZE, name="mean")(h)
        log_std = jnp.clip(nn.Dense(ACTION_SIZE, name="log_std")(h), LOG_STD_MIN, LOG_STD_MAX)
        return mean, log_std


class LSTMActor(nn.Module):
    """LSTM(26 -> units) -> Linear(units -> 3): tanh output (TD3) or Gaussian head (SAC). `sequence_unroll`
    (agent.sequence_unroll) is how `unroll` runs it over a replay sequence; it shapes no parameter."""
    units: int
    stochastic: bool = False
    sequence_unroll: int = 0

    @nn.compact
    def __call__(self, carry, obs):
        carry, h = nn.OptimizedLSTMCell(self.units, name="lstm")(carry, obs)
        return carry, _Head(self.stochastic, name="head")(h)

    def init_carry(self, batch_shape=()):
        zeros = jnp.zeros((*batch_shape, self.units), jnp.float32)
        return (zeros, zeros)  # (c, h), flax's LSTM carry order


class MLPActor(nn.Module):
    """The baselines' actor: hidden ReLU layers -> tanh output or Gaussian head.

    With `frames` > 1 it reads stacked observations: the current one after the `frames` - 1 before it,
    which its carry holds (zeros before an episode's first step), so the trainer stores, burns in and
    resets that carry exactly as it does an LSTM's. `obs_size` sizes that carry."""
    hidden: Sequence[int]
    stochastic: bool = False
    frames: int = 1
    obs_size: int = 0
    sequence_unroll: int = 0   # as LSTMActor's

    @nn.compact
    def __call__(self, carry, obs):
        h = obs
        if self.frames > 1:
            h = jnp.concatenate([carry[0], obs], axis=-1)
            carry = (h[..., obs.shape[-1]:],)  # the oldest frame drops out
        for i, width in enumerate(self.hidden):
            h = nn.relu(nn.Dense(width, name=f"dense_{i}")(h))
        return carry, _Head(self.stochastic, name="head")(h)

    def init_carry(self, batch_shape=()):
        # one float is a placeholder that keeps one carry layout for a memoryless actor
        width = (self.frames - 1) * self.obs_size if self.frames > 1 else 1
        return (jnp.zeros((*batch_shape, width), jnp.float32),)


class QNetwork(nn.Module):
    """One Q-network on concat(obs, action): hidden ReLU layers (each optionally LayerNorm'd before
    the ReLU) -> one float32 value. `dtype` is the activations' dtype; parameters stay float32, and
    LayerNorm's statistics are reduced in float32 whatever the dtype."""
    hidden: Sequence[int]
    layer_norm: bool = False
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, x):
        for i, width in enumerate(self.hidden):
            x = nn.Dense(width, dtype=self.dtype, name=f"dense_{i}")(x)
            if self.layer_norm:
                x = nn.LayerNorm(dtype=self.dtype, name=f"norm_{i}")(x)
            x = nn.relu(x)
        return nn.Dense(1, dtype=self.dtype, name="out")(x)[..., 0].astype(jnp.float32)


class Critic(nn.Module):
    """`num` independent Q-networks on concat(obs, action); returns Q of shape [num, ...].

    The heads are one `nn.vmap`-ed ensemble: their parameters are stacked on a leading axis of size
    `num` (params["params"]["q"]["dense_0"]["kernel"] is [num, in, out]) and XLA runs all heads as one
    batched matmul per layer instead of one small matmul per head. `layer_norm` normalises every hidden
    layer (as in PQN, Brax/Playground SAC and FastTD3-style critics); it keeps the critic stable under
    the large batches and learning rates that make training fast."""
    hidden: Sequence[int]
    num: int = 2
    layer_norm: bool = False
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, obs, action):
        x = jnp.concatenate([obs, action], axis=-1)
        ensemble = nn.vmap(QNetwork, variable_axes={"params": 0}, split_rngs={"params": True},
                           in_axes=None, out_axes=0, axis_size=self.num)
        return ensemble(tuple(self.hidden), self.layer_norm, self.dtype, name="q")(x)

    @nn.nowrap
    def head(self, params, obs, action, index: int = 0):
        """Q of head `index` alone (what `apply(...)[index]` returns) without computing the others:
        the TD3 actor loss reads only the first critic."""
        one = jax.tree.map(lambda p: p[index], params["params"]["q"])
        return QNetwork(tuple(self.hidden), self.layer_norm, self.dtype).apply(
            {"params": one}, jnp.concatenate([obs, action], axis=-1))


def make_actor(agent_config, obs_size: int, stochastic: bool) -> nn.Module:
    """The actor an agent config describes, for observations of `obs_size` floats: an LSTM, or an MLP
    (reading agent.frames stacked observations); a Gaussian head when `stochastic` (SAC)."""
    a = agent_config
    if a.actor == "lstm":
        return LSTMActor(units=a.actor_hidden[0], stochastic=stochastic, sequence_unroll=a.sequence_unroll)
    return MLPActor(hidden=tuple(a.actor_hidden), stochastic=stochastic, frames=a.frames, obs_size=obs_size,
                    sequence_unroll=a.sequence_unroll)


def carry_features(carry) -> jax.Array:
    """An actor carry as one flat feature vector per row ([..., floats]): what critics that see the
    actor's memory (agent.critic_carry) read beside the observation."""
    return jnp.concatenate(jax.tree.leaves(carry), axis=-1)


def make_critic(agent_config) -> Critic:
    """The critic an agent config describes: two heads (TD3, SAC), or one for DDPG (the paper's
    "Det." row); sizes, LayerNorm and activation dtype."""
    return Critic(hidden=tuple(agent_config.critic_hidden), num=1 if agent_config.algo == "ddpg" else 2,
                  layer_norm=agent_config.critic_layer_norm, dtype=jnp.dtype(agent_config.critic_dtype))


def unroll(actor: nn.Module, params, carry, obs_seq, reset_seq, memory: bool = True):
    """Runs the actor over a sequence (time on axis 0): obs_seq [T, ..., 26], reset_seq [T, ...] bool.

    The carry is zeroed *before* a step whose reset flag is set (the first step of an episode), which
    is exactly what happened while acting; with memory=False it is zeroed before every step (the
    original's memoryless LSTM). Returns (carries_in, outputs, final carry, carries_after), each
    stacked on time: carries_in[t] is the carry the actor received at step t, carries_after[t] the one
    it would read step t's *next* obs with (the new carry; a zero carry when memoryless), which is what
    TD targets need.

    The loop is fully unrolled for the short replay sequences (T <= 32): XLA then fuses across time
    steps instead of paying a while-loop iteration (and its kernel launches) per step. An actor with
    `sequence_unroll` k > 0 runs k steps per iteration instead: the same results, a smaller program.
    """
    zero = jax.tree.map(jnp.zeros_like, carry)

    def step(c, xs):
        obs, reset = xs
        if memory:
            c = jax.tree.map(lambda z, v: jnp.where(expand_flag(reset, v), z, v), zero, c)
        else:
            c = zero
        new_c, out = actor.apply(params, c, obs)
        return new_c, (c, out, new_c if memory else zero)

    length = obs_seq.shape[0]
    per_iteration = actor.sequence_unroll or (length if length <= 32 else 1)
    final, (carries_in, outs, after) = jax.lax.scan(step, carry, (obs_seq, reset_seq),
                                                    unroll=max(1, min(per_iteration, length)))
    return carries_in, outs, final, after


def expand_flag(flag, like):
    """Reshapes a per-row flag of shape (B,) (or any leading shape) to broadcast against `like` of shape
    (B, ...): trailing axes of size 1 are appended, e.g. a reset flag (B,) against a carry (B, units)."""
    return flag.reshape(flag.shape + (1,) * (like.ndim - flag.ndim))
