"""Documented dataclass fields and their errors, shared by the trainer's config (docrl_jax.config)
and the environment's parameters (docrl_jax.envs.params).

    x: float = documented(0.5, "What x means, its unit and its source.", choices=None)
    field_docs(EnvParams)              -> {"x": "What x means, ..."}
    field_docs(TrainConfig, "train")   -> {"train.x": ...}
    fail("train.x", -1, "must be >= 0", error=ConfigError)   # raises "train.x=-1: must be >= 0"

Every field carries its documentation where it is declared (CleanRL style), so error messages, the
README and `--help` texts read one source, and every error names the key, the bad value and why.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NoReturn


def documented(default: Any, doc: str, choices: tuple | None = None) -> Any:
    """A dataclass field with `default`, its documentation and, where the values are a closed set,
    the valid `choices` (checked by the loader, listed in its error)."""
    return dataclasses.field(default=default, metadata={"doc": doc, "choices": choices})


def field_docs(cls, prefix: str = "") -> dict[str, str]:
    """Field name (as 'prefix.name' when `prefix` is given) -> documentation, in declaration order, for
    every field declared with `documented` (others, such as nested sections, are skipped)."""
    return {(f"{prefix}.{f.name}" if prefix else f.name): f.metadata["doc"] for f in dataclasses.fields(cls)
            if "doc" in f.metadata}


def fail(key: str, value: Any, why: str, *, error: type[Exception] = ValueError, prefix: str = "") -> NoReturn:
    """Raises `error` with the one message format of the package: '{prefix}{key}={value!r}: {why}'."""
    raise error(f"{prefix}{key}={value!r}: {why}")
