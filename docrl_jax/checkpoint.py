"""Orbax checkpoints of a run: everything needed to resume, and the actor alone for evaluation.

    <run_dir>/checkpoints/<env_steps>/
        state/    the whole runner state of every seed (agent, optimisers, replay buffer, envs, keys)
        policy/   the run's policy: the actor's Polyak average (agent.policy_average_tau; the trained
                  actor itself when that is 1), stacked over seeds (read by `load_policy`)
        best/     with train.track_best_policy: each seed's best evaluated policy so far, stacked
                  over seeds (docrl_jax.best_policy; `load_policy(..., which="best")`)
        meta/     JSON: env_steps, chunk, wall_time_s, config name, and the best policies' record

Orbax cannot write zero-size arrays (MJX keeps a few), so a tree is stored as its non-empty leaves
keyed by flat index and rebuilt from an abstract tree of the same structure on restore.

Arrays are stored as global arrays, whatever devices held them: a run whose seeds were split over
several devices or processes (docrl_jax.sharding) writes one checkpoint (every process its shards,
process 0 the metadata; `save` is collective), and `restore` places it onto the devices asked for
now: one device by default, or a seed-axis sharding over any number of devices.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

CHECKPOINT_DIR = "checkpoints"


def _pack(tree: Any) -> dict[str, Any]:
    return {f"{i:05d}": leaf for i, leaf in enumerate(jax.tree.leaves(tree)) if leaf.size}


def _abstract_packed(abstract_tree: Any, sharding: jax.sharding.Sharding | None) -> dict[str, Any]:
    # An explicit sharding makes Orbax restore onto this machine's devices, whatever the topology the
    # checkpoint was written on (a GPU run evaluated on a CPU, 8 GPUs resumed on 2, say).
    sharding = sharding or jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
    return {f"{i:05d}": jax.ShapeDtypeStruct(leaf.shape, leaf.dtype, sharding=sharding)
            for i, leaf in enumerate(jax.tree.leaves(abstract_tree)) if _size(leaf.shape)}


def _size(shape) -> int:
    n = 1
    for s in shape:
        n *= s
    return n


def _unpack(abstract_tree: Any, packed: dict[str, Any], sharding: jax.sharding.Sharding | None = None) -> Any:
    leaves, treedef = jax.tree.flatten(abstract_tree)
    if sharding is not None:  # global arrays as Orbax placed them; empty leaves placed the same way
        empty = lambda leaf: jax.make_array_from_callback(  # noqa: E731
            leaf.shape, sharding, lambda index: np.zeros(leaf.shape, leaf.dtype)[index])
        return jax.tree.unflatten(treedef, [packed[f"{i:05d}"] if _size(leaf.shape) else empty(leaf)
                                            for i, leaf in enumerate(leaves)])
    out = [packed[f"{i:05d}"] if _size(leaf.shape) else jnp.zeros(leaf.shape, leaf.dtype)
           for i, leaf in enumerate(leaves)]
    # Via numpy: orbax returns arrays *committed* to a device, while the trainer's own arrays are not,
    # and jit would compile the chunk again for the different placement.
    return jax.tree.unflatten(treedef, [jnp.asarray(np.asarray(x)) for x in out])


def manager(run_dir: str | Path, keep: int | None = None, create: bool = False) -> ocp.CheckpointManager:
    options = ocp.CheckpointManagerOptions(max_to_keep=keep, create=create)
    return ocp.CheckpointManager(Path(run_dir).resolve() / CHECKPOINT_DIR, options=options)


def save(mngr: ocp.CheckpointManager, env_steps: int, state: Any, policy_params: Any, meta: dict,
         best_params: Any = None) -> None:
    """Writes one checkpoint synchronously (a Ctrl-C right after must not leave it half written)."""
    items = dict(state=ocp.args.StandardSave(_pack(state)), policy=ocp.args.StandardSave(_pack(policy_params)),
                 meta=ocp.args.JsonSave(meta))
    if best_params is not None:
        items["best"] = ocp.args.StandardSave(_pack(best_params))
    mngr.save(env_steps, args=ocp.args.Composite(**items), force=True)
    mngr.wait_until_finished()


def latest_step(run_dir: str | Path) -> int | None:
    path = Path(run_dir) / CHECKPOINT_DIR
    if not path.is_dir():
        return None
    return manager(run_dir).latest_step()


def has_best(mngr: ocp.CheckpointManager, step: int) -> bool:
    """Whether checkpoint `step` holds best policies (runs before 2026-11-23 or without
    train.track_best_policy do not)."""
    return (Path(mngr.directory) / str(step) / "best").is_dir()


def restore(mngr: ocp.CheckpointManager, step: int, abstract_state: Any = None, abstract_policy: Any = None,
            sharding: jax.sharding.Sharding | None = None, item: str = "policy"):
    """Restores (state, policy_params, meta); pass None for an item you do not need; `item="best"`
    reads the best policies (same tree as the policy) in place of the final one. With
    `sharding` (the seed axis over several devices, `SeedPlacement.seed_sharding`) every leaf is
    restored as a global array placed by it (collective over processes); without, as an
    uncommitted array on this process's first device."""
    items = {"meta": ocp.args.JsonRestore()}
    if abstract_state is not None:
        items["state"] = ocp.args.StandardRestore(_abstract_packed(abstract_state, sharding))
    if abstract_policy is not None:
        items[item] = ocp.args.StandardRestore(_abstract_packed(abstract_policy, sharding))
    out = mngr.restore(step, args=ocp.args.Composite(**items))
    state = _unpack(abstract_state, out["state"], sharding) if abstract_state is not None else None
    policy = _unpack(abstract_policy, out[item], sharding) if abstract_policy is not None else None
    return state, policy, out["meta"]
