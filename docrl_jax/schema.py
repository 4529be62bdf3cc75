"""Documented dataclass fields and their errors, shared by the trainer's config (docrl_jax.config)
and the environment's parameters (docrl_jax.envs.params).

    x: float = documented(0.5, "What x means, its unit and its source.", choices=None)
    field_docs(EnvParams)              -> {"x": "What x means, ..."}
    field_docs(TrainConfig, "train")   -> {"train.x": ...}
    fail("train.x", -1, "must be >= 0", error=ConfigError)   # raises "train.x=-1: must be >= 0"
    did_you_mean("lr_actr", ["actor_lr", "gamma"])  -> "; did you mean 'actor_lr'?"
    first_and_count(["a", "b", "c"])                -> "'a' (and 2 more: 'b', 'c')"
    declared_in(TrainConfig)                        -> "docrl_jax/config/sections.py"

Every field carries its documentation where it is declared (CleanRL style), so error messages, the
README and `--help` texts read one source, and every error names the key, the bad value and why; an
unknown name gets the valid names nearest it and where all of them are declared.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Iterable, NoReturn


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


def did_you_mean(name: str, valid: Iterable[str], *, key: Callable[[str], str] = str,
                 shown: Callable[[str], str] = str) -> str:
    """"; did you mean 'a' or 'b'?" naming the valid names nearest `name` (at most three, best first), or
    "" when none is near. Names are compared as `key(valid_name)` and shown as `shown(valid_name)`.
    Nearness is difflib's similarity of the names, or of their underscore-separated words in sorted
    order, whichever is higher: a typo ('lidar_fov' -> 'lidar_fov_deg') and words in another order
    ('lr_actr' -> 'actor_lr') both count. Only names about as near as the nearest are named, so a
    clear match ('td3_lsmt' -> 'td3_lstm') is not drowned by the names that merely share a part."""
    import difflib  # only an error needs it; the import would cost every launch

    def words(text: str) -> str:
        return "_".join(sorted(text.split("_")))

    def nearness(candidate: str) -> float:
        return max(difflib.SequenceMatcher(None, name, candidate).ratio(),
                   difflib.SequenceMatcher(None, words(name), words(candidate)).ratio())

    scored = sorted(((nearness(key(v)), v) for v in sorted(valid)), key=lambda s: -s[0])
    best = scored[0][0] if scored else 0.0
    # 0.6: difflib.get_close_matches' default cutoff
    near = [repr(shown(v)) for score, v in scored[:3] if score >= max(0.6, best - 0.1)]
    if not near:
        return ""
    *rest, last = near
    return f"; did you mean {', '.join(rest) + ' or ' if rest else ''}{last}?"


def first_and_count(names: list[str]) -> str:
    """"'a' (and 2 more: 'b', 'c')": an error about unknown names names the first (its suggestions are
    for it) and still lists the others, so a file with several typos is not fixed one run at a time."""
    more = f" (and {len(names) - 1} more: {', '.join(map(repr, names[1:]))})" if names[1:] else ""
    return repr(names[0]) + more


def declared_in(cls) -> str:
    """The source file, relative to the repository (and to site-packages), that declares `cls`: where a
    user reads every field it has."""
    return cls.__module__.replace(".", "/") + ".py"
