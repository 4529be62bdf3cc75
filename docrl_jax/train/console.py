"""How the training commands (train, sweep) talk and end, light enough for a command line to use
before it imports JAX: their exit codes, their Rich console, and `exit_process`, which ends the process
safely while a device wait (docrl_jax.train.loop.wait) may still be blocked inside XLA."""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from typing import NoReturn

EXIT_OK, EXIT_CONFIG, EXIT_NONFINITE, EXIT_INTERRUPTED = 0, 2, 3, 130

# docrl_jax.train.loop.wait's helper threads, while the device computes
waiters: list[threading.Thread] = []


def make_console(**kwargs):
    """The commands' Rich console: output that is not a terminal (a log file, a pipe) is not wrapped
    at 80 columns, so a printed command or path stays on one line."""
    from rich.console import Console
    return Console(soft_wrap=True, **kwargs)


def exit_process(status: int) -> NoReturn:
    """Ends a command's process with `status`. After a third Ctrl-C the device may still compute the
    chunk the loop walked away from, with `wait`'s helper thread blocked inside XLA: Python's
    shutdown would end that thread in the middle of the call and the C++ runtime would abort
    ('terminate called after throwing an instance of ...', exit 134). Then the process leaves
    without Python's shutdown, once the threads that Python would wait for have ended (the program
    store's writes) and its output is flushed; what it keeps (checkpoints, metrics.csv, TensorBoard
    events) is written and closed by then."""
    if any(t.is_alive() for t in waiters):
        for thread in threading.enumerate():
            if not thread.daemon and thread is not threading.current_thread():
                thread.join()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(status)
    raise SystemExit(status)
