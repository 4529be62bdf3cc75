"""Trial counts checked against this machine's memory before anything compiles (docrl_jax.evaluate.trial_memory):
the estimate counts the records the rollout really returns, and a count that cannot fit is one line naming
how many would, exit status 2, nothing written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from docrl_jax.arguments import UsageError
from docrl_jax.evaluate import trial_memory
from docrl_jax.evaluate.trial_memory import Need

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("render", [False, True])
def test_record_bytes_are_the_rollout_s_records(render):
    """The rollout's outputs per trial, from their shapes (traced, not compiled), are record_bytes."""
    import jax

    from docrl_jax.baselines import bba
    from docrl_jax.evaluate import rollout
    steps, n = 7, 3
    env = rollout.make_eval_env(2, steps)
    policy = bba.make_bba(env.params)
    fn = rollout.make_rollout(env, policy, steps, render)
    goal = jax.ShapeDtypeStruct((n, 3) if render else (3,), np.float32)
    out = jax.eval_shape(fn, policy.params, jax.ShapeDtypeStruct((n, 2), np.uint32),
                         jax.ShapeDtypeStruct((n, 3), np.float32), jax.ShapeDtypeStruct((n,), np.float32), goal)
    per_trial = {k: v.size * v.dtype.itemsize // n for k, v in out.items() if v.ndim >= 2}   # per-step records
    ranges = (out["ranges"].shape[-1] + out["vertical_ranges"].shape[-1]) if render else None
    assert sum(per_trial.values()) == trial_memory.record_bytes(steps, render_ranges=ranges)
    if render:   # the commands count the observation's size for the ranges: never fewer
        assert env.params.observation_size >= ranges


GB = 10**9


def test_a_count_that_cannot_fit_names_how_many_would():
    need = Need(500, held=2, rows=2)
    per_trial = need.device() + need.host()
    assert 80_000 < per_trial < 100_000   # measured on CPU: 88 KB a trial (evaluate, one scenario, both ways)
    cpu = (24 * GB, None, "available host RAM")
    trial_memory.check("--trials", 200_000, need, free=cpu)
    with pytest.raises(UsageError, match=r"^--trials 1000000: about \d\d GB at 500 steps \(trial records, the "
                                         r"rollout's working memory, trials.csv rows\); this machine has 24 GB free "
                                         r"\(available host RAM\): at most ~2[4-9]0000 trials$"):
        trial_memory.check("--trials", 1_000_000, need, free=cpu)
    # on a GPU the device holds one rollout's trials, the host the records and rows
    gpu = (24 * GB, 1 * GB, "NVIDIA H100 80GB HBM3 memory")
    with pytest.raises(UsageError, match=r"this machine has 1.0 GB free \(NVIDIA H100 80GB HBM3 memory\): at most "
                                         r"~\d\d000 trials$"):
        trial_memory.check("--trials", 100_000, need, free=gpu)
    with pytest.raises(UsageError, match=r"free \(available host RAM\)"):
        trial_memory.check("--trials", 500_000, need, free=(24 * GB, 80 * GB, "H100"))
    trial_memory.check("--trials", 10**9, need, free=(None, None, "host RAM"))   # unreadable: not refused


def test_free_memory_reads_this_machine():
    host, device, what = trial_memory.free_memory()
    assert host is None or host > 0
    assert (device is None) == (what == "available host RAM")


@pytest.mark.parametrize("argv, flag", [
    (["evaluate", "--policy", "td3_lstm", "--scenarios", "2", "--trials", "100000000"], "--trials 100000000"),
    (["robustness", "--policy", "bba", "--tests", "random_trips", "--trials", "100000000", "--out", "r"],
     "--trials 100000000"),
    (["render", "--trials", "1000000"], "--trials 1000000"),
])
def test_too_many_trials_exit_in_one_line_before_compiling(argv, flag, tmp_path):
    """What hung for minutes, or was killed by the kernel, is one line."""
    proc = subprocess.run([sys.executable, "-m", "docrl_jax", *argv], capture_output=True, text=True, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=300)
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(err) == 1, proc.stderr
    assert f"error: {flag}: about " in err[0] and " free (" in err[0] and "at most ~" in err[0], err[0]
    assert not list(tmp_path.iterdir())
