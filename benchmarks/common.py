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


def write_results(out_dir: str, stem: str, title: str, meta: dict, rows: list[dict],
                  columns: list[tuple[str, str]]) -> str:
    """Writes <stem>.json (meta + rows) and <stem>.md (a table of `columns`: (header, row key)).

    Called after every row, so a sweep that fails part-way keeps what it measured."""
    import json
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, f"{stem}.json"), "w") as f:
        json.dump({**meta, "results": rows}, f, indent=1)
    fmt = lambda v: f"{v:,}" if isinstance(v, int) and not isinstance(v, bool) else str(v)
    lines = [f"# {title} ({meta['gpu']}, {meta['date']})", "", f"Command: `{meta['command']}`  ",
             f"Versions: {meta['versions']}", "", "| " + " | ".join(h for h, _ in columns) + " |",
             "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(fmt(r[k]) for _, k in columns) + " |" for r in rows]
    table = "\n".join(lines) + "\n"
    with open(os.path.join(out_dir, f"{stem}.md"), "w") as f:
        f.write(table)
    return table


def time_chunks(chunk, state, repeats: int, get=lambda tree: tree):
    """One warm-up call of the compiled `chunk` (it fills the buffer, so every later iteration learns),
    then `repeats` timed calls. Returns (state, seconds of each call, the fewest learning iterations
    of any seed in each: `get` brings a call's metrics to the host)."""
    import time

    import jax
    import numpy as np
    state, m = chunk(state)
    jax.block_until_ready(m)
    times, learn = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        state, m = chunk(state)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t0)
        learn.append(int(np.min(get(m["learn_iters"]))))
    return state, times, learn
