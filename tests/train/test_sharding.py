"""Seeds over devices and processes (docrl_jax.sharding): the device plan and its errors, and runs
of 4 seeds on 4 CPU devices, on 1, resumed across device counts, and over 2 processes x 2 devices.

The runs need XLA's forced host devices, set before JAX starts, so they run in subprocesses
(tests/train/_sharding_worker.py, all three started at once) on a tiny config; compiling dominates.

Tolerance. A seed's computation does not depend on where it runs, but XLA batches the vmapped
program of 4 seeds on one device differently from the unbatched program each device runs with one
seed, so the two agree to float rounding only: after the 40 updates of TINY the largest relative
difference measured was ~1e-6 (metrics) and ~6e-8 absolute (weights); they are compared at
rtol 1e-4 / atol 1e-5, episode and update counts exactly. Runs of the same per-device program (4
devices in one process, or 2 x 2 in two) must agree exactly.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from docrl_jax import sharding
from docrl_jax.config import ConfigError, load_config
from docrl_jax.memory import check_memory
from docrl_jax.sharding import plan_devices
from docrl_jax.train import load_policy

WORKER = Path(__file__).resolve().parent / "_sharding_worker.py"
# "[Gloo] Rank 0 is connected to 3 peer ranks. Expected number of connected peer ranks is : 3", less its numbers.
# Gloo's connection line as it writes it, in pieces that other threads' pieces can fall between
# (seen: a "3" between " peer ranks. " and "Expected ...").
GLOO_LINE = ("[Gloo] Rank ", " is connected to ", "Expected number of connected peer ranks is : ", " peer ranks. ")
EXACT = {"env_steps", "seed", "train_episodes", "grad_updates"}


def test_plan_devices_default_uses_the_largest_even_split():
    assert plan_devices(8, 0, 8) == (8, None)
    assert plan_devices(16, 0, 8) == (8, None)
    assert plan_devices(2, 0, 1) == (1, None)
    d, note = plan_devices(6, 0, 4)
    assert d == 3 and "using 3 devices (2 seeds each), 1 idle" in note and "num_seeds 4, 8, 12" in note
    d, note = plan_devices(1, 0, 8)
    assert d == 1 and "using 1 device (1 seed), 7 idle" in note
    assert plan_devices(4, 0, 4, processes=2) == (4, None)
    d, note = plan_devices(2, 0, 4, processes=2)  # one device of each process
    assert d == 2 and "4 devices over 2 processes: using 2 devices (1 seed each), 2 idle" in note
    assert plan_devices(8, 2, 4, processes=2) == (2, None)
    assert plan_devices(6, 2, 4) == (2, None)


@pytest.mark.parametrize("args, message", [
    ((6, 4, 4), r"train.devices=4 does not divide train.num_seeds=6 .* valid train.devices for 6 seeds on 4 "
                r"devices: 'all' or \[1, 2, 3\], or set train.num_seeds to a multiple of 4"),
    ((4, 8, 4), r"train.devices=8: only 4 devices visible; valid: 'all' or 1..4"),
    ((4, 2, 1), r"train.devices=2: only 1 device visible; valid: 'all' or 1..1"),
    ((3, 0, 4, 2), r"train.num_seeds=3: the 2 processes must hold the same number of seeds; use a multiple of 2"),
    ((4, 1, 4, 2), r"train.devices=1: each of the 2 processes must use the same number of devices; valid: "
                   r"'all' or \[2, 4\]"),
])
def test_plan_devices_refuses_uneven_or_unavailable_counts(args, message):
    with pytest.raises(ConfigError, match=message):
        plan_devices(*args)


def test_seed_keys_are_jax_s_keys_computed_on_the_host():
    # JAX's threefry seeding puts a 32-bit seed in the key's second word; the keys land where the seeds go.
    placement = sharding.SeedPlacement((jax.devices()[0],))
    keys = placement.seed_keys([0, 5, 2**31 - 1])
    assert keys.dtype == np.uint32 and np.array_equal(np.asarray(keys), [[0, 0], [0, 5], [0, 2**31 - 1]])
    with sharding.on_host():
        assert jax.numpy.zeros(2).devices() == {jax.local_devices(backend="cpu")[0]}


def test_train_devices_config_values():
    assert load_config("td3_lstm", ["train.devices=all"]).train.devices == 0
    assert load_config("td3_lstm").train.devices == 0
    for bad in ("-1", "some", "1.5", "true"):
        with pytest.raises(ConfigError, match=r"train.devices=.*: must be 'all' \(or 0: every device\) or a device "
                                              r"count >= 1"):
            load_config("td3_lstm", [f"train.devices={bad}"])
    # Resolved against the visible devices before anything compiles (here through the memory check);
    # loading alone needs no device, so a run dir from a bigger machine still loads.
    n = len(jax.devices())
    bigger = load_config("td3_lstm", [f"train.devices={n + 1}", f"train.num_seeds={n + 1}"])
    with pytest.raises(ConfigError, match=rf"train.devices={n + 1}: only {n} device"):
        check_memory(bigger)


def test_distributed_is_requested_by_the_coordinator_and_process_count():
    assert sharding.distributed_from_env({"JAX_COORDINATOR_ADDRESS": "h:1", "JAX_NUM_PROCESSES": "2"})
    assert not sharding.distributed_from_env({"JAX_COORDINATOR_ADDRESS": "h:1"})
    assert not sharding.distributed_from_env({})


def test_distributed_without_a_coordinator_is_a_clear_error(monkeypatch, capsys):
    from docrl_jax.train import cli
    for name in ("JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID", "SLURM_JOB_ID"):
        monkeypatch.delenv(name, raising=False)
    assert cli.main(["--distributed", "--config", "td3_lstm", "--run-dir", "x"]) == cli.EXIT_CONFIG
    assert "set JAX_COORDINATOR_ADDRESS=host:port of process 0" in " ".join(capsys.readouterr().out.split())


def test_the_command_line_ends_a_distributed_session_after_its_run(monkeypatch, tmp_path):
    """After the run, every process together (`sharding.shutdown_distributed`), not in JAX's exit
    handler after the devices are gone; a single-process launch has no session to end."""
    from docrl_jax.train import cli
    from docrl_jax.train import run as train_run
    calls = []
    monkeypatch.setattr(sharding, "initialize_distributed", lambda: calls.append("initialize"))
    monkeypatch.setattr(train_run, "run", lambda *a, **k: calls.append("run") or cli.EXIT_INTERRUPTED)
    monkeypatch.setattr(jax.distributed, "is_initialized", lambda: "initialize" in calls)
    monkeypatch.setattr(jax.distributed, "shutdown", lambda: calls.append("shutdown"))
    monkeypatch.setattr(sharding, "barrier", lambda: calls.append("barrier"))
    args = ["--config", "td3_lstm", "--run-dir", str(tmp_path / "run"), "--compile-cache", "off"]
    assert cli.main(["--distributed", *args]) == cli.EXIT_INTERRUPTED
    assert calls == ["initialize", "run", "barrier", "shutdown"]
    calls.clear()
    assert cli.main(args) == cli.EXIT_INTERRUPTED and calls == ["run"]


def test_two_processes_end_their_session_together_and_quietly(tmp_path):
    """Two CPU processes (2 devices each) gather over both, then end the session as the command line
    does: both exit 0 with the session closed and nothing on their output but Gloo's connection line
    and their own. (The GRPC 'WatchTasksAsync ... CANCELLED' lines came from two GPU processes; two
    CPU processes left to JAX's exit handler print none either, so this cannot show their absence.)"""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    env = {"JAX_COORDINATOR_ADDRESS": f"127.0.0.1:{port}", "JAX_COORDINATOR_BIND_ADDRESS": f"127.0.0.1:{port}",
           "JAX_NUM_PROCESSES": "2"}
    procs = [_run(["shutdown", str(tmp_path)], {**env, "JAX_PROCESS_ID": str(i)}) for i in range(2)]
    try:
        logs = [p.communicate(timeout=120)[0] for p in procs]
    finally:
        for p in procs:
            p.kill()
    for i, (p, log) in enumerate(zip(procs, logs)):
        assert p.returncode == 0, log[-3000:]
        assert f"process {i}: gathered [0, 1, 2, 3], session open after the end: False" in log, log
        # Gloo's connection lines, each process's two devices' at once, can interleave mid-line (seen:
        # a lone "3"): what is left without them and the process's own line must be their numbers only.
        rest = "\n".join(line for line in log.splitlines() if not line.startswith(f"process {i}:"))
        for piece in GLOO_LINE:
            rest = rest.replace(piece, " ")
        assert re.fullmatch(r"[\d\s]*", rest), rest


def _rows(run_dir: Path) -> list[dict]:
    with open(run_dir / "metrics.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _assert_close_rows(a: list[dict], b: list[dict]) -> None:
    assert [(r["env_steps"], r["seed"]) for r in a] == [(r["env_steps"], r["seed"]) for r in b]
    for ra, rb in zip(a, b):
        for k, va in ra.items():
            if k == "wall_time_s":
                continue
            if k in EXACT:
                assert va == rb[k], (k, ra, rb)
            else:
                x, y = float(va), float(rb[k])
                assert (math.isnan(x) and math.isnan(y)) or math.isclose(x, y, rel_tol=1e-4, abs_tol=1e-5), (k, x, y)


def _policies(run_dir: Path) -> list:
    """Actor params of each seed (the trained actor, not a best pick), restored onto this process's single device."""
    return [load_policy(run_dir, i, which="final").params for i in range(4)]


def _run(args: list[str], env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(WORKER), *args], env={**os.environ, **(env or {})},
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


class _Runs:
    """The worker processes, started together (the one-process run and the two processes compile
    in parallel, which about halves the wall-clock on 2 cores)."""

    def __init__(self, root: Path):
        self.single_dir, self.multi_dir = root / "single", root / "multi"
        self.single_dir.mkdir()
        self.multi_dir.mkdir()
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        env = {"JAX_COORDINATOR_ADDRESS": f"127.0.0.1:{port}", "JAX_COORDINATOR_BIND_ADDRESS": f"127.0.0.1:{port}",
               "JAX_NUM_PROCESSES": "2"}
        self.single = _run(["single", str(self.single_dir)])
        self.multi = [_run(["multi", str(self.multi_dir)], {**env, "JAX_PROCESS_ID": str(i)}) for i in range(2)]
        self.logs: dict = {}

    def wait(self, proc: subprocess.Popen) -> str:
        if proc not in self.logs:
            try:
                self.logs[proc] = proc.communicate(timeout=600)[0]
            except subprocess.TimeoutExpired:
                self.kill()
                raise
        return self.logs[proc]

    def kill(self):
        for p in (self.single, *self.multi):
            if p.poll() is None:
                p.kill()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    r = _Runs(tmp_path_factory.mktemp("sharding"))
    yield r
    r.kill()


@pytest.fixture(scope="module")
def single(runs) -> Path:
    log = runs.wait(runs.single)
    assert runs.single.returncode == 0, log[-5000:]
    return runs.single_dir


def test_four_devices_match_one_device_and_resume_across_device_counts(single):
    summary = json.loads((single / "summary.json").read_text())
    assert summary["state_devices"] == [4] and summary["shard_seeds"] == [1]  # really one seed per device
    # Building a multi-device program switched JAX from Shardy to GSPMD (sharding.use_gspmd_partitioner).
    assert summary["shardy_before"] is True and summary["shardy_after_sharded_programs"] is False
    assert summary["six_seeds_default"][0] == 3 and "using 3 devices" in summary["six_seeds_default"][1]
    assert "valid train.devices for 4 seeds on 4 devices: 'all' or [1, 2, 4]" in summary["three_devices_error"]
    assert summary["eight_devices_status"] == 2 and not (single / "eight").exists()

    one, four = _rows(single / "one"), _rows(single / "four")
    assert [int(r["env_steps"]) for r in one] == [0] * 4 + [128] * 4 + [192] * 4
    assert int(one[-1]["grad_updates"]) == 40
    _assert_close_rows(four, one)
    _assert_close_rows(_rows(single / "four_then_one"), one)  # 4-device checkpoint resumed on 1 device
    _assert_close_rows(_rows(single / "one_then_four"), one)  # and the other way
    assert sorted(int(p.name) for p in (single / "four" / "checkpoints").iterdir()) == [64, 128, 192]
    for a, b in zip(_policies(single / "four"), _policies(single / "one")):
        jax.tree.map(lambda x, y: np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-4, atol=1e-5),
                     a, b)


def test_two_processes_match_one_process_and_only_process_0_writes(runs, single):
    logs = [runs.wait(p) for p in runs.multi]
    for proc, log in zip(runs.multi, logs):
        assert proc.returncode == 0, log[-5000:]
    assert "done:" in logs[0] and "done:" not in logs[1]  # process 1 prints nothing of the run

    run_dir = runs.multi_dir / "multi"
    assert [p.name for p in runs.multi_dir.iterdir()] == ["multi"]
    # Process 0's event files only: one per session, as in the one-process run.
    assert len(list((run_dir / "tb").iterdir())) == len(list((single / "four" / "tb").iterdir())) == 2
    strip = lambda rows: [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows]  # noqa: E731
    assert strip(_rows(run_dir)) == strip(_rows(single / "four"))  # same per-device program: exact
    for a, b in zip(_policies(run_dir), _policies(single / "four")):
        jax.tree.map(lambda x, y: np.testing.assert_array_equal(np.asarray(x), np.asarray(y)), a, b)
