"""What a run directory's config.yaml says that the evaluation commands need before loading a policy:
its name, its seed count, the vehicle its policy flies in, and the cheap checks of the directory."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from docrl_jax import pretrained
from docrl_jax.errors import RunDirError


def run_config(run_dir: str | os.PathLike) -> dict:
    """A run directory's config.yaml as plain YAML."""
    # Plain YAML rather than runs.read_config: only name, train.num_seeds and agent are read here, and
    # a config of an older version still gets its policy loaded (or a precise error) by load_policy.
    from docrl_jax import runs   # (runs imports JAX: the commands check their arguments first)
    with open(Path(run_dir) / runs.CONFIG_FILE) as f:
        return yaml.safe_load(f) or {}


def run_vehicle(run_dir: str | os.PathLike | None, policy: str | None = None) -> dict:
    """The vehicle settings of a run's config.yaml (`envs.params.VEHICLE_FIELDS`, e.g. env.vel_i_rate),
    which its policy is flown in; a shipped policy's (`policy`, a --policy name) when run_dir is None;
    {} for a baseline."""
    from docrl_jax.envs.params import vehicle_overrides
    if run_dir is None:
        return pretrained.vehicle(policy) if policy in pretrained.PRETRAINED else {}
    return vehicle_overrides(run_config(run_dir).get("env") or {})


def check_run_dir(run_dir: str | os.PathLike) -> Path:
    """Cheap checks of a run directory before load_policy: exists, is a directory, has config.yaml."""
    from docrl_jax import runs
    path = Path(run_dir)
    if not path.exists():
        raise RunDirError(f"run directory {str(path)!r} does not exist")
    if not path.is_dir():
        raise RunDirError(f"run directory {str(path)!r} is not a directory")
    if not (path / runs.CONFIG_FILE).is_file():
        found = sorted(x.name for x in path.iterdir())[:20]
        raise RunDirError(f"run directory {str(path)!r} has no config.yaml (is it a trainer run dir? "
                          f"it contains: {found or 'nothing'})")
    return path


def config_name(run_dir: str | os.PathLike) -> str:
    """The `name` in a run directory's config.yaml (its folder's name if it has none)."""
    return str(run_config(run_dir).get("name") or Path(run_dir).resolve().name)


def run_num_seeds(run_dir: str | os.PathLike) -> int:
    """How many seeds a run directory trained (vmapped in one process): train.num_seeds of its config.yaml."""
    train = run_config(run_dir).get("train") or {}
    try:
        return max(1, int(train.get("num_seeds", 1)))
    except (TypeError, ValueError):
        raise RunDirError(f"{run_dir}: config.yaml has train.num_seeds={train.get('num_seeds')!r}, "
                          "not a positive integer; pass --seed-index explicitly") from None
