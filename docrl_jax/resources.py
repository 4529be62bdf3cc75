"""Where the packaged data lives: `assets/` (MJCF scenes) and `configs/` (agent YAML files).

Installed (pip install, editable or not), they are the subpackages `docrl_jax.assets` and
`docrl_jax.configs` (pyproject.toml maps the top-level folders there). Run from a plain checkout on
PYTHONPATH (e.g. the GPU machine, which cannot pip install), they are the top-level folders.
"""

from __future__ import annotations

import importlib
from pathlib import Path


def resource_dir(name: str) -> Path:
    """Directory of the packaged `assets` or `configs`."""
    if name not in ("assets", "configs"):
        raise ValueError(f"unknown resource {name!r}; valid: 'assets', 'configs'")
    try:
        return Path(importlib.import_module(f"docrl_jax.{name}").__path__[0])
    except ModuleNotFoundError:
        return Path(__file__).resolve().parent.parent / name
