"""The flags several commands share, each defined once: its name, destination, type and the help every
command's starts with (`FLAGS`, added by `add`), and the one check of its value.

    add(p, "--trials", " per scenario and direction (default 100)", default=100)
    add(p, "--scenarios", " (default 2); render flies one", "--scenario")   # an alias after the detail
    parse_scenarios("1,3") -> [1, 3]          parse_directions("W-A") -> ["water_to_air"]
    check_positive("--trials", 0)             # UsageError: '--trials 0: must be a positive integer'

A command that takes one of these flags adds it here, so `evaluate --scenarios 2` and `render
--scenarios 2` are one flag read one way (tests/test_command_flags.py walks every command's parser).
The other checks of a shared flag have one home each too: --out `arguments.check_out`, --tank
`evaluate.tank_sets.check`, --policy `pretrained.check_name`, --run `evaluate.run_dirs.check_run_dir`,
--trials' memory `evaluate.trial_memory`.

Light on purpose (the standard library and the protocol's names): a command builds its parser before it
imports JAX. On the evaluation's floor (tests/test_imports.py), as it reads the protocol's scenarios.
"""

from __future__ import annotations

import argparse
from typing import Callable, NamedTuple, Sequence

from docrl_jax.arguments import OUT_HELP, UsageError
from docrl_jax.evaluate.protocol import DIRECTIONS, SCENARIOS


class Flag(NamedTuple):
    dest: str
    type: Callable | None
    help: str   # what every command's help of the flag starts with


# A direction by its name or its short name, in any case.
DIRECTION_NAMES = {**{d: d for d in DIRECTIONS}, "a-w": "air_to_water", "w-a": "water_to_air",
                   "aw": "air_to_water", "wa": "water_to_air"}
DIRECTIONS_TEXT = "air_to_water (A-W), water_to_air (W-A)"

FLAGS = {
    "--run": Flag("run", None, "a trainer run directory (config.yaml + checkpoints)"),
    "--policy": Flag("policy", None, "a policy built into the package, by name"),
    "--scenarios": Flag("scenarios", None, "the paper's scenarios, comma-separated: 1, 2, 3"),
    "--directions": Flag("directions", None, f"comma-separated: {DIRECTIONS_TEXT}"),
    "--trials": Flag("trials", int, "how many trials"),
    "--tank": Flag("tank", None, "a tank set: a tank file, a folder of them, a packaged tank's name, or gallery "
                                 "(every packaged tank; docs/TANKS.md)"),
    "--out": Flag("out", None, OUT_HELP),
}


def add(p, flag: str, detail: str = "", *aliases: str, **kwargs) -> argparse.Action:
    """Adds the shared `flag` (and its `aliases`, other names of the same flag) to the parser or group
    `p`: its destination, type and help from `FLAGS`, the command's own `detail` after that help;
    `kwargs` (default, metavar, nargs, action, required) are the command's."""
    f = FLAGS[flag]
    return p.add_argument(flag, *aliases, dest=f.dest, type=f.type, help=f.help + detail, **kwargs)


def check_positive(flag: str, value: int) -> int:
    """A count (--trials, --layouts, --max-steps): a positive integer."""
    if value <= 0:
        raise UsageError(f"{flag} {value}: must be a positive integer")
    return value


def _one(flag: str, text: str, values: list, what: str, command: str | None) -> None:
    if command is not None and len(values) > 1:
        raise UsageError(f"{flag} {text}: {command} draws one {what}; give one (e.g. {flag} {values[0]})")


def parse_scenarios(text: str, flag: str = "--scenarios", one: str | None = None) -> list[int]:
    """The scenarios of a comma-separated list, sorted, without repeats. `one`: the command that flies a
    single scenario (a list is refused in one line saying so)."""
    valid = ", ".join(map(str, SCENARIOS))
    try:
        values = [int(t) for t in str(text).split(",") if t.strip() != ""]
    except ValueError:
        values = []
    if not values or any(v not in SCENARIOS for v in values):
        raise UsageError(f"{flag} {text!r}: valid scenarios are {valid} (comma-separated, e.g. 1,2,3)")
    values = sorted(set(values))
    _one(flag, text, values, "scenario", one)
    return values


def parse_directions(text: str, flag: str = "--directions", extra: Sequence[str] = (),
                     one: str | None = None) -> list[str]:
    """The directions of a comma-separated list (their names, A-W, W-A, AW, WA, any case), in the order
    given, without repeats; `extra`: the command's other values (render's `random`). `one`: as for
    `parse_scenarios`."""
    from docrl_jax.schema import did_you_mean
    names = {**DIRECTION_NAMES, **{e: e for e in extra}}
    values = [t.strip().lower() for t in str(text).split(",") if t.strip()]
    bad = [v for v in values if v not in names] or ([] if values else [str(text)])
    if bad:
        valid = DIRECTIONS_TEXT + "".join(f", {e}" for e in extra)
        raise UsageError(f"{flag} {text!r}: valid directions are {valid}"
                         f"{did_you_mean(bad[0], [*DIRECTIONS, *extra])}")
    values = list(dict.fromkeys(names[v] for v in values))
    _one(flag, text, values, "direction", one)
    return values


def check_tank_or_scenarios(tank: str | None, scenarios: str | None, flag: str = "--scenarios") -> None:
    """--tank and --scenarios exclude each other: a tank set's trials fly in scenario 0."""
    if tank is not None and scenarios is not None:
        raise UsageError(f"--tank {tank} and {flag} {scenarios}: a tank set's trials fly in scenario 0, in place of "
                         "the scenarios' paper pairs; give one of them")
