"""One config value against the type its key declares (docrl_jax/config/sections.py): the checks and
conversions every key gets, whatever its section, and the one error they raise."""

from __future__ import annotations

import functools
import math
from typing import Any

from docrl_jax import schema
from docrl_jax.errors import ConfigError

# bad(key, value, why) raises ConfigError("key=value: why"), the package's one error format.
bad = functools.partial(schema.fail, error=ConfigError)


def coerce(key: str, value: Any, typ: Any, choices: tuple | None) -> Any:
    """Checks one value against its declared type; ints are accepted for floats, and strings such as
    '3e-4' (which YAML 1.1 reads as text) are accepted for floats when they parse as numbers."""
    if typ is bool:
        if not isinstance(value, bool):
            also = " or 'auto'" if key == "train.eval_alongside" else ""
            raise ConfigError(f"{key}={value!r}: must be a bool (true or false){also}")
    elif typ is int:
        if key == "train.devices":
            if value == "all":
                value = 0
            elif isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"{key}={value!r}: must be 'all' (or 0: every device) or a device count >= 1")
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
                value = int(value)  # 1e6 written as 1.0e+6
            else:
                raise ConfigError(f"{key}={value!r}: must be an integer")
    elif typ is float:
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise ConfigError(f"{key}={value!r}: must be a number") from None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key}={value!r}: must be a number")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"{key}={value!r}: must be finite")
    elif typ is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}={value!r}: must be a string")
    elif typ is tuple:
        if isinstance(value, int) and not isinstance(value, bool):
            value = [value]
        if not isinstance(value, (list, tuple)) or not value or not all(
                isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value):
            raise ConfigError(f"{key}={value!r}: must be a non-empty list of positive integers, e.g. [256, 256]")
        value = tuple(value)
    if choices is not None and value not in choices:
        raise ConfigError(f"{key}={value!r}: valid choices are {list(choices)}")
    return value


def freeze(v: Any) -> Any:
    """Lists (YAML's, at any depth) as tuples, so a Config holding them stays hashable."""
    return tuple(freeze(x) for x in v) if isinstance(v, (list, tuple)) else v
