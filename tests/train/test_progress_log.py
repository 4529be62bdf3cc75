"""What training prints when its output is not a terminal (a log file, a pipe, a batch job): one whole
line per chunk, never cut at 80 columns, and the final message on a line of its own. The progress bar
is for a terminal: a live display drawn into a file comes out once, cut, with the next line run on."""

from __future__ import annotations

import io

from docrl_jax.console import make_console
from docrl_jax.train.run import _Display

STATS = "train return -12.3  train success 0.05  eval success 0.10  critic 16.4  actor 1.23  alpha 0.0123"
FINAL = "interrupted: checkpoint saved at env step 12,000; resume with python -m docrl_jax.train --run-dir r --resume"


def _show(console) -> str:
    display = _Display(console, "td3_lstm", 100_000, 0, show_progress=True)
    with display.live():
        for steps in (4_000, 8_000, 12_000):
            display.chunk(steps, 1234.5, "ETA 3 min 10 s", STATS)
    console.print(FINAL)
    return console.file.getvalue()


def test_a_log_gets_one_whole_line_per_chunk_and_the_final_message_on_its_own():
    text = _show(make_console(file=io.StringIO()))       # a file: not a terminal, Rich's width 80
    assert text.splitlines() == [f"{steps} steps  1,234 steps/s  ETA 3 min 10 s  {STATS}"
                                 for steps in ("4,000", "8,000", "12,000")] + [FINAL]


def test_a_terminal_keeps_the_progress_bar():
    console = make_console(file=io.StringIO(), force_terminal=True, force_interactive=True, width=120)
    text = _show(console)
    assert "12,000/100,000 env steps" in text and "\n4,000 steps  " not in text
