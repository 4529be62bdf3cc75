"""Public names that moved when the package was reorganised: importing an old module name fails
with a message naming the new one, instead of a bare ModuleNotFoundError.

`MOVED_MODULES` is the one list; `docrl_jax/__init__.py` installs the finder that reads it. A command
kept at its old short name (`python -m docrl_jax.sweep`) is a real module that calls `command`.

`lazy_members` is the other import rule of the package: a package's public names that live in heavy
modules are imported when first used.
"""

from __future__ import annotations

import importlib
import importlib.abc
import sys

# old module -> where its contents live now
MOVED_MODULES = {
    "docrl_jax.cli": "docrl_jax.train.cli (the command line) and docrl_jax.train.run (run, resume)",
    "docrl_jax.run_dir": "docrl_jax.runs (the run directory, load_policy) and docrl_jax.train.metrics (metrics.csv rows)",
    "docrl_jax.train_eval": "docrl_jax.train.evaluation",
    "docrl_jax.best_policy": "docrl_jax.train.best_policy",
    "docrl_jax.protocol": "docrl_jax.evaluate.protocol",
    "docrl_jax.paper_results": "docrl_jax.evaluate.paper_results",
    "docrl_jax.train.console": "docrl_jax.console",
}


class MovedModuleError(ModuleNotFoundError):
    """An import of a module that moved; the message names the new module."""


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname in MOVED_MODULES:
            # No `name=`: `from docrl_jax import cli` would then swallow it for a bare "cannot import name".
            raise MovedModuleError(f"{fullname} moved: import {MOVED_MODULES[fullname]} instead")
        return None


def install() -> None:
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _MovedFinder())


def command(module_name: str, target: str, home: str | None = None) -> None:
    """Body of a command module kept at a short name: run `target.main()` under `python -m`, and
    make attribute look-ups on the short module name say the module where the code lives (`home`,
    default `target`)."""
    module = sys.modules[module_name]
    if module_name == "__main__":
        from docrl_jax.console import run_main
        run_main(importlib.import_module(target).main)

    def __getattr__(name):
        if name.startswith("__"):  # the import system's own look-ups
            raise AttributeError(name)
        # ImportError, not AttributeError: `from module import name` would replace the latter's message.
        raise ImportError(f"{module_name}.{name}: {module_name} is only the command; import {name} from {home or target}")
    module.__getattr__ = __getattr__


def moved_names(module_name: str, names: dict[str, str]) -> None:
    """Makes `from module_name import OLD` fail with a message naming where OLD lives now."""
    module = sys.modules[module_name]

    def __getattr__(name):
        if name in names:  # ImportError: `from module import name` keeps its message
            raise ImportError(f"{module_name}.{name} moved: import it from {names[name]}")
        raise AttributeError(f"module {module_name!r} has no attribute {name!r}")
    module.__getattr__ = __getattr__


def lazy_members(package: str, members: dict[str, str]):
    """A module `__getattr__` (PEP 562) for `package`: each name in `members` is imported from its
    module (the dict's value) when first used, then kept. So a package whose public names need
    MuJoCo's MJX or Flax can be imported for its light modules alone (the train command reads its
    config, then loads its stored programs while those heavy imports run)."""
    def __getattr__(name: str):
        if name not in members:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(members[name]), name)
        setattr(sys.modules[package], name, value)
        return value
    return __getattr__
