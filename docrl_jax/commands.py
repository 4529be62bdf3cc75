"""`docrl`: the package's commands under one name (also `python -m docrl_jax`).

    docrl train --config td3_lstm --run-dir runs/d
    docrl evaluate --policy td3_lstm --trials 20 --scenarios 2
    docrl tanks check my_tank.yaml
    docrl SUBCOMMAND --help

Each subcommand is the command of its module, given the rest of the command line: `docrl evaluate ...`
is `python -m docrl_jax.evaluate ...` (which keeps working), with the same parser, checks and exit
status. `COMMANDS` is the one list.
"""

from __future__ import annotations

import importlib
import sys
from typing import NamedTuple, Sequence

from docrl_jax import __version__
from docrl_jax.arguments import OneLineParser, launcher


class Command(NamedTuple):
    module: str     # its module, whose main(argv) runs it
    summary: str


COMMANDS = {
    "train": Command("docrl_jax.train.cli", "train a config into a run directory, or resume one"),
    "evaluate": Command("docrl_jax.evaluate.cli", "the paper's evaluation protocol: Table I, CSV/JSON, figures"),
    "render": Command("docrl_jax.evaluate.video", "trials drawn by MuJoCo's renderer to an MP4 or GIF"),
    "export": Command("docrl_jax.export.cli", "a trained actor as ONNX, StableHLO and NumPy artefacts"),
    "robustness": Command("docrl_jax.evaluate.robustness_cli", "policies beyond the protocol: perturbations, "
                                                              "random trips, held-out tanks"),
    "sweep": Command("docrl_jax.train.sweep_cli", "a hyperparameter grid x seeds, with as few programs as it allows"),
    "compare": Command("docrl_jax.evaluate.compare", "several evaluations beside the paper's Table I"),
    "tanks": Command("docrl_jax.envs.tanks_cli", "the packaged tanks; check and draw tank files"),
}


def build_parser() -> OneLineParser:
    width = max(map(len, COMMANDS))
    listing = "\n".join(f"  {name:<{width}}  {c.summary}" for name, c in COMMANDS.items())
    p = OneLineParser(prog=launcher() or "docrl", description=__doc__.split("\n\n")[0],
                      epilog=f"subcommands:\n{listing}\n\n'SUBCOMMAND --help' shows its arguments.")
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    p.add_argument("command", nargs="?", metavar="SUBCOMMAND", help="one of the subcommands below")
    p.add_argument("args", nargs="...", metavar="ARGS", help="the subcommand's arguments")
    return p


def chosen(argv: Sequence[str] | None = None) -> tuple[str, list[str]]:
    """(the subcommand named first in `argv` (default: the process's arguments), the rest). An unknown
    subcommand is one line naming the nearest and the valid ones, exit status 2."""
    from docrl_jax.schema import did_you_mean
    parser = build_parser()
    args = parser.parse_args(sys.argv[1:] if argv is None else list(argv))
    if args.command is None:
        parser.error(f"give a subcommand: {', '.join(COMMANDS)} (--help describes them)")
    if args.command not in COMMANDS:
        parser.error(f"unknown subcommand {args.command!r}{did_you_mean(args.command, COMMANDS)} "
                     f"(valid: {', '.join(COMMANDS)})")
    return args.command, args.args


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the subcommand named first in `argv` in this process (`chosen`); returns its exit status."""
    name, rest = chosen(argv)
    return importlib.import_module(COMMANDS[name].module).main(rest)


def entry() -> None:
    """The `docrl` console script and `python -m docrl_jax`: the chosen subcommand as the process's
    work (docrl_jax.console.run_main: its exit status; Ctrl-C answered in every phase)."""
    from docrl_jax.console import run_main
    name, rest = chosen()
    run_main(lambda: importlib.import_module(COMMANDS[name].module).main(rest))
