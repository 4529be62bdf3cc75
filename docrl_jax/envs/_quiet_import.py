"""`mjx`: `mujoco.mjx`, imported without its notice about the optional Warp backend (the env's
modules import MJX from here).

mujoco-mjx tries `import warp` (NVIDIA Warp, an optional backend this package does not use) when
`mujoco.mjx` is imported and `print`s "Failed to import warp: No module named 'warp'" and the same
for mujoco_warp when it is absent: two lines of noise at the top of every command. Exactly those
lines are dropped; anything else the import prints (a broken Warp install, say) is passed through.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import re
import sys

# What mujoco/mjx/warp/__init__.py prints when Warp is simply not installed.
WARP_MISSING = re.compile(r"Failed to import (warp|mujoco_warp): No module named '?warp'?\s*")


def import_quietly(module: str, drop: re.Pattern = WARP_MISSING):
    """Imports `module` with stdout captured, then writes back every captured line that `drop` does
    not fully match (also when the import raises). Returns the module."""
    if module in sys.modules:
        return sys.modules[module]
    captured = io.StringIO()
    try:
        with contextlib.redirect_stdout(captured):
            return importlib.import_module(module)
    finally:
        for line in captured.getvalue().splitlines(keepends=True):
            if not drop.fullmatch(line):
                sys.stdout.write(line)


mjx = import_quietly("mujoco.mjx")
