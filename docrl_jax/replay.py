"""Sequence replay over per-env trajectories, flashbax style: `make_sequence_buffer(...)` checks its
arguments and returns pure functions over a `BufferState` pytree that lives in the scan carry.

Layout: every leaf is `[num_envs, capacity, ...]`; row e is env e's own trajectory, written in time
order into a ring (all envs share one write position, since they step together). A stored step is
whatever pytree the trainer adds; it must hold a bool field `start` (this step is the first of an
episode). The trainer stores obs, action, reward, next obs (the true final obs on episode ends),
terminated, truncated, start and the actor's carry at the step.

`sample` draws `batch_size` windows of `seq_len` consecutive steps uniformly over (env, window
start) among windows that lie inside the written data (never across the write position, where old
and new data meet) and returns them as `[batch, seq_len, ...]` with a `mask`: mask[l] is False
from the first step l >= 1 that starts a new episode, so a sequence never mixes two episodes.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class BufferState:
    data: Any            # pytree, leaves [num_envs, capacity, ...]
    pos: jax.Array       # () int32: next write index in [0, capacity)
    count: jax.Array     # () int32: steps written per env, saturates at capacity


class SequenceBuffer(NamedTuple):
    init: Callable[[Any], BufferState]                 # one env's step (unbatched example) -> empty state
    add: Callable[[BufferState, Any], BufferState]     # step with leaves [num_envs, ...] -> state
    sample: Callable[[BufferState, jax.Array], dict]   # (state, key) -> sequences [batch, seq_len, ...]
    can_sample: Callable[[BufferState], jax.Array]     # () bool: at least one full window per env
    num_envs: int
    capacity: int
    batch_size: int
    seq_len: int


def make_sequence_buffer(num_envs: int, capacity: int, batch_size: int, seq_len: int,
                         start_field: str = "start") -> SequenceBuffer:
    for name, value in (("num_envs", num_envs), ("capacity", capacity), ("batch_size", batch_size),
                        ("seq_len", seq_len)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"make_sequence_buffer: {name}={value!r} must be a positive integer")
    if capacity < seq_len:
        raise ValueError(f"make_sequence_buffer: capacity={capacity} steps per env cannot hold one sequence "
                         f"of seq_len={seq_len}; raise the buffer size or lower seq_len")

    def init(example: Any) -> BufferState:
        if not isinstance(example, dict) or start_field not in example:
            raise ValueError(f"make_sequence_buffer: a stored step must be a dict with a bool {start_field!r} field")
        data = jax.tree.map(lambda x: jnp.zeros((num_envs, capacity, *jnp.shape(x)), jnp.asarray(x).dtype),
                            example)
        return BufferState(data=data, pos=jnp.zeros((), jnp.int32), count=jnp.zeros((), jnp.int32))

    def add(state: BufferState, step: Any) -> BufferState:
        data = jax.tree.map(lambda buf, x: jax.lax.dynamic_update_slice_in_dim(buf, x[:, None].astype(buf.dtype),
                                                                               state.pos, axis=1),
                            state.data, step)
        return BufferState(data=data, pos=(state.pos + 1) % capacity, count=jnp.minimum(state.count + 1, capacity))

    def can_sample(state: BufferState) -> jax.Array:
        return state.count >= seq_len

    def sample(state: BufferState, key: jax.Array) -> dict:
        k_env, k_off = jax.random.split(key)
        env = jax.random.randint(k_env, (batch_size,), 0, num_envs)
        windows = jnp.maximum(state.count - seq_len + 1, 1)
        offset = jax.random.randint(k_off, (batch_size,), 0, windows)
        # The oldest stored step is at 0 until the ring is full, then at the write position.
        oldest = jnp.where(state.count < capacity, 0, state.pos)
        idx = (oldest + offset[:, None] + jnp.arange(seq_len)[None, :]) % capacity   # [batch, seq_len]
        seqs = jax.tree.map(lambda buf: buf[env[:, None], idx], state.data)
        starts = seqs[start_field]
        later_start = starts.at[:, 0].set(False)
        seqs["mask"] = jnp.cumsum(later_start, axis=1) == 0
        return seqs

    return SequenceBuffer(init=init, add=add, sample=sample, can_sample=can_sample, num_envs=num_envs,
                          capacity=capacity, batch_size=batch_size, seq_len=seq_len)
