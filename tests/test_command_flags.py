"""One vocabulary of flags: every command that takes --run, --policy, --scenarios, --directions,
--trials, --tank or --out takes the one flag `docrl_jax.flags` defines (its destination, type and help),
and reads its value the one way."""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from docrl_jax import flags
from docrl_jax.arguments import UsageError
from docrl_jax.commands import COMMANDS

REPO = Path(__file__).resolve().parent.parent
# Other names a command accepts for a shared flag (render's singular forms, kept so old lines run).
ALIASES = {"--scenarios": {"--scenario"}, "--directions": {"--direction"}}


def parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every command's parser and its subcommands' parsers, built without running anything."""
    out = []
    for name, command in COMMANDS.items():
        stack = [(name, importlib.import_module(command.module).build_parser())]
        while stack:
            where, p = stack.pop()
            out.append((where, p))
            for action in p._actions:
                if isinstance(action, argparse._SubParsersAction):
                    stack += [(f"{where} {sub}", sp) for sub, sp in action.choices.items()]
    return out


def test_every_shared_flag_is_the_one_definition():
    seen: dict[str, list[str]] = {flag: [] for flag in flags.FLAGS}
    for where, p in parsers():
        for action in p._actions:
            names = set(action.option_strings)
            shared = names & set(flags.FLAGS)
            singular = {a for aliases in ALIASES.values() for a in aliases} & names
            assert shared or not singular, f"{where}: {sorted(singular)} without its shared flag"
            for flag in shared:
                f = flags.FLAGS[flag]
                assert action.dest == f.dest, f"{where} {flag}: dest {action.dest!r}, not {f.dest!r}"
                assert action.type is f.type, f"{where} {flag}: type {action.type}, not {f.type}"
                assert (action.help or "").startswith(f.help), f"{where} {flag}: help {action.help!r}"
                assert names - {flag} <= ALIASES.get(flag, set()), f"{where}: {sorted(names)}"
                seen[flag].append(where)
    # the commands that fly policies take the whole vocabulary
    for flag in flags.FLAGS:
        assert {"evaluate", "render", "robustness"} <= set(seen[flag]), (flag, seen[flag])
    assert {"train", "export", "compare"} <= {w for ws in seen.values() for w in ws}


def test_render_takes_the_evaluator_s_flags_with_one_value():
    from docrl_jax.evaluate import video
    p = video.build_parser()
    for argv in (["--scenarios", "3", "--directions", "A-W"], ["--scenario", "3", "--direction", "A-W"]):
        args = p.parse_args(argv)
        assert (args.scenarios, args.directions) == ("3", "A-W")
        assert flags.parse_scenarios(args.scenarios, one="render") == [3]
        assert flags.parse_directions(args.directions, extra=("random",), one="render") == ["air_to_water"]
    with pytest.raises(UsageError, match=r"^--scenarios 1,2: render draws one scenario; give one "
                                         r"\(e.g. --scenarios 1\)$"):
        flags.parse_scenarios("1,2", one="render")
    with pytest.raises(UsageError, match=r"^--directions W-A,random: render draws one direction"):
        flags.parse_directions("W-A,random", extra=("random",), one="render")
    # the evaluator's lists read the same way
    assert flags.parse_scenarios("3,1,3") == [1, 3]
    assert flags.parse_directions("w-a,AW,water_to_air") == ["water_to_air", "air_to_water"]
    with pytest.raises(UsageError, match=r"^--directions 'random': valid directions are air_to_water \(A-W\), "
                                         r"water_to_air \(W-A\)$"):
        flags.parse_directions("random")   # only render's trials have it


@pytest.mark.parametrize("argv, line", [
    (["--scenarios", "1,2", "--out", "v.gif"], "--scenarios 1,2: render draws one scenario; give one "
                                               "(e.g. --scenarios 1)"),
    (["--directions", "A-W,W-A", "--out", "v.gif"], "--directions A-W,W-A: render draws one direction"),
    (["--scenario", "4", "--out", "v.gif"], "--scenarios '4': valid scenarios are 1, 2, 3"),
])
def test_render_refuses_a_list_in_one_line(argv, line, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "docrl_jax", "render", *argv], capture_output=True, text=True,
                          cwd=tmp_path, env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(err) == 1 and line in err[0], proc.stderr
    assert not list(tmp_path.iterdir())
