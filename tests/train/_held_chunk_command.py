"""Run by tests/train/test_run_safety.py in a subprocess: the training command, `python -m docrl_jax.train
ARGS`, whose second chunk never ends. Its wait (docrl_jax.train.loop.wait) also waits for a device
computation that runs until the process is gone, so every Ctrl-C the test sends after the first chunk's
progress line lands while a chunk computes, with `wait`'s helper thread inside XLA, however fast or busy
the machine.

    python tests/train/_held_chunk_command.py ARGS...
"""

from __future__ import annotations

import runpy

import jax
import jax.numpy as jnp

from docrl_jax.train import loop


def _endless():
    """A device computation that outlasts any test: 2**31 - 1 products of 64 x 64 matrices, each needing the
    one before (hours on any CPU). Made of matrix products, XLA's CPU client runs it in its own threads (a
    computation it deems cheap, such as a loop of scalar steps, would run in this thread's call)."""
    return jax.jit(lambda x: jax.lax.fori_loop(0, 2**31 - 1, lambda _, v: jnp.sin(v @ v.T) / 64.0, x))(
        jnp.ones((64, 64)))


_real_wait, _waits = loop.wait, [0]


def _wait(tree, interrupt=None, poll_s=0.1):
    _waits[0] += 1
    if _waits[0] == 2:   # the second chunk
        return _real_wait((tree, _endless()), interrupt, poll_s)[0]
    return _real_wait(tree, interrupt, poll_s)


loop.wait = _wait
runpy.run_module("docrl_jax.train", run_name="__main__", alter_sys=True)
