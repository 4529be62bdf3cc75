"""Fails if learning breaks: TD3 with the recurrent LSTM actor on the easy task (empty tank, air
goals 1-2 m away, progress shaping, no wind, 100-step episodes) must beat the untrained policy.

Baseline = the same run with learning disabled. With learning rates 0 the actor never changes
(tests/test_algorithms.py::test_learning_rate_zero_freezes_the_networks), so that run's final
evaluation is the initial actor evaluated on the final evaluation's episodes: computed here
directly, which needs no second training run and compares on identical episodes.
Measured on 2 CPU cores, 64 evaluation episodes, runs of 160k env steps (about 40 s after a ~45 s
compile): final success 0.97 / 0.97 / 0.86 for seeds 0 / 1 / 2, untrained 0.02-0.08. Shorter runs
are fragile: the schedules (policy delay, OU decay) follow training progress, and a 100k-step run
reached only 0.31 once float rounding changed its trajectory.
"""

from __future__ import annotations

import csv

import jax
import jax.numpy as jnp
from _trainer_common import easy_config, finished_run

from docrl_jax.train import make_trainer
from docrl_jax.train.programs import compile_programs, eval_keys

STEPS = 160_000
MARGIN = 0.5


def test_td3_lstm_learns_the_easy_task():
    overrides = dict(train__total_env_steps=STEPS, train__eval_every=STEPS, train__checkpoint_every=STEPS)
    run_dir = finished_run(**overrides)
    with open(run_dir / "metrics.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["env_steps"]) for r in rows] == [0, STEPS]
    trained = float(rows[-1]["success_rate"])

    config = easy_config(**overrides)
    programs = compile_programs(config)[0]
    init, evaluate = programs.init, programs.evaluate
    untrained_state = init(jax.random.PRNGKey(config.train.seed)[None],
                           jnp.asarray(make_trainer(config).total_env_steps, jnp.int32))
    untrained = float(evaluate(untrained_state.agent.actor, eval_keys([config.train.seed], STEPS))["success_rate"][0])
    print(f"success after {STEPS} env steps: {trained:.3f}; untrained on the same episodes: {untrained:.3f}")
    assert trained >= untrained + MARGIN, (trained, untrained)
