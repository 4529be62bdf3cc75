"""How the commands talk and end, light enough for a command line to use before it imports JAX: their
exit codes, their Rich console, `exit_process`, which ends the process safely while a device wait
(docrl_jax.train.loop.wait) may still be blocked inside XLA, and `run_main`, the one way a process runs a
command: a Ctrl-C ends it at once in any phase (`quit_on_ctrl_c`), except inside a training loop, which
stops in three stages of its own (docrl_jax.train.loop.Interrupt, `passing_ctrl_c`)."""

from __future__ import annotations

import _thread
import contextlib
import os
import signal
import sys
import threading
from typing import Callable, NoReturn

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


INTERRUPTED_LINE = "interrupted (Ctrl-C): stopped; files it had already written are kept"

# While non-empty, the watcher of `quit_on_ctrl_c` hands each Ctrl-C to the main thread's Python handler
# (`passing_ctrl_c`): the training loop's stages (docrl_jax.train.loop.Interrupt).
_passing: list[object] = []


def quit_on_ctrl_c() -> None:
    """From now on a Ctrl-C (SIGINT) ends the process at once with one line on stderr and EXIT_INTERRUPTED,
    whatever the main thread is doing: importing, compiling, or blocked inside XLA, where Python's own
    handler would wait until the call returns (and a KeyboardInterrupt raised there can be swallowed or
    left as a traceback); inside `passing_ctrl_c` it goes to the main thread's handler instead. SIGINT is
    blocked in this thread and so in every thread started after it (XLA's pools inherit the mask) and taken
    by a watcher thread that waits for it (sigwait). Call it from the main thread before the command's work
    starts (before JAX is imported: a thread started earlier could take the signal instead); elsewhere it
    does nothing."""
    if threading.current_thread() is not threading.main_thread():
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})

    def watch():
        while True:
            signal.sigwait({signal.SIGINT})
            if not _passing:
                break
            _thread.interrupt_main(signal.SIGINT)   # runs the handler the loop installed, in the main thread
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        with contextlib.suppress(Exception):
            if sys.stderr.isatty():   # a progress display may have hidden the cursor and left its line open
                sys.stderr.write("\x1b[?25h\n")
            sys.stderr.write(f"{INTERRUPTED_LINE}\n")
            sys.stderr.flush()
        os._exit(EXIT_INTERRUPTED)

    threading.Thread(target=watch, daemon=True, name="docrl_jax Ctrl-C").start()


@contextlib.contextmanager
def passing_ctrl_c():
    """Inside, a Ctrl-C reaches the main thread's Python handler (`signal.signal`'s) as if `quit_on_ctrl_c`
    had not been called: a loop that stops in stages of its own."""
    token = object()
    _passing.append(token)
    try:
        yield
    finally:
        _passing.remove(token)


def run_main(main: Callable[[], int | None]) -> NoReturn:
    """Runs a command's `main()` as the process's work and ends the process with its status
    (`exit_process`); a Ctrl-C is answered in every phase (`quit_on_ctrl_c`)."""
    quit_on_ctrl_c()
    exit_process(main() or 0)
