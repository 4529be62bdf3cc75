"""`docrl` (docrl_jax.commands, also `python -m docrl_jax`): each subcommand is its module's command
given the rest of the command line; the version; a mistyped subcommand is one line naming the nearest; a
Ctrl-C ends a command that is not training in any phase, in one line with exit status 130."""

from __future__ import annotations

import importlib
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from docrl_jax import __version__, commands
from docrl_jax import console

ROOT = Path(__file__).resolve().parent.parent


def _docrl(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "docrl_jax", *argv], capture_output=True, text=True, cwd=ROOT)


def test_the_console_script_is_the_same_entry_as_python_m():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"docrl": "docrl_jax.commands:entry"}
    assert "entry()" in (ROOT / "docrl_jax" / "__main__.py").read_text()
    for name, command in commands.COMMANDS.items():   # every subcommand's module has the command's main
        assert callable(importlib.import_module(command.module).main), name


def test_version_and_a_mistyped_subcommand():
    out = _docrl("--version")
    assert out.returncode == 0 and out.stdout.split() == ["python", "-m", "docrl_jax", __version__]
    out = _docrl("evalute", "--policy", "bba")
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.splitlines() == [
        "python -m docrl_jax: error: unknown subcommand 'evalute'; did you mean 'evaluate'? "
        f"(valid: {', '.join(commands.COMMANDS)})"]


def test_a_subcommand_gets_the_rest_of_the_command_line(capsys):
    """`docrl evaluate ARGS` is `python -m docrl_jax.evaluate ARGS`: the same checks, the same line."""
    with pytest.raises(SystemExit) as e:
        commands.main(["evaluate", "--policy", "nope"])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1
    assert err[0].startswith("python -m docrl_jax.evaluate: error: --policy 'nope': unknown policy")
    with pytest.raises(SystemExit) as e:
        commands.main([])
    assert e.value.code == 2 and "give a subcommand: train, evaluate" in capsys.readouterr().err


def test_a_mistyped_choice_names_the_nearest(capsys):
    with pytest.raises(SystemExit) as e:
        commands.main(["tanks", "chek"])
    assert e.value.code == 2 and capsys.readouterr().err.splitlines() == [
        "python -m docrl_jax.tanks: error: argument ACTION: invalid choice: 'chek' "
        "(choose from 'list', 'check', 'draw'); did you mean 'check'?"]


def test_tanks_check_prints_one_line_per_file(tmp_path, capsys):
    (tmp_path / "picture.gif").write_bytes(b"GIF89a\x01\x00\x01\x00\x80\xff\x00\x00\x00\x00")
    (tmp_path / "words.yaml").write_text("just some words\n")
    (tmp_path / "broken.json").write_text("{\"floor_top\": \n")
    files = [str(tmp_path / n) for n in ("picture.gif", "words.yaml", "broken.json", "missing.yaml")]
    assert commands.main(["tanks", "check", *files]) == 2
    out = capsys.readouterr()
    assert out.out.splitlines() == [
        f"invalid: {files[0]}: not a text file; a tank file is YAML or JSON text (docs/TANKS.md)",
        f"invalid: {files[1]}: a tank file holds a mapping of keys (name, description, floor_top, air, water, solids), "
        "not str",
        f"invalid: {files[2]}: not valid JSON at line 2: Expecting value",
        f"invalid: {files[3]}: no such tank file"]
    assert out.err.strip() == "4 of 4 files are not valid tanks (docs/TANKS.md)"


def test_tanks_list_names_every_packaged_tank(capsys):
    from docrl_jax.envs import tanks
    assert commands.main(["tanks", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines[:-1]] == tanks.packaged_names()
    assert lines[-1].startswith(f"{len(tanks.packaged_names())} tanks in ")


def _interrupt_after_first_line(argv: list[str]) -> tuple[subprocess.CompletedProcess, str]:
    """Starts `argv`, sends one SIGINT once it has printed its first stdout line, waits for the end (a
    process that ignores the Ctrl-C fails this as a time-out)."""
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    first = proc.stdout.readline()
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()       # the Ctrl-C was not answered: no process left behind
        raise
    return subprocess.CompletedProcess(argv, proc.returncode, first + out, err), first


def test_a_ctrl_c_while_xla_computes_ends_the_command_at_once_with_one_line():
    # The main thread blocks inside one compiled call that never returns (its value stays positive):
    # Python's own handler would run only after it returned.
    script = ("from docrl_jax.console import run_main\n"
              "def step(c):\n"   # says 'computing' from inside the compiled loop, at its first iteration
              "    jax.lax.cond(c[0] == 0, lambda: jax.debug.callback(lambda: print('computing', flush=True)),\n"
              "                 lambda: None)\n"
              "    return c[0] + 1, c[1] * 1.0000001 + 1e-9\n"
              "def main():\n"   # JAX is imported (its threads start) once the command runs, as in every command
              "    global jax\n"
              "    import jax, jax.numpy as jnp\n"
              "    spin = jax.jit(lambda x: jax.lax.while_loop(lambda c: c[1][0] > 0, step, (0, x)))\n"
              "    jax.block_until_ready(spin(jnp.ones(256)))\n"
              "    return 0\n"
              "run_main(main)\n")
    done, first = _interrupt_after_first_line([sys.executable, "-c", script])
    assert first == "computing\n"
    assert done.returncode == 130
    assert done.stderr.splitlines() == [console.INTERRUPTED_LINE]


@pytest.mark.parametrize("command", ["evaluate", "train"])
def test_a_ctrl_c_while_a_command_starts_is_one_line_exit_130_and_keeps_what_was_there(tmp_path, command):
    # Sent once the command has printed its first line: it is loading or compiling (the training loop's
    # own three stages begin with its first chunk: tests/train/test_run_safety.py).
    out = tmp_path / "out"
    out.mkdir()
    (out / "kept.txt").write_text("written before")
    argv = {"evaluate": ["evaluate", "--policy", "td3_lstm", "--scenarios", "1", "--trials", "5", "--out", str(out)],
            "train": ["train", "--config", "td3_lstm", "--run-dir", str(out / "run")]}[command]
    done, first = _interrupt_after_first_line([sys.executable, "-m", "docrl_jax", *argv])
    assert "td3_lstm" in first, first    # the policy or the run line
    assert done.returncode == 130, done.stderr
    assert done.stderr.splitlines()[-1] == console.INTERRUPTED_LINE
    assert (out / "kept.txt").read_text() == "written before"
    if command == "evaluate":
        assert [p.name for p in out.iterdir()] == ["kept.txt"]
