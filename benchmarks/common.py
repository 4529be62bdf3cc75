"""Shared by the benchmark scripts: machine and version facts recorded with every result."""

from __future__ import annotations

import datetime as dt
import os
import platform
import subprocess
import sys
from importlib.metadata import version


def gpu_name() -> str:
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=20)
        return out.stdout.strip().splitlines()[0] if out.returncode == 0 and out.stdout.strip() else "none"
    except (OSError, subprocess.TimeoutExpired):
        return "none"


def run_meta() -> dict:
    import jax
    pkgs = ("jax", "jaxlib", "mujoco", "mujoco-mjx", "flax", "optax", "orbax-checkpoint")
    return {"command": " ".join([os.path.basename(sys.executable)] + sys.argv), "gpu": gpu_name(),
            "device": str(jax.devices()[0]), "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            "versions": {"python": platform.python_version(), **{p: version(p) for p in pkgs}}}
