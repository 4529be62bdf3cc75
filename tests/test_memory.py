"""Memory checks before compile (docrl_jax.memory): a run that cannot fit its device is a ConfigError
naming what to lower, with the estimate and the free memory in GiB. The device's free memory is
stubbed, so these run in a second on any machine."""

from __future__ import annotations

import subprocess
import sys

import jax
import pytest

from docrl_jax import memory
from docrl_jax.config import ConfigError, load_config

GIB = 2**30


def _free(monkeypatch, gib, what="NVIDIA H100 80GB HBM3 memory"):
    monkeypatch.setattr(memory, "available_device_bytes", lambda device=None: (int(gib * GIB), what))


def test_replay_larger_than_memory_is_rejected_with_its_size(monkeypatch):
    _free(monkeypatch, 10 / 1024, "available host RAM")
    config = load_config("td3_lstm", backend="cpu")  # 64 envs x 1,024 steps
    with pytest.raises(ConfigError, match=r"replay buffers need 0\.03 GiB \(num_seeds=1 x buffer_size=65536 steps x "
                                          r"\d+ bytes\), more than the 0\.01 GiB of available host RAM; lower "
                                          r"replay.buffer_size"):
        memory.check_memory(config)
    big = load_config("td3_lstm", ["replay.buffer_size=100000000", "train.num_seeds=8"])  # loads: no device check
    assert memory.replay_bytes(big) > 100 * GIB


def test_a_batch_too_large_for_the_device_is_refused_before_compile(monkeypatch):
    # What compiled, then died with RESOURCE_EXHAUSTED allocating 49.6 GB on an 80 GB H100: the
    # packaged td3_lstm at its GPU size with 100,000 sequences per update.
    _free(monkeypatch, 78.0)
    huge = load_config("td3_lstm", ["replay.batch_size=100000"], backend="gpu")
    assert 45 * GIB < memory.critic_activation_bytes(huge) < 55 * GIB
    _free(monkeypatch, 40.0)
    with pytest.raises(ConfigError, match=r"replay.batch_size=100000: the gradient updates need an estimated "
                                          r"\d+\.\d\d GiB .*more than the 40\.00 GiB of NVIDIA H100 80GB HBM3 "
                                          r"memory; lower replay.batch_size"):
        memory.check_memory(huge, devices=jax.devices()[:1])
    # the packaged default at its GPU size fits easily
    memory.check_memory(load_config("td3_lstm", backend="gpu"), devices=jax.devices()[:1])


def test_the_estimate_scales_with_the_seeds_each_device_holds(monkeypatch):
    one = load_config("td3_lstm", backend="gpu")
    three = load_config("td3_lstm", ["train.num_seeds=3"], backend="gpu")
    assert memory.replay_bytes(three) == 3 * memory.replay_bytes(one)
    per_seed = memory.replay_bytes(one) + memory.update_bytes(one)
    _free(monkeypatch, 2.5 * per_seed / GIB)  # room for two seeds, not three
    memory.check_memory(load_config("td3_lstm", ["train.num_seeds=2"], backend="gpu"), devices=jax.devices()[:1])
    with pytest.raises(ConfigError, match=r"num_seeds=3.*lower replay.batch_size"):
        memory.check_memory(three, devices=jax.devices()[:1])


def test_too_many_envs_are_refused_naming_how_many_fit(monkeypatch):
    """The environments of a vectorised step grow with env.num_envs beside a buffer of a set size."""
    many = load_config("td3_lstm", ["env.num_envs=1000000", "replay.buffer_size=20000000"], backend="gpu")
    assert memory.env_bytes(many) == 1_000_000 * memory.ENV_BYTES
    fixed = memory.replay_bytes(many) + memory.update_bytes(many)
    _free(monkeypatch, (fixed + 100_500 * memory.ENV_BYTES) / GIB)   # room for ~100,500 envs beside the buffer
    with pytest.raises(ConfigError, match=r"^env.num_envs=1000000: the environments need an estimated 18\.63 GiB "
                                          r"\(num_seeds=1 x num_envs x ~20 KB: .*: at most ~100(499|500) envs fit; "
                                          r"lower env.num_envs or train.num_seeds$"):
        memory.check_memory(many, devices=jax.devices()[:1])
    memory.check_memory(load_config("td3_lstm", ["env.num_envs=100000", "replay.buffer_size=20000000"],
                                    backend="gpu"), devices=jax.devices()[:1])


def test_the_batch_check_also_runs_on_configs_built_without_validation():
    import dataclasses
    ok = load_config("td3_lstm", ["env.num_envs=4", "replay.buffer_size=256", "replay.batch_size=196"])
    bad = dataclasses.replace(ok, replay=dataclasses.replace(ok.replay, batch_size=4096))
    with pytest.raises(ConfigError, match=r"replay.batch_size=4096: exceeds the 196 distinct sequences"):
        memory.check_memory(bad)


def test_config_does_not_import_sharding_or_memory():
    code = ("import sys, docrl_jax.config as c; c.load_config('td3_lstm'); "
            "print([m for m in ('docrl_jax.sharding', 'docrl_jax.memory') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
