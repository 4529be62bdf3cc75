"""What one trial of the paper's evaluation protocol is: the env settings, the nominal start yaw of each
direction and the jitter that makes the N trials of one (scenario, direction) differ.

Used by the evaluator (`docrl_jax.evaluate`, the protocol in full) and by the trainer's training-time
estimate of it (`docrl_jax.train_eval`, `train.eval_pair_starts: paper`), so both start their trials
the same way. The start and goal of each pair are `docrl_jax.envs.eval_pair`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp

DIRECTIONS = ("air_to_water", "water_to_air")
# Env settings of the evaluation (on top of the scenario's defaults; evaluate --env KEY=VALUE overrides).
DEFAULT_EVAL_ENV = {"sensor_noise_std": 0.01, "wind": True}
# Nominal start yaw per direction (original spawn yaw 0; the commented water spawn has yaw -1.57).
NOMINAL_YAW = {"air_to_water": 0.0, "water_to_air": -math.pi / 2}


@dataclass(frozen=True)
class TrialSpec:
    """How the N trials of one (scenario, direction) differ from each other."""
    start_jitter_xy: float = 0.1   # m, uniform in +-this on x and y
    yaw_jitter: float = 0.1        # rad, uniform in +-this around the nominal yaw


def trial_starts(key, start, num_trials: int, yaw: float, spec: TrialSpec = TrialSpec()):
    """Jittered start positions (N, 3) and yaws (N,)."""
    k_xy, k_yaw = jax.random.split(key)
    xy = jax.random.uniform(k_xy, (num_trials, 2), minval=-spec.start_jitter_xy, maxval=spec.start_jitter_xy)
    pos = jnp.asarray(start, jnp.float32)[None] + jnp.concatenate([xy, jnp.zeros((num_trials, 1))], -1)
    yaws = yaw + jax.random.uniform(k_yaw, (num_trials,), minval=-spec.yaw_jitter, maxval=spec.yaw_jitter)
    return pos, yaws
