"""Config checks that must fail before anything compiles: each names the key, the bad value and what
to change. Pure config: no JAX device, no compile."""

from __future__ import annotations

import pytest

from docrl_jax.config import ConfigError, load_config, max_batch_size


def test_wall_clock_cadences_default_to_ten_minutes_and_must_be_positive():
    c = load_config("td3_lstm")
    assert c.train.eval_every_minutes == 10.0 and c.train.checkpoint_every_minutes == 10.0
    c = load_config("td3_lstm", ["train.eval_every_minutes=2", "train.checkpoint_every_minutes=0.5"])
    assert c.train.eval_every_minutes == 2.0 and isinstance(c.train.eval_every_minutes, float)
    assert c.train.checkpoint_every_minutes == 0.5
    for key in ("eval_every_minutes", "checkpoint_every_minutes"):
        for bad in ("0", "-1"):
            with pytest.raises(ConfigError, match=rf"train.{key}=-?[01].0: must be > 0"):
                load_config("td3_lstm", [f"train.{key}={bad}"])
        with pytest.raises(ConfigError, match=rf"train.{key}='soon': must be a number"):
            load_config("td3_lstm", [f"train.{key}=soon"])


@pytest.mark.parametrize("value", ["0", "-3"])
def test_a_bad_num_envs_is_named_even_when_the_buffer_is_auto(value):
    # td3_lstm.yaml sets replay.buffer_size: auto (num_envs x steps per env)
    with pytest.raises(ConfigError, match=rf"env.num_envs={value}: must be >= 1"):
        load_config("td3_lstm", [f"env.num_envs={value}"])


def test_a_float_written_num_envs_still_resolves_the_auto_buffer():
    c = load_config("td3_lstm", ["env.num_envs=100.0"], backend="cpu")
    assert c.env.num_envs == 100 and c.replay.buffer_size == 100 * 1024


def test_start_steps_at_or_past_the_end_is_refused():
    with pytest.raises(ConfigError, match=r"train.start_steps=5000: must be < train.total_env_steps=5000: .*"
                                          r"would train nothing"):
        load_config("td3_lstm", ["train.total_env_steps=5000", "train.start_steps=5000"])
    with pytest.raises(ConfigError, match=r"train.start_steps=100000: must be < train.total_env_steps=64"):
        load_config("td3_lstm", ["train.total_env_steps=64"])  # td3_lstm starts after 100,000 steps
    assert load_config("td3_lstm", ["train.total_env_steps=5000", "train.start_steps=4999"]).train.start_steps == 4999


def test_a_batch_larger_than_the_distinct_sequences_is_refused():
    # 4 envs x 64 steps each, 16-step windows: 4 x 49 = 196 distinct sequences; td3_lstm asks for 1,024
    over = ["env.num_envs=4", "replay.buffer_size=256"]
    with pytest.raises(ConfigError, match=r"replay.batch_size=1024: exceeds the 196 distinct sequences .*"
                                          r"env.num_envs=4 x \(replay.buffer_size=256 // num_envs - "
                                          r"replay.seq_len=16 \+ 1\)\); the largest valid batch is 196: lower "
                                          r"replay.batch_size or raise replay.buffer_size"):
        load_config("td3_lstm", over)
    ok = load_config("td3_lstm", over + ["replay.batch_size=196"])
    assert max_batch_size(ok) == 196
    with pytest.raises(ConfigError, match=r"replay.batch_size=197"):
        load_config("td3_lstm", over + ["replay.batch_size=197"])


def test_run_dir_error_lives_beside_config_error():
    from docrl_jax import errors
    assert issubclass(errors.RunDirError, ValueError) and issubclass(errors.ConfigError, ValueError)
    assert not issubclass(errors.RunDirError, errors.ConfigError)


def test_config_and_env_params_share_one_schema_helper():
    import dataclasses

    from docrl_jax import config, errors, schema
    from docrl_jax.envs import EnvParams, make, param_docs

    @dataclasses.dataclass(frozen=True)
    class Example:
        size: int = schema.documented(4, "How many.", choices=(4, 8))
        speed: float = schema.documented(0.5, "How fast (m/s).")

    f = dataclasses.fields(Example)[0]
    assert Example().size == 4 and f.metadata == {"doc": "How many.", "choices": (4, 8)}
    assert schema.field_docs(Example) == {"size": "How many.", "speed": "How fast (m/s)."}
    assert schema.field_docs(Example, "sec") == {"sec.size": "How many.", "sec.speed": "How fast (m/s)."}
    # the two public doc collectors read the same helper
    assert param_docs() == schema.field_docs(EnvParams) and "wind" in param_docs()
    docs = config.field_docs()
    assert schema.field_docs(config.TrainConfig, "train").items() <= docs.items() and "name" in docs
    assert "env" not in docs and "train.eval_every_minutes" in docs
    # one error format, key first, whichever error type
    with pytest.raises(errors.ConfigError, match=r"^train.x=-1: must be >= 0$"):
        schema.fail("train.x", -1, "must be >= 0", error=errors.ConfigError)
    with pytest.raises(ValueError, match=r"^env parameter wind='yes': must be a bool"):
        make(1, wind="yes")
    assert config.ConfigError is errors.ConfigError
