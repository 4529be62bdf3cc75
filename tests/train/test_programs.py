"""Every packaged agent, and the original's memoryless LSTM, traces as one pure `train(key)` program
(jax.eval_shape: traced, shape-checked, not compiled, so this stays cheap on CPU)."""

from __future__ import annotations

import jax
import pytest

import yaml

from docrl_jax.config import config_from_dict, load_config, packaged_configs_dir
from docrl_jax.train import make_train, make_trainer

SMALL = ["env.num_envs=4", "train.start_steps=0", "replay.buffer_size=400", "replay.batch_size=8", "train.total_env_steps=64",
         "train.log_every=32", "train.eval_episodes=2", "env.max_episode_steps=20"]


@pytest.mark.parametrize("name, extra", [
    ("td3_lstm", []), ("sac_lstm", []), ("ddpg_mlp", []), ("sac_mlp", []),
    ("td3_lstm", ["agent.memory=false", "replay.seq_len=1", "replay.burn_in=0", "agent.n_step=1"]),
    ("td3_lstm_paper", []), ("sac_lstm_paper", []), ("ddpg_mlp_paper", []), ("sac_mlp_paper", []),
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


@pytest.mark.parametrize("name", ["td3_lstm", "sac_lstm"])
def test_packaged_default_traces_at_its_gpu_size(name):
    """What `--config td3_lstm` builds on a GPU (4,096 envs, 1,024 sequences per update, the auto
    buffer), traced on the CPU: the shapes the GPU will compile."""
    raw = yaml.safe_load((packaged_configs_dir() / f"{name}.yaml").read_text())
    config = config_from_dict(raw, backend="gpu")
    state, metrics = jax.eval_shape(make_train(config), jax.random.PRNGKey(0))
    n, steps = config.env.num_envs, config.replay.buffer_size // config.env.num_envs
    assert (n, steps) == (4096, 256) and state.buffer.data["obs"].shape == (n, steps, 26)
    assert metrics["critic_loss"].shape == (make_trainer(config).num_chunks,)


def test_a_chunk_traces_the_agent_update_once(monkeypatch):
    """Tracing is a cold launch's first cost after the imports: the chunk's gradient updates sit in a
    `lax.cond` whose skip branch needs their output shapes, and reading those shapes must not trace the
    updates a second time (it did: about a fifth of lowering the chunk)."""
    from docrl_jax.train import trainer as trainer_module

    traced, make_agent = [], trainer_module.make_agent

    def counting_agent(config):
        agent = make_agent(config)

        def update(*args, **kwargs):
            traced.append(1)
            return agent.update(*args, **kwargs)
        return agent._replace(update=update)

    monkeypatch.setattr(trainer_module, "make_agent", counting_agent)
    config = load_config("td3_lstm", SMALL + ["train.seed=7"])   # its own config: make_trainer is memoised
    trainer = make_trainer(config)
    state = jax.eval_shape(trainer.init, jax.random.PRNGKey(0))
    jax.jit(trainer.chunk).lower(state)
    assert len(traced) == 1
