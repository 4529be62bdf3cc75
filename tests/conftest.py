"""Shared fixtures: environments and their jitted functions are built once per parameter set, since
compiling an MJX step costs seconds on CPU while running it costs milliseconds."""

from __future__ import annotations

import functools
import os

# The suite mostly compiles (a run's programs take 30-50 s on 2 cores, running them seconds). XLA's
# CPU back end at optimisation level 1, not 2: measured on the procedural learning test's programs,
# compile 34 s against 51 s and its 160k training steps no slower (45 s against 52 s). Only the
# machine code changes: every comparison in the suite is between programs built under the same flags.
# Set before JAX creates its backend; a subprocess inherits it (and may append its own).
os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_backend_optimization_level=1".strip()

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs


@functools.lru_cache(maxsize=None)
def _env_fns(scenario: int, overrides: tuple):
    env = envs.make(scenario, **dict(overrides))

    def rollout(state, actions):
        def body(s, a):
            s = env.step(s, a)
            return s, (s.obs, s.reward, s.done, s.info)
        return jax.lax.scan(body, state, actions)

    compiled = jax.jit(rollout)

    def padded_rollout(state, actions):
        """Runs len(actions) steps. Always compiles ROLLOUT_STEPS (padding with the last action) so
        every test of one parameter set shares a single compiled program."""
        n = actions.shape[0]
        assert n <= ROLLOUT_STEPS, n
        pad = jnp.broadcast_to(actions[-1], (ROLLOUT_STEPS - n, actions.shape[1]))
        final, outs = compiled(state, jnp.concatenate([actions, pad]))
        return final, jax.tree.map(lambda x: x[:n], outs)

    return env, jax.jit(env.reset_to), padded_rollout


ROLLOUT_STEPS = 80


@pytest.fixture(scope="session")
def same_picture():
    """same_picture(a, b): asserts two renders of the same scene are the same picture. Not bit for
    bit: with another process rendering at the same time (the suite's two workers), Mesa's llvmpipe
    drew a few pixels of one of two identical renders differently (8 of 18,432 values, up to 30 levels
    apart; 1 run in 3, never alone). A different scene differs by a mean of several levels."""
    def check(a, b):
        assert a.shape == b.shape and a.dtype == b.dtype
        diff = np.abs(a.astype(int) - b.astype(int))
        assert (diff > 0).mean() <= 0.002 and diff.mean() <= 0.05, ((diff > 0).mean(), diff.mean())
    return check


@pytest.fixture(scope="session")
def env_fns():
    """env_fns(scenario, **overrides) -> (env, reset_to, rollout), jitted, cached per process.

    rollout(state, actions (T, 3)) -> (final state, (obs, reward, done, info) stacked over T <= 80)."""
    def get(scenario: int = 1, **overrides):
        return _env_fns(scenario, tuple(sorted(overrides.items())))
    return get
