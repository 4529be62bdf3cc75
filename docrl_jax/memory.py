"""Will a run fit its devices? Estimates checked before anything is compiled.

    check_memory(config)          # ConfigError naming what to lower, or None

A run's device memory is dominated by two things that the config alone determines:

  * the replay buffers (`replay_bytes`): per stored step the obs, next obs, action, reward and actor
    carry in float32, plus three bool flags, for num_envs x (buffer_size // num_envs) steps per seed;
  * one gradient update (`update_bytes`): the sampled batches (batch_size x seq_len stored steps each, the
    vectorised step's updates_per_step of them drawn together) and
    the critics' activations and gradients, which grow with batch_size x the trained steps x the
    critics' widths and are what a too-large replay.batch_size exhausts.

Each device holds the seeds that `train.devices` gives it (vmapped, so both terms scale with that
count); host-platform (CPU) devices of one process share its RAM. The environments, the evaluation
and the networks' parameters are small next to these and are not counted.

This module sits above `config` and `sharding` (it imports both); `config` imports neither, so
loading a config needs no JAX device.
"""

from __future__ import annotations

from typing import Sequence

import jax

from docrl_jax.config import Config, ConfigError, check_batch_size, observation_size
from docrl_jax.envs import ACTION_SIZE

# Bytes of the critics' activations per trained step, per critic, per hidden unit, in units of one
# float32 (4 bytes). An update keeps each hidden layer's pre-activation and ReLU output for the
# backward pass, their gradients, and runs the critics again for the TD target and the actor loss;
# LayerNorm adds its normalised outputs and statistics. Calibrated from XLA's compiled temp memory of
# one update (`jit(agent.update).lower(...).compile().memory_analysis()`) for the packaged agents:
# measured 7.6 with LayerNorm (td3_lstm, sac_lstm, sac_mlp) and 3.0-4.0 without (td3_lstm_paper,
# ddpg_mlp, whose 512-512 MLP actor is included in its 4.0); td3_lstm with replay.batch_size=100000
# measured 49.5 GB, the allocation that failed on an 80 GB H100 with the replay buffers beside it.
CRITIC_ACTIVATION_FACTOR = {True: 8, False: 4}  # critic_layer_norm -> factor
# The estimate counts 4 bytes per activation whatever agent.critic_dtype is: with bfloat16 critics it
# over-estimates (td3_lstm's measured peak fell from 0.77 to 0.68 GiB), which errs on the safe side.
# Bytes of one environment of the vectorised step, per seed: its state (2.7 KB in a paper scenario,
# 6.1 KB with a tank layout beside it) and its share of the step's working memory (the evaluator's
# rollout of the same env step and actor measured 12.6 KB a trial: docrl_jax/evaluate/trial_memory.py).
ENV_BYTES = 20_000


def carry_size(c: Config) -> int:
    """Floats in one actor carry, as the config's actor makes it (`init_carry`): (c, h) of the LSTM, an
    MLP's previous frames (agent.frames > 1), or a 1-float placeholder for a memoryless MLP actor."""
    from docrl_jax.networks import make_actor
    actor = make_actor(c.agent, observation_size(c), stochastic=False)
    carry = jax.eval_shape(lambda: actor.init_carry(()))   # shapes only: nothing is allocated
    return sum(int(leaf.size) for leaf in jax.tree.leaves(carry))


def step_bytes(c: Config) -> int:
    """Bytes of one stored (or sampled) step: obs, next obs, action, reward and carry in float32,
    plus three bool flags (terminated, truncated, episode start)."""
    return 4 * (2 * observation_size(c) + ACTION_SIZE + 1 + carry_size(c)) + 3


def replay_bytes(c: Config) -> int:
    """Bytes of the replay buffers of all seeds (train.num_seeds)."""
    capacity = c.replay.buffer_size // c.env.num_envs
    return c.train.num_seeds * c.env.num_envs * capacity * step_bytes(c)


def batch_bytes(c: Config) -> int:
    """Bytes of one sampled batch, one seed: batch_size sequences of seq_len steps."""
    return c.replay.batch_size * c.replay.seq_len * step_bytes(c)


def batches_drawn(c: Config) -> int:
    """Batches a vectorised step holds at once, one seed: its updates draw theirs together
    (docrl_jax.train.trainer); counted as one when it makes no update."""
    return max(1, c.train.updates_per_step)


def critic_activation_bytes(c: Config) -> int:
    """Estimated bytes of the critics' activations and gradients in one update, one seed: the critics
    run on the trained steps only (seq_len - burn_in), batch_size x those x sum(critic_hidden) floats
    per critic, times CRITIC_ACTIVATION_FACTOR."""
    critics = 1 if c.agent.algo == "ddpg" else 2
    trained = c.replay.seq_len - c.replay.burn_in
    factor = CRITIC_ACTIVATION_FACTOR[bool(c.agent.critic_layer_norm)]
    return c.replay.batch_size * trained * sum(c.agent.critic_hidden) * 4 * critics * factor


def env_bytes(c: Config) -> int:
    """Estimated bytes of the environments of one seed's vectorised step: env.num_envs x ENV_BYTES."""
    return c.env.num_envs * ENV_BYTES


def update_bytes(c: Config) -> int:
    """Estimated bytes the gradient updates need beyond the replay buffers, one seed: the batches of a
    vectorised step's updates, drawn together (docrl_jax.train.trainer), and one update's activations."""
    return batch_bytes(c) * batches_drawn(c) + critic_activation_bytes(c)


def available_device_bytes(device=None) -> tuple[int | None, str]:
    """Free memory of `device` (default: this process's first device) and what it is: GPU/TPU from
    `memory_stats()`, CPU from the host's MemAvailable. (None, what) when it cannot be read."""
    import jax
    # this process's device: in a multi-process run jax.devices()[0] may belong to another process
    dev = device if device is not None else jax.local_devices()[0]
    if dev.platform != "cpu":
        stats = dev.memory_stats() or {}
        if "bytes_limit" in stats:
            return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0)), f"{dev.device_kind} memory"
        return None, str(dev)
    return available_host_bytes(), "available host RAM"


def available_host_bytes() -> int | None:
    """The host's available RAM (MemAvailable of /proc/meminfo; elsewhere the free pages the OS counts),
    None where neither can be read."""
    import os
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def seeds_per_memory(c: Config, devices: Sequence) -> int:
    """Seeds whose buffers and updates share one memory: those of one device, or, on host-platform
    (CPU) devices, those of all this process's devices (they share its RAM)."""
    import jax
    sharing = len(devices) // jax.process_count() if devices[0].platform == "cpu" else 1
    return c.train.num_seeds // len(devices) * sharing


def check_memory(c: Config, devices: Sequence | None = None) -> None:
    """Refuses (ConfigError) a config whose batch cannot be sampled from its buffer, or whose replay
    buffers plus one update's estimated memory (per device, for the seeds it holds) exceed the
    device's free memory. `devices`: the devices the seeds are split over; None resolves
    train.devices with `sharding.seed_devices`, so an impossible device count is refused here too.
    Call it after loading a config and before compiling."""
    check_batch_size(c)
    if devices is None:
        from docrl_jax.sharding import seed_devices
        devices, _ = seed_devices(c.train)
    devices = tuple(devices)
    import jax
    mine = [d for d in devices if d.process_index == jax.process_index()]
    free, what = available_device_bytes(mine[0] if mine else None)
    if free is None:
        return
    seeds = seeds_per_memory(c, devices)
    held = f"num_seeds={c.train.num_seeds}" if seeds == c.train.num_seeds else \
        f"{seeds} of num_seeds={c.train.num_seeds} over {len(devices)} devices"
    replay = replay_bytes(c) // c.train.num_seeds * seeds
    if replay > free:
        raise ConfigError(
            f"replay buffers need {replay / 2**30:.2f} GiB ({held} x buffer_size={c.replay.buffer_size} steps "
            f"x {step_bytes(c)} bytes), more than the {free / 2**30:.2f} GiB of {what}; lower "
            f"replay.buffer_size (auto: steps per env x env.num_envs={c.env.num_envs}) or "
            f"train.num_seeds, or split the seeds over more devices (train.devices)")
    update = update_bytes(c) * seeds
    if replay + update > free:
        r = c.replay
        raise ConfigError(
            f"replay.batch_size={r.batch_size}: the gradient updates need an estimated {update / 2**30:.2f} GiB "
            f"({held}: {batches_drawn(c)} batches of {r.batch_size} x seq_len={r.seq_len} steps, "
            f"drawn together for a vectorised step's updates, and one update's critics' activations "
            f"for {r.batch_size} x {r.seq_len - r.burn_in} trained steps x critic_hidden="
            f"{list(c.agent.critic_hidden)}) beside {replay / 2**30:.2f} GiB of replay buffers, "
            f"{(replay + update) / 2**30:.2f} GiB in all, more than the {free / 2**30:.2f} GiB of {what}; "
            f"lower replay.batch_size (or replay.seq_len, agent.critic_hidden), replay.buffer_size or "
            f"train.num_seeds, or split the seeds over more devices (train.devices)")
    envs = env_bytes(c) * seeds
    if replay + update + envs > free:
        most = max(0, int((free - replay - update) // (ENV_BYTES * seeds)))
        raise ConfigError(
            f"env.num_envs={c.env.num_envs}: the environments need an estimated {envs / 2**30:.2f} GiB ({held} x "
            f"num_envs x ~{ENV_BYTES // 1000} KB: each env's state and its share of a vectorised step) beside "
            f"{(replay + update) / 2**30:.2f} GiB of replay buffers and updates, more than the {free / 2**30:.2f} GiB "
            f"of {what}: at most ~{most} envs fit; lower env.num_envs or train.num_seeds")


# The name config.py exported before this module existed; same check.
check_replay_memory = check_memory
