"""What a wheel holds: pyproject.toml lists its packages one by one, and an editable install finds
any folder of the checkout, so a subpackage missing from the list imports in every test here and is
absent from `pip install docrl_jax` (the whole of `docrl_jax.config`, say)."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_every_subpackage_of_the_checkout_ships_in_the_wheel():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "docrl_jax").rglob("__init__.py")}
    assert "docrl_jax.envs" in found and "docrl_jax.config" in found
    assert not found - listed, f"add to [tool.setuptools] packages in pyproject.toml: {sorted(found - listed)}"
