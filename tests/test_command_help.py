"""Every command answers --help before it imports JAX, MuJoCo or Flax (seconds on a CPU), and its help
keeps names whole: each subcommand of `docrl` and each `python -m docrl_jax.COMMAND`, in a fresh process
whose imported modules are read once the parser has printed its help."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from docrl_jax import commands

ROOT = Path(__file__).resolve().parent.parent
HEAVY = ("jax", "mujoco", "flax", "optax", "orbax.checkpoint", "matplotlib")

# Runs a command's --help in this process and reports its exit status and the heavy modules imported.
PROBE = """
import json, runpy, sys
how, name = sys.argv[1], sys.argv[2]
sys.argv = [name, "--help"]
try:
    if how == "docrl":
        from docrl_jax import commands
        commands.main([name, "--help"] if name else ["--help"])
    else:
        runpy.run_module(name, run_name="__main__", alter_sys=True)
    code = None
except SystemExit as e:
    code = e.code
print(json.dumps({"code": code, "heavy": [m for m in %r if m in sys.modules]}), file=sys.stderr)
""" % (HEAVY,)


def _probe(how: str, name: str) -> dict:
    out = subprocess.run([sys.executable, "-c", PROBE, how, name], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stderr.strip().splitlines()[-1])
    assert "usage:" in out.stdout, out.stdout
    return report


@pytest.mark.parametrize("name", ["", *commands.COMMANDS])
def test_docrl_help_imports_nothing_heavy(name):
    assert _probe("docrl", name) == {"code": 0, "heavy": []}


@pytest.mark.parametrize("module", ["docrl_jax.train", "docrl_jax.evaluate", "docrl_jax.render", "docrl_jax.export"])
def test_python_m_help_imports_nothing_heavy(module):
    assert _probe("module", module) == {"code": 0, "heavy": []}


def test_help_keeps_every_word_whole(monkeypatch):
    """argparse's default wrapping breaks words at hyphens and cuts a word longer than the column
    (JAX_COORDINATOR_ADDRESS/JAX_NUM_PROCESSES/JAX_PROCESS_ID came out as '...ADDR' and 'ESS/...')."""
    import importlib
    monkeypatch.setenv("COLUMNS", "60")
    for name, command in commands.COMMANDS.items():
        parser = importlib.import_module(command.module).build_parser()
        shown = set(parser.format_help().split())
        for action in parser._actions:
            cut = [w for w in (action.help or "").split() if w not in shown and "%" not in w]
            assert not cut, (name, action.dest, cut)
    from docrl_jax.train import cli
    assert "JAX_COORDINATOR_ADDRESS/JAX_NUM_PROCESSES/JAX_PROCESS_ID" in cli.build_parser().format_help().split()
