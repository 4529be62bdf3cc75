"""Orbax checkpoints of a run: everything needed to resume, and the actor alone for evaluation.

    <run_dir>/checkpoints/<env_steps>/
        state/    the whole runner state of every seed (agent, optimisers, replay buffer, envs, keys)
        policy/   the final (current) policy: the actor's Polyak average (agent.policy_average_tau;
                  the trained actor itself when that is 1), stacked over seeds
                  (`load_policy(..., which="final")`; `--run` loads it where no best/ is kept)
        best/     with train.track_best_policy: each seed's best evaluated policy so far, stacked
                  over seeds (docrl_jax.train.best_policy): the run's policy, what `load_policy` and
                  `--run` load by default
        meta/     JSON: env_steps, chunk, wall_time_s, config name, and the best policies' record

Orbax cannot write zero-size arrays (MJX keeps a few), so a tree is stored as its non-empty leaves
keyed by flat index and rebuilt from an abstract tree of the same structure on restore. A state
field added since a checkpoint was written shifts those indices, and a field stored in another shape
then no longer reads: `OlderLayout` names such fields, and the state reads back with them filled as
the older version ran (or, for values the env recomputes before reading them, with zeros).

Arrays are stored as global arrays, whatever devices held them: a run whose seeds were split over
several devices or processes (docrl_jax.sharding) writes one checkpoint (every process its shards,
process 0 the metadata; `save` is collective), and `restore` places it onto the devices asked for
now: one device by default, or a seed-axis sharding over any number of devices.

A checkpoint is written into a temporary folder and renamed when complete (Orbax), so a crash or a
full disk never leaves a half-written `<env_steps>/`; `save` removes the temporary folder of a
write that failed and raises one `OSError` line. `restore_newest_intact` skips a damaged newest
checkpoint for the one before it and says why.
"""

from __future__ import annotations

import errno
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

from docrl_jax.errors import RunDirError, not_the_data, short_reason

CHECKPOINT_DIR = "checkpoints"
DAMAGED_DIR = "checkpoints_damaged"   # where a resume moves the checkpoints it could not read


def _pack(tree: Any) -> dict[str, Any]:
    return {f"{i:05d}": leaf for i, leaf in enumerate(jax.tree.leaves(tree)) if leaf.size}


@dataclass(frozen=True)
class OlderLayout:
    """How a checkpoint written by an earlier version reads into today's state. `added`: fields (attribute
    names or dict keys anywhere in the tree) that did not exist then, whose leaves take `fill` (ShapeDtypeStruct ->
    array), as those versions behaved. `reshaped`: fields stored then in another shape, as (name,
    today's shape -> the stored one) pairs; their stored leaves are read in that shape and dropped, and
    they take zeros, so only values that the env step computes before it reads them belong here."""
    what: str                                   # what the layout predates, for the resume's message
    added: tuple[str, ...] = ()
    fill: Callable[[Any], np.ndarray] | None = None
    reshaped: tuple[tuple[str, Callable[[tuple], tuple]], ...] = ()

    def stored_index(self, abstract_tree: Any) -> list[int | None]:
        """Each leaf's index in such a checkpoint, None for an added one: the leaves after an added
        leaf sit one place earlier there."""
        out, i = [], 0
        for path, _ in jax.tree_util.tree_flatten_with_path(abstract_tree)[0]:
            if any(_field(k) in self.added for k in path):
                out.append(None)
            else:
                out.append(i)
                i += 1
        return out

    def stored_shapes(self, abstract_tree: Any) -> list[Callable[[tuple], tuple] | None]:
        """Each leaf's `reshaped` rule (today's shape -> the stored one), None for a leaf stored as it is."""
        rules = dict(self.reshaped)
        return [next((rules[_field(k)] for k in path if _field(k) in rules), None)
                for path, _ in jax.tree_util.tree_flatten_with_path(abstract_tree)[0]]


def _field(key) -> Any:
    """A tree path entry's field name: a dataclass attribute's or a dict key's (the env's info)."""
    return getattr(key, "name", getattr(key, "key", None))


def _stored_index(abstract_tree: Any, older: OlderLayout | None) -> list[int | None]:
    n = len(jax.tree.leaves(abstract_tree))
    return list(range(n)) if older is None else older.stored_index(abstract_tree)


def _stored_shapes(abstract_tree: Any, older: OlderLayout | None) -> list[Callable[[tuple], tuple] | None]:
    n = len(jax.tree.leaves(abstract_tree))
    return [None] * n if older is None else older.stored_shapes(abstract_tree)


def _abstract_packed(abstract_tree: Any, sharding: jax.sharding.Sharding | None,
                     older: OlderLayout | None = None) -> dict[str, Any]:
    # An explicit sharding makes Orbax restore onto this machine's devices, whatever the topology the
    # checkpoint was written on (a GPU run evaluated on a CPU, 8 GPUs resumed on 2, say).
    sharding = sharding or jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
    leaves = jax.tree.leaves(abstract_tree)
    shapes = [leaf.shape if rule is None else rule(leaf.shape)
              for leaf, rule in zip(leaves, _stored_shapes(abstract_tree, older))]
    return {f"{i:05d}": jax.ShapeDtypeStruct(shape, leaf.dtype, sharding=sharding)
            for i, leaf, shape in zip(_stored_index(abstract_tree, older), leaves, shapes)
            if i is not None and _size(shape)}


def _size(shape) -> int:
    n = 1
    for s in shape:
        n *= s
    return n


def _unpack(abstract_tree: Any, packed: dict[str, Any], sharding: jax.sharding.Sharding | None = None,
            older: OlderLayout | None = None) -> Any:
    leaves, treedef = jax.tree.flatten(abstract_tree)
    index = _stored_index(abstract_tree, older)
    reshaped = _stored_shapes(abstract_tree, older)

    def value(i, leaf):  # as a host array where it is not read from the checkpoint
        if index[i] is None:
            return np.asarray(older.fill(leaf), leaf.dtype).reshape(leaf.shape)
        if reshaped[i] is not None or not _size(leaf.shape):
            return np.zeros(leaf.shape, leaf.dtype)
        return packed[f"{index[i]:05d}"]

    if sharding is not None:  # global arrays as Orbax placed them; the others placed the same way
        def placed(i, leaf):
            v = value(i, leaf)
            if isinstance(v, np.ndarray):
                return jax.make_array_from_callback(leaf.shape, sharding, lambda where: v[where])
            return v
        return jax.tree.unflatten(treedef, [placed(i, leaf) for i, leaf in enumerate(leaves)])
    # Via numpy: orbax returns arrays *committed* to a device, while the trainer's own arrays are not,
    # and jit would compile the chunk again for the different placement.
    return jax.tree.unflatten(treedef, [jnp.asarray(np.asarray(value(i, leaf))) for i, leaf in enumerate(leaves)])


def manager(run_dir: str | Path, keep: int | None = None, create: bool = False) -> ocp.CheckpointManager:
    options = ocp.CheckpointManagerOptions(max_to_keep=keep, create=create)
    return ocp.CheckpointManager(Path(run_dir).resolve() / CHECKPOINT_DIR, options=options)


class CheckpointWriteError(OSError):
    """A checkpoint could not be written; the message names the folder and the cause."""


def save(mngr: ocp.CheckpointManager, env_steps: int, state: Any, policy_params: Any, meta: dict,
         best_params: Any = None) -> None:
    """Writes one checkpoint synchronously (a Ctrl-C right after must not leave it half written).
    On failure (read-only folder, full disk, ...) removes the partial write and raises
    CheckpointWriteError; the checkpoints written before stay."""
    items = dict(state=ocp.args.StandardSave(_pack(state)), policy=ocp.args.StandardSave(_pack(policy_params)),
                 meta=ocp.args.JsonSave(meta))
    if best_params is not None:
        items["best"] = ocp.args.StandardSave(_pack(best_params))
    try:
        mngr.save(env_steps, args=ocp.args.Composite(**items), force=True)
        mngr.wait_until_finished()
    except Exception as e:  # Orbax wraps OS errors in its own types, sometimes in threads
        root = Path(mngr.directory)
        for partial in root.glob(f"{env_steps}.orbax-checkpoint-tmp*"):
            shutil.rmtree(partial, ignore_errors=True)
        cause = _os_error(e)
        why = (cause.strerror or short_reason(cause)) if cause else short_reason(e)
        raise CheckpointWriteError(cause.errno if cause else errno.EIO,
                                   f"cannot write checkpoint {env_steps} in {root}: {why}") from None


def _os_error(e: BaseException | None) -> OSError | None:
    """The OSError at the root of `e` (Orbax and TensorStore re-raise them as other types)."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, OSError):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def latest_step(run_dir: str | Path) -> int | None:
    path = Path(run_dir) / CHECKPOINT_DIR
    if not path.is_dir():
        return None
    return manager(run_dir).latest_step()


def has_best(mngr: ocp.CheckpointManager, step: int) -> bool:
    """Whether checkpoint `step` holds best policies (runs from before best-policy tracking or
    without train.track_best_policy do not)."""
    return (Path(mngr.directory) / str(step) / "best").is_dir()


def restore(mngr: ocp.CheckpointManager, step: int, abstract_state: Any = None, abstract_policy: Any = None,
            sharding: jax.sharding.Sharding | None = None, item: str = "policy", older: OlderLayout | None = None):
    """Restores (state, policy_params, meta); pass None for an item you do not need; `item="best"`
    reads the best policies (same tree as the policy) in place of the final one. With
    `sharding` (the seed axis over several devices, `SeedPlacement.seed_sharding`) every leaf is
    restored as a global array placed by it (collective over processes); without, as an
    uncommitted array on this process's first device. With `older`, the state is read in that earlier
    version's layout."""
    items = {"meta": ocp.args.JsonRestore()}
    if abstract_state is not None:
        items["state"] = ocp.args.StandardRestore(_abstract_packed(abstract_state, sharding, older))
    if abstract_policy is not None:
        items[item] = ocp.args.StandardRestore(_abstract_packed(abstract_policy, sharding))
    out = mngr.restore(step, args=ocp.args.Composite(**items))
    state = _unpack(abstract_state, out["state"], sharding, older) if abstract_state is not None else None
    policy = _unpack(abstract_policy, out[item], sharding) if abstract_policy is not None else None
    return state, policy, out["meta"]


@dataclass(frozen=True)
class Restored:
    step: int
    state: Any
    best: Any                  # the best policies, or None when not asked for or not in the checkpoint
    meta: dict
    skipped: list              # [(step, why)] of newer checkpoints that could not be read
    older: OlderLayout | None = None   # the earlier layout it was read in (restore_newest_intact's `older`)


def restore_newest_intact(mngr: ocp.CheckpointManager, abstract_state: Any, sharding=None,
                          best_shape: Any = None, older: tuple[OlderLayout, ...] = ()) -> Restored:
    """The newest checkpoint that reads back whole (state, meta and, with `best_shape`, the best
    policies when it holds them), trying older ones when a newer one is damaged (a crash while
    the disk was full, a file deleted by hand). A checkpoint whose state does not read in today's
    layout is read in each `older` one in turn, before it counts as damaged. Raises RunDirError
    naming every checkpoint tried and why, when none reads back."""
    skipped = []
    for step in sorted(mngr.all_steps(), reverse=True):
        try:
            with_best = best_shape is not None and has_best(mngr, step)
            state, best, meta, layout = _restore_run(mngr, step, abstract_state, sharding,
                                                     best_shape if with_best else None, older)
        except Exception as e:  # any unreadable part means the same: try the one before
            unjudged = not_the_data(e, f"checkpoint {step} in {mngr.directory}")
            if unjudged:   # it may be whole: resuming from an older one would throw its progress away
                raise unjudged from None
            skipped.append((step, short_reason(e)))
            continue
        return Restored(step, state, best, meta, skipped, layout)
    tried = "; ".join(f"{s}: {why}" for s, why in skipped) or "none found"
    raise RunDirError(f"no intact checkpoint in {mngr.directory} ({tried})")


def _restore_run(mngr, step: int, abstract_state, sharding, best_shape, older: tuple[OlderLayout, ...]) -> tuple:
    """(state, best, meta, the earlier layout it was read in or None) of checkpoint `step`, in today's
    layout or else the first of the `older` ones that reads; a failure in all raises today's error."""
    def read(layout):
        state, best, meta = restore(mngr, step, abstract_state=abstract_state, sharding=sharding,
                                    abstract_policy=best_shape, item="best", older=layout)
        if not isinstance(meta, dict) or not {"env_steps", "chunk", "wall_time_s", "pending"} <= set(meta):
            raise ValueError("its meta/ holds no run record")
        return state, best, meta
    try:
        return (*read(None), None)
    except Exception as today:
        for layout in older:
            try:
                return (*read(layout), layout)
            except Exception:
                continue
        raise today from None


def set_aside(mngr: ocp.CheckpointManager, steps: list[int]) -> Path | None:
    """Moves damaged checkpoints out of the way (into <run_dir>/checkpoints_damaged/), so the resumed
    run can write those steps again; nothing is deleted. Returns the folder, or None if none moved.
    The caller reloads every process's manager afterwards (`mngr.reload()`)."""
    if not steps:
        return None
    root = Path(mngr.directory)
    aside = root.parent / DAMAGED_DIR
    aside.mkdir(exist_ok=True)
    for step in steps:
        target, n = aside / str(step), 1
        while target.exists():
            target, n = aside / f"{step}.{n}", n + 1
        shutil.move(str(root / str(step)), str(target))
    return aside
