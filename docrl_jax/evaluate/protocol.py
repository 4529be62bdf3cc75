"""What one trial of the paper's evaluation protocol is: the env settings, the nominal start yaw of each
direction and the jitter that makes the N trials of one (scenario, direction) differ.

Used by the evaluator (`docrl_jax.evaluate`, the protocol in full) and by the trainer's training-time
estimate of it (`train.eval_pair_starts: paper`), so both start their trials the same way. The start
and goal of each pair are `docrl_jax.envs.eval_pair`.

Protocol (the paper's "Experimental Results"):
  * For each scenario and both directions ("air_to_water" A-W, "water_to_air" W-A), N trials from
    the paper's start to its target (`docrl_jax.envs.eval_pair`).
  * A trial ends at arrival (3-D distance < 0.5 m, the env's `arrival_distance`), at a collision or
    leaving the vertical bounds (the env's `terminated`), or after `max_steps` = 500 control steps
    (100 s simulated; the paper's episode limit. The original's test had no time limit at all).
  * Trials differ by seed only: the wind (an OU process started from its stationary distribution),
    range noise (`sensor_noise_std`, default 0.01 m here: the order of the original sensors'
    quantisation, 0.015 m LIDAR resolution and 0.02 m sonar bins), the policy's own key, and a
    start jitter: x and y uniform in +-0.1 m around the paper's start, yaw uniform in +-0.1 rad
    around the nominal yaw (0 for A-W: the original's spawn; -pi/2 for W-A: the original's
    commented water spawn, yaw -1.57). See `DEFAULT_EVAL_ENV` and `TrialSpec`.

Per scenario and direction: successes out of N; t_air and t_water, mean +- std (population std,
ddof 0) over the successful trials, in simulated seconds: a control step counts as air or water by
the vehicle's medium at the start of the step (z >= 0 air, z < 0 water), so t_air + t_water is
exactly the trial time (steps * control_dt); collisions (walls, floor, obstacles), out-of-bounds,
time-outs; path length (sum of the per-step displacements), mean +- std over successful trials.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

DIRECTIONS = ("air_to_water", "water_to_air")
SCENARIOS = (1, 2, 3)
# How a trial ends; `run_trials` returns each trial's outcome as an index into this tuple.
OUTCOMES = ("success", "collision", "out_of_bounds", "timeout", "diverged")
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
    import jax  # here: the commands read the constants above before they import JAX
    import jax.numpy as jnp
    k_xy, k_yaw = jax.random.split(key)
    xy = jax.random.uniform(k_xy, (num_trials, 2), minval=-spec.start_jitter_xy, maxval=spec.start_jitter_xy)
    pos = jnp.asarray(start, jnp.float32)[None] + jnp.concatenate([xy, jnp.zeros((num_trials, 1))], -1)
    yaws = yaw + jax.random.uniform(k_yaw, (num_trials,), minval=-spec.yaw_jitter, maxval=spec.yaw_jitter)
    return pos, yaws
