"""Checkpoints written by an earlier version still resume (docrl_jax.checkpoint.OlderLayout,
docrl_jax.train.run._older_layout).

tests/data/run_before_training_margins/ is a run of a tiny config stopped after its first chunk by the
package as of commit 4e2d6fc, before `SimState.training_margins` joined the run state and while the best
policy's score still carried a tie-break: its state has one leaf per env state fewer, at a place in the
middle of the tree. Read in today's layout it looks damaged; read in the older one, every leaf lands where
it belongs (the actor's average matches the checkpoint's own copy of the policy, stored apart) and the
new leaf is what that version trained with (no margin: off).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax import checkpoint
from docrl_jax.config import load_config
from docrl_jax.errors import RunDirError
from docrl_jax.train import best_policy, make_trainer
from docrl_jax.train.run import _older_layout

OLD_RUN = Path(__file__).resolve().parents[1] / "data" / "run_before_training_margins"


@pytest.fixture()
def old_run(tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(OLD_RUN, run_dir)
    return run_dir


def _state_shape(config):
    """Today's run state of `config` (one seed, one device), traced only."""
    trainer = make_trainer(config)
    shape = jax.eval_shape(trainer.init_total, jax.ShapeDtypeStruct((2,), jnp.uint32),
                           jax.ShapeDtypeStruct((), jnp.int32))
    return jax.tree.map(lambda s: jax.ShapeDtypeStruct((1, *s.shape), s.dtype), shape)


def test_a_checkpoint_from_before_training_margins_reads_with_every_leaf_in_place(old_run):
    config = load_config(old_run / "config.yaml")
    shape = _state_shape(config)
    mngr = checkpoint.manager(old_run)
    with pytest.raises(RunDirError, match="no intact checkpoint"):   # today's layout alone
        checkpoint.restore_newest_intact(mngr, shape)
    restored = checkpoint.restore_newest_intact(mngr, shape, older=_older_layout(config),
                                                best_shape=shape.agent.actor_average)
    assert restored.older and restored.step == 64 and not restored.skipped
    margins = [leaf for path, leaf in jax.tree_util.tree_flatten_with_path(restored.state)[0]
               if "training_margins" in jax.tree_util.keystr(path)]
    assert margins and not any(np.asarray(m).any() for m in margins)
    # The policy item was stored apart, in a layout that did not change: the state's copy must match it.
    _, policy, meta = checkpoint.restore(mngr, 64, abstract_policy=shape.agent.actor_average)
    jax.tree.map(lambda a, b: np.testing.assert_array_equal(np.asarray(a), np.asarray(b)),
                 restored.state.agent.actor_average, policy)
    assert int(np.asarray(restored.state.agent.updates)[0]) > 0
    # Its best policy's score was (the pairs' score, a tie-break); today's is the first alone.
    best = best_policy.from_meta(restored.best, meta["best"])
    assert best.score.shape == (1,) and best.env_steps.tolist() == [64]
