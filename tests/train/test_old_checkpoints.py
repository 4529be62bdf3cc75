"""Checkpoints written by an earlier version still resume (docrl_jax.checkpoint.OlderLayout,
docrl_jax.train.run._older_layouts).

tests/data/run_before_training_margins/ is a run of a tiny config stopped after its first chunk by the
package as of commit 4e2d6fc, before `SimState.training_margins` joined the run state, while the best
policy's score still carried a tie-break and while MJX kept the mass matrix dense: its state has one leaf
per env state fewer, at a place in the middle of the tree, and the mass matrix and its factor in another
shape. Read in today's layout it looks damaged; read in the older one, every leaf lands where it belongs
(the actor's average matches the checkpoint's own copy of the policy, stored apart) and the new leaf is
what that version trained with (no margin: off). A run state of the layout in between (margins, dense
mass matrix) is written here and read back leaf by leaf.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from docrl_jax import checkpoint
from docrl_jax.config import load_config
from docrl_jax.errors import RunDirError
from docrl_jax.train import best_policy, make_trainer
from docrl_jax.train.run import _older_layouts

OLD_RUN = Path(__file__).resolve().parents[1] / "data" / "run_before_training_margins"


@pytest.fixture()
def old_run(tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(OLD_RUN, run_dir)
    return run_dir


def _state_shape(config, build=make_trainer):
    """Today's run state of `config` (one seed, one device), traced only."""
    trainer = build(config)
    shape = jax.eval_shape(trainer.init_total, jax.ShapeDtypeStruct((2,), jnp.uint32),
                           jax.ShapeDtypeStruct((), jnp.int32))
    return jax.tree.map(lambda s: jax.ShapeDtypeStruct((1, *s.shape), s.dtype), shape)


def test_a_checkpoint_from_before_training_margins_reads_with_every_leaf_in_place(old_run):
    config = load_config(old_run / "config.yaml")
    shape = _state_shape(config)
    mngr = checkpoint.manager(old_run)
    with pytest.raises(RunDirError, match="no intact checkpoint"):   # today's layout alone
        checkpoint.restore_newest_intact(mngr, shape)
    restored = checkpoint.restore_newest_intact(mngr, shape, older=_older_layouts(config),
                                                best_shape=shape.agent.actor_average)
    assert restored.older.added == ("training_margins", "rot") and restored.step == 64 and not restored.skipped
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


def _mass_matrix_leaf(path) -> bool:
    return any(getattr(k, "name", None) in ("M", "qLD", "qLDiagInv") for k in path)


def test_a_run_state_with_the_dense_mass_matrix_reads_back_leaf_by_leaf(tmp_path, monkeypatch):
    config = load_config(OLD_RUN / "config.yaml")
    today = _state_shape(config)
    # The same run state as the scenes built it before they factored the mass matrix sparse.
    load = mujoco.MjModel.from_xml_path

    def dense(path, *args, **kwargs):
        model = load(path, *args, **kwargs)
        model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
        return model
    with monkeypatch.context() as m:
        m.setattr(mujoco.MjModel, "from_xml_path", dense)
        before = _state_shape(config, make_trainer.__wrapped__)   # not make_trainer's memo of today's env
    # Those versions' env info held no attitude either.
    before = before.replace(env=before.env.replace(info={k: v for k, v in before.env.info.items() if k != "rot"}))
    shapes = {jax.tree_util.keystr(p): leaf.shape for p, leaf in jax.tree_util.tree_flatten_with_path(before)[0]
              if _mass_matrix_leaf(p)}
    assert shapes and any(len(s) == 4 and s[-2:] == (6, 6) for s in shapes.values())   # (seed, env, nv, nv)
    leaves, treedef = jax.tree.flatten(before)
    # Every leaf a different value (its index in the tree, then counting up), to show where it lands.
    written = jax.tree.unflatten(treedef, [(np.arange(np.prod(leaf.shape)) % 97 + i).reshape(leaf.shape).astype(leaf.dtype)
                                           for i, leaf in enumerate(leaves)])
    mngr = checkpoint.manager(tmp_path, create=True)
    meta = {"env_steps": 64, "chunk": 1, "wall_time_s": 1.0, "pending": {}}
    checkpoint.save(mngr, 64, written, written.agent.actor_average, meta)
    with pytest.raises(RunDirError, match="no intact checkpoint"):   # today's layout alone
        checkpoint.restore_newest_intact(mngr, today)
    restored = checkpoint.restore_newest_intact(mngr, today, older=_older_layouts(config))
    assert restored.older.added == ("rot",) and restored.step == 64
    read = [(path, got) for path, got in jax.tree_util.tree_flatten_with_path(restored.state)[0]
            if "'rot'" not in jax.tree_util.keystr(path)]
    for (path, got), want in zip(read, jax.tree.leaves(written)):
        if _mass_matrix_leaf(path):   # the env's next step computes them before it reads them
            assert not np.asarray(got).any(), jax.tree_util.keystr(path)
        else:
            np.testing.assert_array_equal(np.asarray(got), np.asarray(want), err_msg=jax.tree_util.keystr(path))
