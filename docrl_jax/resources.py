"""Where the packaged data lives: `assets/` (MJCF scenes) and `configs/` (agent YAML files); and
which versions of the packages are installed (for the provenance written beside results).

Installed (pip install, editable or not), they are the subpackages `docrl_jax.assets` and
`docrl_jax.configs` (pyproject.toml maps the top-level folders there). Run from a plain checkout on
PYTHONPATH (e.g. the GPU machine, which cannot pip install), they are the top-level folders.
"""

from __future__ import annotations

import importlib
from pathlib import Path


def versions(packages) -> dict[str, str | None]:
    """Python's version and each installed package's (None = not installed)."""
    import platform
    from importlib import metadata
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in packages:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def resource_dir(name: str) -> Path:
    """Directory of the packaged `assets` or `configs`."""
    if name not in ("assets", "configs"):
        raise ValueError(f"unknown resource {name!r}; valid: 'assets', 'configs'")
    try:
        return Path(importlib.import_module(f"docrl_jax.{name}").__path__[0])
    except ModuleNotFoundError:
        return Path(__file__).resolve().parent.parent / name
