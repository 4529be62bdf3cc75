"""Every packaged agent, and the original's memoryless LSTM, traces as one pure `train(key)` program
(jax.eval_shape: traced, shape-checked, not compiled, so this stays cheap on CPU)."""

from __future__ import annotations

import jax
import pytest

from docrl_jax.config import load_config
from docrl_jax.train import make_train, make_trainer

SMALL = ["env.num_envs=4", "replay.buffer_size=400", "replay.batch_size=8", "train.total_env_steps=64",
         "train.log_every=32", "train.eval_episodes=2", "env.max_episode_steps=20"]


@pytest.mark.parametrize("name, extra", [
    ("td3_lstm", []), ("sac_lstm", []), ("ddpg_mlp", []), ("sac_mlp", []),
    ("td3_lstm", ["agent.memory=false", "replay.seq_len=1", "replay.burn_in=0"]),
])
def test_make_train_traces_for_every_agent(name, extra):
    config = load_config(name, SMALL + extra)
    state, metrics = jax.eval_shape(make_train(config), jax.random.PRNGKey(0))
    trainer = make_trainer(config)
    assert trainer.num_chunks == 2 and metrics["critic_loss"].shape == (2,)
    assert state.buffer.data["obs"].shape == (4, 100, 26)
    carry = state.buffer.data["carry"]
    assert carry[0].shape == ((4, 100, 32) if config.agent.actor == "lstm" else (4, 100, 1))
    ev = jax.eval_shape(trainer.evaluate, state.agent.actor, jax.random.PRNGKey(1))
    assert {"success_rate", "episode_return", "success_air_to_water", "success_water_to_air"} <= set(ev)
