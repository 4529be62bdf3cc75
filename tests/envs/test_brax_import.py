"""Importing the Brax adapter writes nothing: Brax imports `mujoco.mjx`, which prints a notice about
its optional Warp backend when Warp is absent (docrl_jax/envs/_quiet_import.py drops exactly that)."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("brax")


def test_importing_the_brax_adapter_prints_nothing():
    # A fresh process: in this one MJX is already imported, and its notice printed or not long ago.
    done = subprocess.run([sys.executable, "-c", "import docrl_jax.envs.brax_env"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "" and done.stderr == "", (done.stdout, done.stderr)
