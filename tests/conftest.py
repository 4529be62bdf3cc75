"""Shared fixtures: environments and their jitted functions are built once per parameter set, since
compiling an MJX step costs seconds on CPU while running it costs milliseconds."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
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
def env_fns():
    """env_fns(scenario, **overrides) -> (env, reset_to, rollout), jitted, cached per process.

    rollout(state, actions (T, 3)) -> (final state, (obs, reward, done, info) stacked over T <= 80)."""
    def get(scenario: int = 1, **overrides):
        return _env_fns(scenario, tuple(sorted(overrides.items())))
    return get
