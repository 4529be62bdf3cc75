"""Best-policy tracking (docrl_jax/train/best_policy.py): the selection rule against hand-worked cases, and in
a real run: the kept policy is the checkpointed policy of the evaluation the rule picks from
metrics.csv, a resumed run keeps the same one, and old checkpoints say they have none."""

from __future__ import annotations

import csv

import jax
import numpy as np
import pytest
from _trainer_common import finished_run, tmp_dir

from docrl_jax import checkpoint, runs
from docrl_jax.errors import RunDirError
from docrl_jax.train import best_policy
from docrl_jax.train import load_policy


def _ev(rate, a_w=None, w_a=None):
    ev = {"success_rate": np.asarray(rate, float)}
    if a_w is not None:
        ev.update(success_air_to_water=np.asarray(a_w, float), success_water_to_air=np.asarray(w_a, float))
    return ev


def test_selection_per_seed_weaker_direction_ties_to_the_later():
    params = lambda v: {"w": np.full((3, 2), v, float)}  # noqa: E731  (3 seeds, one 2-vector each)
    best, better = best_policy.update(None, params(0.0), _ev([0.5, 0.5, 0.5], [0.9, 0.9, 0.9], [0.1, 0.1, 0.1]), 0)
    assert better.all() and best.env_steps.tolist() == [0, 0, 0]
    # seed 0: weaker direction 0.2 > 0.1 -> replaced although random goals got worse;
    # seed 1: A-W 1.0 but W-A 0.05 -> min 0.05 < 0.1 -> kept although random goals got better;
    # seed 2: same min 0.1 -> tie -> the later evaluation replaces it.
    best, better = best_policy.update(best, params(1.0), _ev([0.1, 0.9, 0.5], [0.2, 1.0, 0.3], [0.9, 0.05, 0.1]), 100)
    assert better.tolist() == [True, False, True]
    assert best.env_steps.tolist() == [100, 0, 100]
    np.testing.assert_array_equal(best.params["w"][:, 0], [1.0, 0.0, 1.0])
    np.testing.assert_array_equal(best.score, [0.2, 0.1, 0.1])
    # seed 2: the same min again, random goals lower -> still the later: random goals break no tie
    # beside the pairs; seeds 0 and 1 lower -> kept.
    best, better = best_policy.update(best, params(2.0), _ev([0.0, 0.0, 0.4], [0.0, 0.0, 0.1], [0.0, 0.0, 0.9]), 200)
    assert better.tolist() == [False, False, True] and best.env_steps.tolist() == [100, 0, 200]
    # Without paper pairs the random-goal success decides.
    b, better = best_policy.update(None, params(0.0), _ev([0.3, 0.6, 0.9]), 0)
    b, better = best_policy.update(b, params(1.0), _ev([0.4, 0.6, 0.1]), 50)
    assert better.tolist() == [True, True, False]
    m = best_policy.to_meta(b)
    again = best_policy.from_meta(b.params, m)
    assert again.env_steps.tolist() == [50, 50, 0] and again.score.tolist() == b.score.tolist()
    assert "env step 50" in runs.describe_best(m, 0) and "random goals 0.40" in runs.describe_best(m, 0)


def _rows(run_dir):
    with open(run_dir / "metrics.csv", newline="") as fh:
        return list(csv.DictReader(fh))


# The easy run evaluated and checkpointed every chunk. Tracking can only be told apart from keeping the
# latest policy when a seed's best evaluation is not its last, and which evaluation is best depends on
# floating-point details of the CPU (CI once saw seed 1's best move to the last chunk). So the first seed
# of a few whose best is earlier is used; each further run reuses the compiled programs (seconds).
EVERY_CHUNK = dict(train__eval_every=4000, train__checkpoint_every=4000, train__keep_checkpoints=5)
CANDIDATE_SEEDS = (1, 2, 3, 4, 5, 6)


def _best_row(rows):
    rates = [float(r["success_rate"]) for r in rows]
    pick = max(range(len(rows)), key=lambda i: (rates[i], i))  # the best, ties to the later
    return int(rows[pick]["env_steps"]), rates


def _tracking_run():
    """(seed, run directory, env step of its best evaluation) of the first candidate whose best is not its last."""
    seen = {}
    for seed in CANDIDATE_SEEDS:
        run_dir = finished_run(train__seed=seed, **EVERY_CHUNK)
        step, rates = _best_row(_rows(run_dir))
        if 0 < step < 16000:
            return seed, run_dir, step
        seen[seed] = rates
    pytest.fail(f"every candidate seed's best evaluation is its first or last; nothing tells tracking apart: {seen}")


def _assert_same(a, b):
    jax.tree.map(lambda x, y: np.testing.assert_array_equal(np.asarray(x), np.asarray(y)), a, b)


def test_the_run_keeps_the_policy_of_its_best_evaluation():
    _, d, step = _tracking_run()
    best, final = load_policy(d, which="best"), load_policy(d, which="final")
    assert f"env step {step:,}" in best.source and "checkpoint 16000" in best.source
    assert final.source == "final policy of seed index 0: checkpoint 16000"
    default = load_policy(d)   # the run's policy: its best, since it kept one
    assert default.which == "best" and default.source == best.source
    _assert_same(default.params, best.params)
    _, expected, _ = checkpoint.restore(checkpoint.manager(d), step,
                                        abstract_policy=jax.tree.map(lambda x: x[None], best.params))
    _assert_same(jax.tree.map(lambda x: x[0], expected), best.params)
    assert any(not np.array_equal(a, b) for a, b in zip(jax.tree.leaves(best.params), jax.tree.leaves(final.params)))


def test_a_resumed_run_keeps_the_same_best_and_old_checkpoints_have_none():
    from _trainer_common import easy_config
    from docrl_jax.train import cli
    from docrl_jax.train import run as train_run
    seed, finished, _ = _tracking_run()
    d, config = tmp_dir("resume_best"), easy_config(train__seed=seed, **EVERY_CHUNK)
    assert train_run.run(config, d, show_progress=False, stop_after_chunks=3) == cli.EXIT_INTERRUPTED
    assert train_run.run(config, d, resume=True, show_progress=False) == cli.EXIT_OK  # the best comes from the checkpoint
    a, b = load_policy(d, which="best"), load_policy(finished, which="best")
    assert a.source == b.source
    _assert_same(a.params, b.params)
    from pathlib import Path
    old = Path(__file__).resolve().parents[2] / "benchmarks/results/h100/runs/h100_td3_lstm_4096_shaped"
    with pytest.raises(RunDirError, match="holds no best policy.*which='final'"):
        load_policy(old, which="best")
    assert load_policy(old).which == "final"   # the run's policy where none was kept
    with pytest.raises(RunDirError, match="valid choices are final, best"):
        load_policy(old, which="newest")
