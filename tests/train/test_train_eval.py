"""The in-training evaluation (docrl_jax.train.evaluation) against physical certainties, with hand-written
constant policies instead of a trained actor: why a paper pair fails is reported correctly."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.config import load_config
from docrl_jax.train.evaluation import make_evaluation
from docrl_jax.train.metrics import FAILURE_COLUMNS


@pytest.fixture(scope="module")
def evaluate():
    config = load_config("td3_lstm", ["env.num_envs=4", "train.eval_episodes=4", "env.max_episode_steps=300"])

    def act(params, carry, obs):  # the "actor parameters" are the constant action itself
        return carry, jnp.broadcast_to(params, (obs.shape[0], 3))

    return jax.jit(make_evaluation(config, act, lambda shape: jnp.zeros(shape), memory=False, train_env=None).evaluate)


def test_diving_leaves_the_bounds_and_cruising_hits_something(evaluate):
    key = jax.random.PRNGKey(0)
    # Full descent: the W-A start is 0.1 m above the lower bound (-1.1 m), so every W-A episode ends
    # out of bounds within a few steps; nothing is hit on the way down.
    dive = jax.device_get(evaluate(jnp.array([0.0, -1.0, 0.0]), key))
    assert dive["success_water_to_air"] == 0.0
    assert dive["out_of_bounds_water_to_air"] == 1.0 and dive["collision_water_to_air"] == 0.0
    # Full forward speed at constant height from the A-W start (2.5 m up, tank centre), any heading:
    # a wall (4.9 m away) or a riser comes within the 0.5 m collision range long before the 60 s limit.
    cruise = jax.device_get(evaluate(jnp.array([1.0, 0.0, 0.0]), key))
    assert cruise["success_air_to_water"] == 0.0
    assert cruise["collision_air_to_water"] == 1.0 and cruise["out_of_bounds_air_to_water"] == 0.0
    for out in (dive, cruise):
        assert set(FAILURE_COLUMNS) <= set(out)
        for d in ("air_to_water", "water_to_air"):
            total = out[f"success_{d}"] + out[f"collision_{d}"] + out[f"out_of_bounds_{d}"]
            assert 0.0 <= total <= 1.0 + 1e-6  # the rest are time-outs
    np.testing.assert_array_less(-1e-6, [dive["success_rate"], cruise["success_rate"]])


def test_resume_gives_an_older_metrics_csv_the_failure_columns(tmp_path):
    """A run written before the failure columns existed, resumed: the kept rows are re-aligned under
    today's header (new columns empty), rows after the checkpoint are dropped as before."""
    import csv

    from docrl_jax.train.metrics import METRIC_COLUMNS, truncate_metrics
    old = [c for c in METRIC_COLUMNS if c not in FAILURE_COLUMNS]
    path = tmp_path / "metrics.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(old)
        for steps in (0, 100, 200):
            w.writerow([steps if c == "env_steps" else f"{c}-{steps}" for c in old])
    truncate_metrics(path, 100)
    rows = list(csv.DictReader(open(path)))
    assert list(rows[0]) == METRIC_COLUMNS and [r["env_steps"] for r in rows] == ["0", "100"]
    assert rows[1]["success_water_to_air"] == "success_water_to_air-100"
    assert all(rows[1][c] == "" for c in FAILURE_COLUMNS)


def test_paper_pair_starts_are_the_evaluators_trials():
    """train.eval_pair_starts 'paper' draws the evaluator's trial starts (protocol.trial_starts: the same
    numbers for the same key), 'random_yaw' the exact start facing any way."""
    from docrl_jax.evaluate import protocol
    from docrl_jax.envs import eval_pair
    from docrl_jax.train.evaluation import pair_starts
    key = jax.random.PRNGKey(3)
    for direction in protocol.DIRECTIONS:
        start, _ = eval_pair(2, direction)
        pos, yaw = pair_starts("paper", key, start, direction, 200)
        ref_pos, ref_yaw = protocol.trial_starts(key, start, 200, protocol.NOMINAL_YAW[direction])
        np.testing.assert_array_equal(pos, ref_pos)
        np.testing.assert_array_equal(yaw, ref_yaw)
        assert np.all(np.abs(yaw - protocol.NOMINAL_YAW[direction]) <= 0.1 + 1e-6)
        assert np.all(np.abs(pos - np.asarray(start)) <= 0.1 + 1e-6) and np.ptp(pos[:, 0]) > 0.1
        pos, yaw = pair_starts("random_yaw", key, start, direction, 200)
        np.testing.assert_array_equal(pos, np.broadcast_to(np.asarray(start, np.float32), (200, 3)))
        assert yaw.min() < -2.5 and yaw.max() > 2.5


def test_eval_pair_starts_setting():
    assert load_config("td3_lstm").train.eval_pair_starts == "paper"
    from docrl_jax.config import ConfigError
    with pytest.raises(ConfigError, match="valid choices are \\['paper', 'random_yaw'\\]"):
        load_config("td3_lstm", ["train.eval_pair_starts=random"])
