"""How a run is cut into compiled chunks, from its config alone (no env, no tracing): what the trainer
compiles (docrl_jax/train/trainer.py) and what the host loop counts (docrl_jax/train/loop.py)."""

from __future__ import annotations

import math
from typing import NamedTuple


class Schedule(NamedTuple):
    """A run's chunks, from its config alone (no env, no tracing): what the loop counts."""
    iters_per_chunk: int     # iterations (one env step of every env, then the updates) per chunk
    steps_per_chunk: int     # env steps per chunk, all envs together
    num_chunks: int
    total_env_steps: int     # train.total_env_steps rounded up to whole chunks


def schedule(config) -> Schedule:
    """A chunk is `train.log_every` env steps rounded up to whole iterations of `env.num_envs`."""
    n, t = config.env.num_envs, config.train
    iters = max(1, math.ceil(t.log_every / n))
    chunks = max(1, math.ceil(t.total_env_steps / (iters * n)))
    return Schedule(iters, iters * n, chunks, chunks * iters * n)
