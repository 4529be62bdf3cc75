"""No run is ever lost or silently wrong: evaluation and checkpoint cadences that hold on a slow
device, an honest ETA, Ctrl-C answered at once and never losing the run, a run directory that is
not overwritten, a damaged newest checkpoint skipped on resume, one-line file-system errors, and
output that stays readable in a log file. Every run here reuses the easy config's compiled programs
(tests/train/_trainer_common.py), so each costs seconds."""

from __future__ import annotations

import csv
import errno
import io
import os
import re
import shutil
import signal
import threading
from concurrent.futures import Future
from pathlib import Path
from unittest.mock import patch

import jax
import jax.numpy as jnp
import pytest
from _trainer_common import WAIT_S, easy_config, finished_run, tmp_dir

from docrl_jax import checkpoint
from docrl_jax.errors import RunDirError
from docrl_jax.train import cli, load_policy, loop
from docrl_jax.train import run as train_run


def _rows(run_dir):
    with open(run_dir / "metrics.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _console():
    out = io.StringIO()
    return cli.make_console(file=out), out


def _steps(run_dir):
    return sorted(int(p.name) for p in (run_dir / "checkpoints").iterdir() if p.name.isdigit())


# ------------------------------------------------------------------ cadences and the ETA
def test_minutes_cadence_evaluates_and_checkpoints_when_env_steps_are_slow():
    """The packaged defaults evaluate every 2.5 M and checkpoint every 25 M env steps: hours to days on
    a CPU. The wall-clock cadences make every chunk evaluate and checkpoint here (0.0001 minutes)."""
    d = tmp_dir("minutes")
    config = easy_config(train__eval_every=10**9, train__checkpoint_every=10**9, train__eval_every_minutes=1e-4,
                         train__checkpoint_every_minutes=1e-4, train__total_env_steps=12000)
    assert train_run.run(config, d, show_progress=False, stop_after_chunks=2) == cli.EXIT_INTERRUPTED
    assert [int(r["env_steps"]) for r in _rows(d)] == [0, 4000, 8000]
    assert _steps(d) == [4000, 8000]


def test_cadence_by_env_steps_or_minutes_whichever_first():
    now = [0.0]
    c = loop.Cadence(every_steps=100, every_minutes=1.0, clock=lambda: now[0])
    assert not c.due(0, 50) and c.due(50, 100) and c.due(150, 250)
    now[0] = 59.0
    assert not c.due(100, 150)
    now[0] = 60.0
    assert c.due(100, 150)          # a minute since it was last done, whatever the steps
    c.done()
    assert not c.due(150, 190)
    assert c.remaining(0, 1000) == 10 and c.remaining(950, 1050) == 2   # ... and one at the end


def test_eta_waits_for_learning_chunks_and_counts_evaluations():
    eta = loop.Eta()
    eta.add_chunk(0.01, learning=False)   # before start_steps: 500x faster than learning chunks
    assert eta.seconds(100, 5) is None and eta.text(100, 5) == "ETA once learning starts"
    eta.add_chunk(2.0, learning=True)
    eta.add_chunk(2.0, learning=True)
    eta.add_eval(5.0)
    assert eta.seconds(10, 2) == pytest.approx(10 * 2.0 + 2 * 5.0)
    assert eta.text(10, 2) == "ETA 30 s"


def test_progress_line_says_no_eta_before_learning_then_one():
    """The easy config learns from env step 2,000: its first chunk (4,000 steps) learns on only some
    iterations, which gives no ETA (Eta's own test covers a chunk that learns on none); the second on all."""
    console, out = _console()
    assert train_run.run(easy_config(), tmp_dir("eta"), console=console, show_progress=False, stop_after_chunks=2) == \
        cli.EXIT_INTERRUPTED
    lines = [line for line in out.getvalue().splitlines() if " steps/s " in line]
    assert len(lines) == 2
    assert "ETA once learning starts" in lines[0]
    assert "ETA " in lines[1] and "once learning" not in lines[1]


# ------------------------------------------------------------------ Ctrl-C
class _Computing:
    """A chunk's result still being computed until the test calls `finish`: `jax.block_until_ready` (what
    `loop.wait`'s helper thread runs) blocks on it until then, or WAIT_S at most (then `timed_out`)."""

    def __init__(self):
        self.finished, self.timed_out = threading.Event(), False

    def finish(self):
        self.finished.set()

    def is_ready(self) -> bool:
        return self.finished.is_set()

    def block_until_ready(self):
        self.timed_out = not self.finished.wait(WAIT_S) or self.timed_out
        return self


def test_ctrl_c_is_answered_while_the_device_still_computes():
    """The message comes while the chunk runs, not when it ends: `wait` returns to Python between polls.
    The chunk's result (`_Computing`) is ready only once the message is out."""
    said, computing = [], _Computing()

    class Recorder:
        def print(self, text):
            said.append((text, computing.is_ready()))
            computing.finish()

    with loop.Interrupt(Recorder()) as interrupt:
        os.kill(os.getpid(), signal.SIGINT)
        result = loop.wait({"metrics": jnp.arange(3.0), "computing": computing}, interrupt)
    assert not computing.timed_out, f"timed out after {WAIT_S} s waiting for the Ctrl-C's message during the chunk"
    assert interrupt.requested and len(said) == 1 and "after the running chunk" in said[0][0]
    assert said[0][1] is False   # printed while the device was still computing
    assert result["computing"] is computing and list(result["metrics"]) == [0.0, 1.0, 2.0]


def test_a_ctrl_c_while_the_chunk_still_compiles_is_answered_at_once():
    """The message comes while the chunk's first build compiles; the build is done only after it, from
    another thread, and `wait_for_build` returns once it is."""
    said, first, answered = [], Future(), threading.Event()

    class Recorder:
        def print(self, text):
            said.append((text, first.done()))
            answered.set()

    class Building:   # a cold start's chunk whose quick build compiles (docrl_jax.train.programs.Tiered)
        pass

    chunk = Building()
    chunk.first = first

    def compile_once_answered():   # or after WAIT_S unanswered, so that the test ends and says why
        answered.wait(WAIT_S)
        first.set_result(None)

    compiler = threading.Thread(target=compile_once_answered, daemon=True)
    compiler.start()
    with loop.Interrupt(Recorder()) as interrupt:
        os.kill(os.getpid(), signal.SIGINT)
        loop.wait_for_build(chunk, interrupt)
    assert answered.is_set(), f"timed out after {WAIT_S} s waiting for the Ctrl-C's message while the chunk compiled"
    assert first.done() and interrupt.requested and len(said) == 1 and said[0][1] is False


def _interrupting(monkeypatch, times: int, during_save: int = 0, chunk: int = 1):
    """Sends `times` SIGINTs while chunk number `chunk` runs and `during_save` more inside the first save."""
    real_wait, real_save = loop.wait, checkpoint.save
    sent = {"wait": 0, "save": False}

    def wait(tree, interrupt=None, poll_s=0.1):
        sent["wait"] += 1
        if sent["wait"] == chunk:
            for _ in range(times):
                os.kill(os.getpid(), signal.SIGINT)
        return real_wait(tree, interrupt, poll_s)

    def save(*args, **kwargs):
        if not sent["save"]:
            sent["save"] = True
            for _ in range(during_save):
                os.kill(os.getpid(), signal.SIGINT)
        return real_save(*args, **kwargs)

    monkeypatch.setattr(loop, "wait", wait)
    monkeypatch.setattr(checkpoint, "save", save)


@pytest.mark.parametrize("presses", [1, 2])
def test_ctrl_c_once_or_twice_saves_after_the_chunk(monkeypatch, presses):
    """Once during chunk 1; twice during chunk 3, when the second press gives an estimate from the time
    chunk 2 took (chunk 1, 4,000 env steps from start_steps 2,000, learned on half its
    iterations, chunk 2 on all; the command's test below presses during chunk 2: no estimate yet)."""
    chunk = 1 if presses == 1 else 3
    d = tmp_dir(f"ctrl_c_{presses}")
    _interrupting(monkeypatch, presses, chunk=chunk)
    console, out = _console()
    assert train_run.run(easy_config(), d, console=console, show_progress=False) == cli.EXIT_INTERRUPTED
    text = out.getvalue()
    assert "stopping after the running chunk" in text
    assert ("still stopping" in text) == (presses == 2)
    if presses == 2:   # an estimate from chunk 2's time: "about N s more", or "any moment" where chunks take
        # under a second (4,000 env steps on a fast CPU; the arithmetic has its own test above, on a set clock)
        assert re.search(r"still stopping after the running chunk \((about [^)]+ more|any moment: it has run "
                         r"[^,]+, chunks take about [^)]+)\)", text), text
    assert _steps(d)[-1] == 4000 * chunk   # (checkpoint_every 8,000 adds 8,000 before chunk 3's)
    # Not wrapped at 80 columns in a log file: the resume command is on one line.
    assert f"resume with python -m docrl_jax.train --run-dir {d} --resume" in text
    assert load_policy(d).source.endswith(f"checkpoint {4000 * chunk}")


def test_a_ctrl_c_says_how_long_the_running_chunk_has_left():
    """From the time a learning chunk takes, less what the running one has run; no estimate while
    the last chunk did not learn on every iteration (such chunks are far faster than the next)."""
    said, now = [], [100.0]

    class Recorder:
        def print(self, text):
            said.append(text)

    eta = loop.Eta()
    eta.add_chunk(0.2, learning=False)       # only stepped the envs
    assert eta.next_chunk() is None
    eta.add_chunk(60.0, learning=True)
    eta.add_chunk(62.0, learning=True)
    assert eta.next_chunk() == pytest.approx(61.0)
    interrupt = loop.Interrupt(Recorder(), clock=lambda: now[0])
    interrupt.chunk_started(eta.next_chunk())
    now[0] += 21.0
    interrupt.count = 2
    interrupt.poll()
    assert all("(about 40 s more)" in line for line in said) and len(said) == 2, said
    now[0] += 45.0                           # longer than chunks take
    assert interrupt.next_stop == "after the running chunk (any moment: it has run 1 min 06 s, chunks take about 1 min 01 s)"
    interrupt.chunk_started(None)
    now[0] += 3.0
    assert interrupt.next_stop == ("after the running chunk (it has run 3 s; no estimate before a learning chunk "
                                   "is timed)")


def test_a_third_ctrl_c_during_a_save_waits_for_it(monkeypatch):
    """Two presses during the chunk, a third while the checkpoint is written: the write completes,
    then the run quits, keeping it."""
    d = tmp_dir("ctrl_c_3")
    _interrupting(monkeypatch, 2, during_save=1)
    console, out = _console()
    assert train_run.run(easy_config(), d, console=console, show_progress=False) == cli.EXIT_INTERRUPTED
    assert "quit without saving; newest checkpoint: env step 4,000" in out.getvalue()
    assert _steps(d) == [4000] and not list((d / "checkpoints").glob("*tmp*"))
    load_policy(d)


# ------------------------------------------------------------------ what a launch prints
def test_a_launch_prints_a_short_summary_and_the_run_directory_holds_the_full_config(tmp_path, monkeypatch):
    """A few lines (the run, where its directory and full config are, the device, the choices made
    for it, the cache) instead of every key; config.yaml holds every key, written before compiling
    (stopped there: a Ctrl-C during the compile)."""
    import yaml

    from docrl_jax.config import config_from_dict, load_config, to_yaml

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(train_run, "compile_programs", interrupted)
    console, out = _console()
    d = tmp_path / "run"
    args = ["--config", "td3_lstm", "--set", "train.num_seeds=2", "--set", "train.seed=3", "--run-dir", str(d),
            "--compile-cache", "off", "--no-progress"]
    with patch.object(cli, "make_console", lambda **kw: console):
        assert cli.main(args) == cli.EXIT_INTERRUPTED
    launch = out.getvalue().split("compiling (or loading)")[0].splitlines()
    assert 3 <= len(launch) <= 8, launch
    text = "\n".join(launch)
    config = load_config("td3_lstm", {"train.num_seeds": 2, "train.seed": 3})
    assert f"td3_lstm: TD3 with an LSTM actor, env scenario {config.env.scenario}, seeds 3-4, " \
           f"{config.train.total_env_steps:,} env steps per seed" in text
    assert f"run directory: {d} (full config: {d / 'config.yaml'})" in text
    assert "actor_lr" not in text and "device:" in text
    written = (d / "config.yaml").read_text()
    assert written == to_yaml(config) and config_from_dict(yaml.safe_load(written)) == config
    assert len(written.splitlines()) > 50   # every key


def test_a_third_ctrl_c_quits_the_command_at_once_with_exit_130_and_the_checkpoints_kept(tmp_path):
    """The command, in a process of its own, loading this process's compiled programs from a program
    store (seconds, no compile), its second chunk held computing (tests/train/_held_chunk_command.py): three
    Ctrl-Cs during it, each sent once the command has answered the one before. The process leaves at once:
    exit 130, no C++ abort (`wait`'s helper thread is inside XLA), the first chunk's checkpoint kept; the
    second press says that the running chunk's length is not known yet (the first chunk learned on only
    some of its iterations)."""
    import queue
    import subprocess
    import sys

    import yaml

    from docrl_jax.config import to_yaml
    from docrl_jax.train import program_store, programs

    config = easy_config(train__total_env_steps=10**6, train__eval_every=10**9, train__checkpoint_every=4000)
    devices = (jax.devices()[0],)
    program_store.source_digest.cache_clear()   # the store's names as the command will compute them
    compiled, _ = programs.compile_programs(config, devices)   # memoised: the suite compiles these anyway
    cache = tmp_path / "cache"
    for what, name in program_store.store_names(config, devices).items():
        assert program_store.save(cache / program_store.FOLDER, name, getattr(compiled, what)), what
    (tmp_path / "easy.yaml").write_text(to_yaml(config))
    d = tmp_path / "run"
    command = [sys.executable, "-u", str(Path(__file__).with_name("_held_chunk_command.py")), "--config",
               str(tmp_path / "easy.yaml"), "--run-dir", str(d), "--compile-cache", str(cache), "--no-progress"]
    with open(tmp_path / "stderr", "w") as err_file:
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=err_file, stdin=subprocess.DEVNULL, text=True)
    lines: queue.Queue = queue.Queue()   # the command's output lines, then None at its end

    def read():
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    out: list[str] = []

    def printed(text: str) -> str:
        """The next line of the command's output that holds `text` (reading the ones before it)."""
        while True:
            try:
                line = lines.get(timeout=WAIT_S)
            except queue.Empty:
                pytest.fail(f"timed out after {WAIT_S} s waiting for the command to print {text!r}: "
                            f"{''.join(out)[-2000:]}")
            if line is None:
                pytest.fail(f"the command ended before printing {text!r}: {''.join(out)[-2000:]}")
            out.append(line)
            if text in line:
                return line

    try:
        printed(" steps/s ")                  # the first chunk's line: the second chunk is running
        proc.send_signal(signal.SIGINT)
        assert printed("stopping after the running chunk").startswith("stopping")
        proc.send_signal(signal.SIGINT)
        second = printed("still stopping after the running chunk")
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"timed out after {WAIT_S} s waiting for the command to quit after the third Ctrl-C")
        reader.join()                          # its output ends with the process
    finally:
        proc.kill()
    while (line := lines.get()) is not None:
        out.append(line)
    out, err = "".join(out), (tmp_path / "stderr").read_text()
    assert "terminate called" not in err and proc.returncode == 130, (proc.returncode, out[-2000:], err[-2000:])
    # The first chunk learned on only some iterations: the second's length is not known yet.
    assert re.search(r"\(it has run [^;]+; no estimate", second), second
    assert _steps(d) == [4000] and "quit without saving; newest checkpoint: env step 4,000" in out, out[-2000:]
    assert load_policy(d).source.endswith("checkpoint 4000")
    assert yaml.safe_load((d / "config.yaml").read_text())["name"] == "easy"


# ------------------------------------------------------------------ run directories
def test_a_directory_holding_a_run_without_checkpoint_is_not_overwritten(tmp_path):
    d = tmp_path / "started"
    d.mkdir()
    (d / "config.yaml").write_text("name: first\n")
    (d / "metrics.csv").write_text("env_steps\n0\n")
    console = cli.make_console(file=io.StringIO(), width=200)
    with patch.object(cli, "make_console", lambda **kw: console):
        assert cli.main(["--config", "sac_lstm", "--run-dir", str(d), "--compile-cache", "off"]) == cli.EXIT_CONFIG
    assert re.search(r"already holds a run.*--resume.*fresh --run-dir", console.file.getvalue())
    assert (d / "config.yaml").read_text() == "name: first\n" and (d / "metrics.csv").read_text() == "env_steps\n0\n"
    # the same from Python: `run` refuses before it writes anything (it once rewrote the metrics)
    console, out = _console()
    assert train_run.run(easy_config(), d, console=console, show_progress=False) == cli.EXIT_CONFIG
    assert re.search(r"already holds a run", out.getvalue())
    assert (d / "config.yaml").read_text() == "name: first\n" and (d / "metrics.csv").read_text() == "env_steps\n0\n"
    args = cli.build_parser().parse_args(["--run-dir", str(d), "--resume"])
    with pytest.raises(RunDirError, match="has no checkpoint to resume from"):
        cli._resolve(args)


def _damaged_copy(name: str, damage) -> tuple:
    """A finished run (checkpoints 8,000 and 16,000) copied, its newest checkpoint damaged, resumed
    with a longer run."""
    src = finished_run()
    d = tmp_dir(name)
    shutil.rmtree(d)
    shutil.copytree(src, d)
    damage(d / "checkpoints" / "16000")
    console, out = _console()
    status = train_run.run(easy_config(), d, resume=True, console=console, show_progress=False)
    return d, status, out.getvalue()


def test_resume_skips_a_corrupt_newest_checkpoint_and_says_why():
    def corrupt(step_dir):
        for f in (step_dir / "state").rglob("*"):
            if f.is_file():
                f.write_bytes(b"garbage")
    d, status, text = _damaged_copy("corrupt_newest", corrupt)
    assert status == cli.EXIT_OK
    assert "skipped checkpoint 16000:" in text and "resumed from env step 8,000" in text
    assert (d / "checkpoints_damaged" / "16000" / "state").is_dir()   # set aside, not deleted
    skipped = [line for line in text.splitlines() if line.startswith("skipped checkpoint")]
    assert len(skipped) == 1 and len(skipped[0]) < 400      # one line, not pages of TensorStore spec
    # The re-run from 8,000 writes the same rows as the uninterrupted run did.
    strip = lambda rows: [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows]  # noqa: E731
    assert strip(_rows(d)) == strip(_rows(finished_run()))
    # The resumed run's progress line knows the last evaluation (it read it back from metrics.csv).
    assert "eval success nan" not in text and "eval success" in text


def test_resume_skips_a_newest_checkpoint_with_empty_metadata():
    def empty_meta(step_dir):
        for f in (step_dir / "meta").rglob("*"):
            if f.is_file():
                f.write_text("")
    _, status, text = _damaged_copy("empty_meta", empty_meta)
    assert status == cli.EXIT_OK and "skipped checkpoint 16000" in text and "resumed from env step 8,000" in text


def test_resume_with_no_intact_checkpoint_is_one_clear_error():
    src = finished_run()
    d = tmp_dir("all_corrupt")
    shutil.rmtree(d)
    shutil.copytree(src, d)
    for f in (d / "checkpoints").rglob("*"):
        if f.is_file() and "state" in f.parts:
            f.write_bytes(b"garbage")
    console, out = _console()
    assert train_run.run(easy_config(), d, resume=True, console=console, show_progress=False) == cli.EXIT_CONFIG
    text = out.getvalue()
    assert "no intact checkpoint" in text and "16000:" in text and "8000:" in text and len(text.splitlines()) <= 6


def test_a_resume_that_would_change_the_recipe_is_refused_before_compiling(monkeypatch, capsys):
    """--resume --set of a key that is not train.total_env_steps, the cadences or the devices (here the
    envs, which the checkpoints' arrays are shaped by, and a learning rate) is one line naming each key
    and what a resume may change, before any compile, with the run's config.yaml kept as it was."""
    src = finished_run()
    d = tmp_dir("resume_changed_recipe")
    shutil.rmtree(d)
    shutil.copytree(src, d)
    kept = (d / "config.yaml").read_text()

    def no_compile(*a, **k):
        raise AssertionError("compiled")
    monkeypatch.setattr(train_run, "compile_programs", no_compile)
    args = ["--run-dir", str(d), "--resume", "--no-progress", "--compile-cache", "off",
            "--set", "env.num_envs=8", "--set", "agent.actor_lr=0.01", "--set", "train.eval_every=4000"]
    assert cli.main(args) == cli.EXIT_CONFIG
    out = " ".join(capsys.readouterr().out.split())
    assert re.search(r"cannot change agent.actor_lr \(0.001 -> 0.01\), env.num_envs \(\d+ -> 8\); it may change "
                     r"train.total_env_steps, train.devices, train.eval_every", out), out
    assert "train.eval_every (" not in out and "Traceback" not in out and "run directory:" not in out
    assert (d / "config.yaml").read_text() == kept and checkpoint.latest_step(d) == 16000


def test_a_device_out_of_memory_is_not_taken_for_a_damaged_checkpoint(monkeypatch):
    """Running out of GPU memory while reading says nothing of the checkpoint: loading a policy does not
    call it corrupt, and resuming does not skip the newest checkpoint for an older one (which would
    throw its progress away) nor set it aside."""
    src = finished_run()
    d = tmp_dir("oom_on_read")
    shutil.rmtree(d)
    shutil.copytree(src, d)

    def restore(*a, **k):
        raise RuntimeError("RESOURCE_EXHAUSTED: CUDA_ERROR_OUT_OF_MEMORY: out of memory")
    monkeypatch.setattr(checkpoint, "restore", restore)
    with pytest.raises(RunDirError, match="out of device memory while reading checkpoint 16000") as e:
        load_policy(d)
    assert "corrupt" not in str(e.value)
    console, out = _console()
    assert train_run.run(easy_config(), d, resume=True, console=console, show_progress=False) == cli.EXIT_CONFIG
    text = out.getvalue()
    assert "out of device memory while reading checkpoint 16000" in text and "skipped" not in text
    assert not (d / "checkpoints_damaged").exists() and (d / "checkpoints" / "16000").is_dir()


# ------------------------------------------------------------------ file-system errors
def test_a_run_directory_that_cannot_be_created_is_one_line(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    console, out = _console()
    assert train_run.run(easy_config(), blocker / "run", console=console, show_progress=False) == cli.EXIT_CONFIG
    lines = [line for line in out.getvalue().splitlines() if line.strip()]
    assert lines[-1].startswith("error:") and str(blocker / "run") in lines[-1] and "Not a directory" in lines[-1]
    assert "Traceback" not in out.getvalue()


def test_a_full_disk_while_checkpointing_is_one_line_and_keeps_older_checkpoints(monkeypatch):
    d = tmp_dir("full_disk")
    config = easy_config(train__checkpoint_every=4000)
    assert train_run.run(config, d, show_progress=False, stop_after_chunks=1) == cli.EXIT_INTERRUPTED
    real = checkpoint.ocp.CheckpointManager.save

    def full(self, step, *args, **kwargs):   # what Orbax leaves when the disk fills mid-write
        (self.directory / f"{step}.orbax-checkpoint-tmp-1234").mkdir(parents=True)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(checkpoint.ocp.CheckpointManager, "save", full)
    console, out = _console()
    assert train_run.run(config, d, resume=True, console=console, show_progress=False) == cli.EXIT_CONFIG
    monkeypatch.setattr(checkpoint.ocp.CheckpointManager, "save", real)
    error = [line for line in out.getvalue().splitlines() if line.startswith("error:")]
    assert len(error) == 1 and "cannot write checkpoint 8000" in error[0] and "No space left on device" in error[0]
    assert "Traceback" not in out.getvalue()
    assert _steps(d) == [4000] and not list((d / "checkpoints").glob("*tmp*"))
    assert load_policy(d).source.endswith("checkpoint 4000")


def test_non_terminal_output_is_not_wrapped():
    console, out = _console()
    long = "python -m docrl_jax.train --run-dir " + "x" * 150 + " --resume"
    console.print(long)
    assert long in out.getvalue().splitlines()
