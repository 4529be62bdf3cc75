"""Sequence replay: insertion order, contiguous windows, episode masks, stored carries come back."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.replay import make_sequence_buffer

NUM_ENVS, CAPACITY, BATCH, SEQ = 3, 10, 512, 4


def _steps(num_steps, seed=0):
    """Per env and time t: a step whose fields encode (env, t), with random episode starts."""
    rng = np.random.default_rng(seed)
    starts = rng.random((num_steps, NUM_ENVS)) < 0.25
    starts[0] = True
    out = []
    for t in range(num_steps):
        code = np.array([100 * e + t for e in range(NUM_ENVS)], np.float32)
        out.append({"obs": np.stack([code, -code], -1), "time": code, "start": starts[t],
                    "carry": (np.stack([code] * 2, -1) + 0.5, np.stack([code] * 2, -1) - 0.5)})
    return out, starts


def _filled(num_steps):
    buf = make_sequence_buffer(NUM_ENVS, CAPACITY, BATCH, SEQ)
    steps, starts = _steps(num_steps)
    example = jax.tree.map(lambda x: x[0], steps[0])
    state = buf.init(example)
    add = jax.jit(buf.add)
    for s in steps:
        state = add(state, s)
    return buf, state, starts


@pytest.mark.parametrize("num_steps", [7, 25])   # before and after the ring wraps
def test_windows_are_contiguous_recent_and_masked_at_episode_starts(num_steps):
    buf, state, starts = _filled(num_steps)
    assert int(state.count) == min(num_steps, CAPACITY) and int(state.pos) == num_steps % CAPACITY
    seqs = jax.device_get(jax.jit(buf.sample)(state, jax.random.PRNGKey(1)))
    time = seqs["time"]
    env = (time[:, 0] // 100).astype(int)
    t0 = (time[:, 0] % 100).astype(int)
    # Contiguous in time, one env per window, inside the written and not yet overwritten steps.
    np.testing.assert_array_equal(time, time[:, :1] + np.arange(SEQ))
    assert t0.min() >= max(0, num_steps - CAPACITY) and t0.max() + SEQ <= num_steps
    # Every valid window start is reachable (uniform sampling over (env, start)).
    assert len(set(zip(env, t0))) == NUM_ENVS * (min(num_steps, CAPACITY) - SEQ + 1)
    # Mask: False from the first later step that starts an episode, so no window mixes episodes.
    for b in range(BATCH):
        s = starts[t0[b]:t0[b] + SEQ, env[b]]
        expected = np.cumsum(np.r_[False, s[1:]]) == 0
        np.testing.assert_array_equal(seqs["mask"][b], expected)
        np.testing.assert_array_equal(seqs["start"][b], s)
    # Stored carries come back exactly, step by step.
    np.testing.assert_array_equal(seqs["carry"][0], time[..., None].repeat(2, -1) + 0.5)
    np.testing.assert_array_equal(seqs["carry"][1], time[..., None].repeat(2, -1) - 0.5)
    np.testing.assert_array_equal(seqs["obs"][..., 1], -time)


def test_can_sample_needs_one_full_window():
    buf, state, _ = _filled(SEQ - 1)
    assert not bool(buf.can_sample(state))
    buf, state, _ = _filled(SEQ)
    assert bool(buf.can_sample(state))


def test_arguments_are_validated():
    with pytest.raises(ValueError, match="capacity=3 steps per env cannot hold one sequence of seq_len=4"):
        make_sequence_buffer(2, 3, 8, 4)
    with pytest.raises(ValueError, match="batch_size=0 must be a positive integer"):
        make_sequence_buffer(2, 8, 0, 4)
    with pytest.raises(ValueError, match="bool 'start' field"):
        make_sequence_buffer(2, 8, 4, 4).init({"obs": jnp.zeros(3)})


def test_batches_drawn_together_are_the_ones_each_key_draws_alone():
    # The trainer draws all the updates of a step in one vmapped call: each batch must be its own key's.
    buf, state, _ = _filled(25)
    keys = jax.vmap(jax.random.split)(jax.random.split(jax.random.PRNGKey(3), 4))[:, 0]
    together = jax.jit(jax.vmap(buf.sample, (None, 0)))(state, keys)
    for i, key in enumerate(keys):
        alone = buf.sample(state, key)
        jax.tree.map(lambda a, b: np.testing.assert_array_equal(a[i], b), together, alone)
    assert not np.array_equal(together["time"][0], together["time"][1])   # different keys, different draws
