"""The standalone NumPy loader (docrl_jax/export/numpy_policy.py) reproduces every actor the trainer
builds: Flax's OptimizedLSTMCell (gate order, which kernels carry the bias) for TD3 and SAC heads,
the memoryless LSTM, and the MLP actors; it imports numpy alone."""

from __future__ import annotations

import ast
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.algorithms import make_agent
from docrl_jax.config import load_config
from docrl_jax.export import artefacts, export_actor
from docrl_jax.export.runners import load_numpy_module, open_artefact

LOADER = Path(artefacts.__file__).with_name(artefacts.LOADER_FILE)

VARIANTS = {
    "td3_lstm": ("td3_lstm", []),
    "sac_lstm": ("sac_lstm", []),
    "td3_lstm_memoryless": ("td3_lstm", ["agent.memory=false", "replay.burn_in=0"]),
    "ddpg_mlp": ("ddpg_mlp", []),
    "sac_mlp": ("sac_mlp", []),
}


def _actor(name: str, seed: int = 0):
    """A config, its agent and random actor params: kernels ~ N(0, 1/fan_in), biases ~ N(0, 0.3^2), so
    every gate and bias matters (fresh biases would be zeros). NumPy draws them: no compile per shape."""
    base, overrides = VARIANTS[name]
    config = load_config(base, overrides, backend="cpu")
    agent = make_agent(config)
    shapes = jax.eval_shape(agent.actor.init, jax.random.PRNGKey(0), agent.actor.init_carry((1,)), jnp.zeros((1, 26)))
    rng = np.random.default_rng(seed)

    def draw(s):
        scale = 1.0 / np.sqrt(s.shape[0]) if len(s.shape) == 2 else 0.3
        return jnp.asarray(rng.normal(0.0, scale, s.shape).astype(np.float32))
    return config, agent, jax.tree.map(draw, shapes)


def _observations(steps: int, batch: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (steps, batch, 26)).astype(np.float32)


def test_the_loader_imports_numpy_alone():
    tree = ast.parse(LOADER.read_text())
    imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert imported == {"numpy"}


@pytest.mark.parametrize("name", list(VARIANTS))
def test_numpy_policy_matches_the_agents_act(name, tmp_path):
    config, agent, params = _actor(name)
    np.savez(tmp_path / "w.npz", **artefacts.numpy_weights(config, params))
    policy = load_numpy_module(LOADER.parent).NumpyPolicy(tmp_path / "w.npz")
    act = jax.jit(agent.act)
    carry_jax = agent.actor.init_carry((4,))
    carry_np = policy.initial_carry(4)
    assert (carry_np == ()) == (not config.agent.recurrent)
    for obs in _observations(30, 4):
        if not config.agent.recurrent:
            carry_jax = agent.actor.init_carry((4,))
        carry_jax, expected = act(params, carry_jax, obs)
        action, carry_np = policy.step(obs, carry_np)
        assert action.shape == (4, 3) and action.dtype == np.float32
        np.testing.assert_allclose(action, np.asarray(expected), atol=1e-5, rtol=0)
        if config.agent.recurrent:
            for mine, theirs in zip(carry_np, carry_jax):
                np.testing.assert_allclose(mine, np.asarray(theirs), atol=1e-5, rtol=0)


def test_memoryless_lstm_exports_without_carry_inputs(tmp_path):
    """An LSTM trained with agent.memory false acts on a zero carry every step: its step function
    takes the observation alone, in every artefact, as the MLP actors' does."""
    config, agent, params = _actor("td3_lstm_memoryless")
    manifest = export_actor(config, params, tmp_path / "x", source={"test": "fresh"})
    assert manifest["carry"]["names"] == [] and manifest["files"]["onnx"]["inputs"] == ["observation"]
    obs = _observations(5, 2, seed=3)
    for fmt in artefacts.FORMATS:
        runner = open_artefact(tmp_path / "x", fmt)
        for o in obs:
            action, carry = runner.step(o, runner.initial_carry(2))
            assert carry == ()
            expected = agent.act(params, agent.actor.init_carry((2,)), o)[1]
            np.testing.assert_allclose(action, np.asarray(expected), atol=1e-5, rtol=0)
