"""Shared by the trainer tests: one easy configuration and runs of it, built once per process.

Every trainer test uses the same configuration (`easy_config`, varied only in fields that do not
change the compiled programs: run length, seeds, when to evaluate/checkpoint), so the MJX-heavy
programs compile once (about a minute on 2 CPU cores) and each run then costs seconds.
The task is easy on purpose: empty tank, goals 1-2 m away in air, dense progress shaping, no wind,
100-step episodes.
"""

from __future__ import annotations

import copy
import functools
import pickle
import tempfile
import threading
from concurrent import futures
from pathlib import Path

import jax
import pytest

from docrl_jax.config import config_from_dict
from docrl_jax.train import jax_internals

EASY = {
    "name": "easy",
    "env": {"scenario": 1, "num_envs": 16, "wind": False, "max_goal_distance": 2.0, "progress_reward_scale": 1.0,
            "max_episode_steps": 100, "goal_water_fraction": 0.0, "start_water_fraction": 0.0},
    "agent": {"algo": "td3", "actor": "lstm", "actor_hidden": [32], "critic_hidden": [64, 64], "tau": 0.01},
    "replay": {"buffer_size": 32000, "batch_size": 64, "seq_len": 4, "burn_in": 2},
    # Evaluations and checkpoints by env steps alone: the wall-clock cadences (10 minutes by default) would
    # add rows and checkpoints to a run that a busy machine slows past them.
    "train": {"total_env_steps": 16000, "start_steps": 2000, "updates_per_step": 2, "log_every": 4000,
              "eval_every": 8000, "eval_episodes": 64, "checkpoint_every": 8000,
              "eval_every_minutes": 1e9, "checkpoint_every_minutes": 1e9},
}


def easy_raw(**overrides) -> dict:
    """The raw (unloaded) EASY with overrides given as section__key=value (e.g. train__seed=1), for tests
    that add to it before loading. A deep copy: callers may change it without touching EASY."""
    raw = copy.deepcopy(EASY)
    for key, value in overrides.items():
        sec, name = key.split("__")
        raw[sec][name] = value
    return raw


def easy_config(**overrides):
    """easy_raw(**overrides), loaded."""
    return config_from_dict(easy_raw(**overrides))


_TMP = Path(tempfile.mkdtemp(prefix="docrl_trainer_tests_"))


@functools.lru_cache(maxsize=None)
def finished_run(**overrides) -> Path:
    """Run directory of an uninterrupted CLI run of easy_config(**overrides)."""
    from docrl_jax.train.run import run
    name = "run_" + "_".join(f"{k}-{v}" for k, v in sorted(overrides.items())) if overrides else "run_default"
    run_dir = _TMP / name
    status = run(easy_config(**overrides), run_dir, show_progress=False)
    assert status == 0, status
    return run_dir


def tmp_dir(name: str) -> Path:
    path = _TMP / name
    path.mkdir(parents=True, exist_ok=True)
    return path


# How long a test waits for what its own steps bring about (a build it releases, a line the command prints
# after a Ctrl-C, the command quitting) before it fails as a time-out. Every such wait ends by that event;
# only a program that hangs, or is broken so that the event never comes, waits this long, on any machine.
WAIT_S = 600


def wait_for(event: threading.Event, what: str) -> None:
    """Returns once `event` is set; fails the test as a time-out after WAIT_S."""
    if not event.wait(WAIT_S):
        pytest.fail(f"timed out after {WAIT_S} s waiting for {what}")


def result_of(future: futures.Future, what: str):
    """`future`'s result (or its exception, raised) once it is done; fails the test as a time-out after WAIT_S."""
    if not futures.wait([future], WAIT_S).done:
        pytest.fail(f"timed out after {WAIT_S} s waiting for {what}")
    return future.result()


def rewrite_entry(path: Path, change) -> None:
    """Writes the entry at `path` again with its constants replaced by `change(constants)`."""
    fmt, payload, trees = pickle.loads(path.read_bytes())
    *parts, consts = jax_internals.unpack(payload, jax.devices()[:1])
    path.write_bytes(pickle.dumps((fmt, jax_internals.pack((*parts, change(consts))), trees)))
