"""Trained policies shipped in the package: evaluate, render and export them without training.

    python -m docrl_jax.evaluate --policy td3_lstm --trials 20 --scenarios 2
    python -m docrl_jax.render --policy sac_mlp_generalist --out flight.gif
    python -m docrl_jax.export --policy td3_lstm --out export/td3_lstm

    from docrl_jax import pretrained
    policy = pretrained.load("td3_lstm")          # a docrl_jax.policy.Policy, as runs.load_policy returns

Each policy is two files here: `<name>.yaml`, the config.yaml of the run that trained it, byte for
byte, and `<name>.npz`, one seed's final actor parameters (float32, keyed by their path in the
parameter tree). README.md in this folder says which run, commit and seed each came from and what it
scores. A policy is flown in its run's vehicle (`vehicle`), as `--run` flies a run's policy.
"""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path
from typing import Any

# Name -> what it is, in a line. The names a command's --policy takes are these and "bba".
PRETRAINED = {
    "td3_lstm": "TD3, LSTM actor: the default config as packaged on 2026-11-27, seed 0 (DoCRL-D)",
    "sac_lstm": "SAC, LSTM actor: Table I's DoCRL-S, seed 0",
    "sac_mlp": "SAC, MLP actor: Table I's Sto., seed 0",
    "sac_mlp_generalist": "SAC, MLP actor, trained on procedural tanks under a randomised plant: the generalist "
                          "(docs/ROBUSTNESS.md), seed 10",
    "sac_mlp_tanks": "SAC, MLP actor, trained on procedural tanks of which half hold structures a person builds: "
                     "fly it with --guide in a tank you know (docs/LEVELS.md), seed 0",
}
BASELINES = ("bba",)
POLICY_NAMES = (*BASELINES, *PRETRAINED)


class UnknownPolicy(ValueError):
    """A --policy name that is neither a shipped policy nor a baseline; the message lists the valid ones."""


def check_name(name: str, flag: str = "--policy") -> str:
    """`name` as given when it is a shipped policy or a baseline; UnknownPolicy (one line naming the
    valid choices) otherwise."""
    if name not in POLICY_NAMES:
        from docrl_jax.schema import did_you_mean
        raise UnknownPolicy(f"{flag} {name!r}: unknown policy; valid choices: {', '.join(POLICY_NAMES)} "
                            f"(or --run RUN_DIR for a trained agent){did_you_mean(name, POLICY_NAMES)}")
    return name


def _file(name: str, suffix: str) -> Path:
    if name not in PRETRAINED:
        raise UnknownPolicy(f"{name!r}: not a shipped policy; valid choices: {', '.join(PRETRAINED)}")
    return Path(str(resources.files(__name__) / f"{name}{suffix}"))


def config(name: str):
    """The `Config` of the run that trained the shipped policy `name`."""
    from docrl_jax.config import load_config
    return load_config(_file(name, ".yaml"))


def vehicle(name: str) -> dict[str, Any]:
    """The vehicle settings the policy `name` was trained in (its config's env section,
    `envs.params.VEHICLE_FIELDS`): evaluate, render and the robustness benchmark fly it in them."""
    import yaml

    from docrl_jax.envs.params import vehicle_overrides
    with open(_file(name, ".yaml")) as f:
        return vehicle_overrides((yaml.safe_load(f) or {}).get("env") or {})


def _actor_shapes(agent):
    import jax
    return jax.eval_shape(agent.init, jax.random.PRNGKey(0)).actor


def _key(path) -> str:
    """'params/head/out/kernel' for a leaf of the actor's (nested dict) parameter tree."""
    return "/".join(str(k.key) for k in path)


@functools.lru_cache(maxsize=None)
def load(name: str):
    """The deterministic `Policy` of the shipped policy `name` (docrl_jax.policy), its params read
    from `<name>.npz` into the actor's parameter tree; ValueError when the file does not match the
    actor its config builds. Kept once loaded: its functions stay the same, so a process that flies
    it again reuses the compiled rollout (cached per policy function)."""
    import jax
    import numpy as np

    from docrl_jax.algorithms import make_agent
    from docrl_jax.runs import actor_policy
    cfg = config(name)
    agent = make_agent(cfg)
    shapes = _actor_shapes(agent)
    with np.load(_file(name, ".npz")) as stored:
        arrays = dict(stored)
    leaves, treedef = jax.tree_util.tree_flatten_with_path(shapes)
    wanted = {_key(path): leaf for path, leaf in leaves}
    if set(wanted) != set(arrays) or any(arrays[k].shape != v.shape for k, v in wanted.items()):
        raise ValueError(f"{name}.npz does not match the actor of {name}.yaml: stored "
                         f"{sorted((k, v.shape) for k, v in arrays.items())}, expected "
                         f"{sorted((k, v.shape) for k, v in wanted.items())}")
    params = jax.tree_util.tree_unflatten(treedef, [jax.numpy.asarray(arrays[_key(p)], leaf.dtype)
                                                    for p, leaf in leaves])
    return actor_policy(cfg, params, f"shipped policy {name}: {PRETRAINED[name]}", agent)


def write(run_dir: str | Path, seed_index: int, name: str, folder: str | Path) -> list[Path]:
    """Writes one seed's final policy of the run in `run_dir` as `<name>.yaml` (its config.yaml, byte
    for byte) and `<name>.npz` under `folder`: how the shipped policies were made (README.md)."""
    import shutil

    import jax
    import numpy as np

    from docrl_jax import runs
    policy = runs.load_policy(run_dir, seed_index=seed_index, which="final")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    config_path = folder / f"{name}.yaml"
    shutil.copyfile(Path(run_dir) / runs.CONFIG_FILE, config_path)
    arrays = {_key(p): np.asarray(leaf, np.float32) for p, leaf in jax.tree_util.tree_leaves_with_path(policy.params)}
    params_path = folder / f"{name}.npz"
    np.savez_compressed(params_path, **arrays)
    return [config_path, params_path]


__all__ = ["PRETRAINED", "BASELINES", "POLICY_NAMES", "UnknownPolicy", "check_name", "config", "vehicle", "load",
           "write"]
