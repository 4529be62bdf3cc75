"""What every command line of the package shares: the one-line parser errors (`OneLineParser`,
`UsageError`), the help's wrapping, the program name a command shows (`prog`), a list of exact names
(`parse_names`, naming the nearest of an unknown one) and the check of an output path (`check_out`),
so that each problem reads the same in every command. The flags several commands share are defined
once in docrl_jax.flags; a --tank is checked by docrl_jax.evaluate.tank_sets.check, which loads it.

Light on purpose (the standard library only): a command builds its parser and answers --help before
it imports JAX, MuJoCo or Flax.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


class UsageError(ValueError):
    """A bad command line; the message lists the valid choices."""


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """argparse's help, its descriptions kept as written, its argument help wrapped at spaces only: the
    default also breaks at hyphens and inside long words, which cuts names such as
    JAX_COORDINATOR_ADDRESS/JAX_NUM_PROCESSES or a path in two."""

    def _split_lines(self, text, width):
        import textwrap
        text = self._whitespace_matcher.sub(" ", text).strip()
        return textwrap.wrap(text, width, break_on_hyphens=False, break_long_words=False)


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, `PROG: error: MESSAGE`, exit status 2, without the
    usage block (the message names the valid choices; --help shows the rest)."""

    def __init__(self, *args, formatter_class=HelpFormatter, **kwargs):
        super().__init__(*args, formatter_class=formatter_class, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")

    def _check_value(self, action, value):
        """argparse's check of a value with choices (a subcommand's name too), naming the nearest."""
        if action.choices is not None and value not in action.choices:
            from docrl_jax.schema import did_you_mean
            choices = ", ".join(map(repr, action.choices))
            raise argparse.ArgumentError(action, f"invalid choice: {value!r} (choose from {choices})"
                                                 f"{did_you_mean(str(value), [str(c) for c in action.choices])}")


def launcher() -> str | None:
    """How this process was started when through the package's one command line: 'docrl' (the console
    script) or 'python -m docrl_jax'; None for a command's own module (`python -m docrl_jax.evaluate`)
    or a library call."""
    first = Path(sys.argv[0]) if sys.argv and sys.argv[0] else None
    if first is None:
        return None
    if first.stem == "docrl":
        return "docrl"
    if first.name == "__main__.py" and first.parent.name == "docrl_jax":
        return "python -m docrl_jax"
    return None


def prog(command: str) -> str:
    """The program name `command`'s help and errors show: as the user typed it ('docrl evaluate',
    'python -m docrl_jax evaluate', 'python -m docrl_jax.evaluate')."""
    top = launcher()
    return f"{top} {command}" if top else f"python -m docrl_jax.{command}"


def parse_names(flag: str, text: str, valid, noun: str, hint: str = "") -> list[str]:
    """A comma-separated list of names, each exactly one of `valid` (no prefix or alias matching: 'tank'
    is not 'tanks'), without repeats, in the order given. UsageError naming the first unknown one, the
    valid names and the nearest ('--tests 'tank': unknown test 'tank'; valid tests: ...; did you mean
    'tanks'?'). `hint` follows the valid names."""
    from docrl_jax.schema import did_you_mean
    valid = list(valid)
    names = [t.strip() for t in str(text).split(",") if t.strip()]
    bad = [n for n in names if n not in valid] or ([] if names else [str(text)])
    if bad:
        raise UsageError(f"{flag} {text!r}: unknown {noun} {bad[0]!r}; valid {noun}s: {', '.join(valid)}{hint}"
                         f"{did_you_mean(bad[0], valid)}")
    return list(dict.fromkeys(names))


OUT_HELP = "where the command writes"   # what every command's --out help starts with (docrl_jax.flags)


def check_out(path: str | Path, flag: str = "--out", folder: bool = True, parents: bool = True) -> Path:
    """An output the command will write, checked before it does any work: a folder (`folder`) or a file,
    whose missing folders the command makes with their missing parents (`parents`), else only the
    output folder itself. The folders are made here to prove they can be, then removed: nothing is
    left behind. Raises UsageError naming the flag, the path and the problem, as every command
    prints it ('--out /proc/nope: No such file or directory')."""
    path = Path(path)
    if path.exists() and path.is_dir() != folder:
        raise UsageError(f"{flag} {path}: {'is a file, not a folder' if folder else 'is a folder, not a file'}")
    where = path if folder else path.parent
    if parents:
        missing = [p for p in (where, *where.parents) if not p.exists()]
    else:
        missing = [where] if folder and not where.exists() else []
    made: list[Path] = []
    try:
        for p in reversed(missing):   # from the top down
            p.mkdir()
            made.append(p)
        if folder:
            import tempfile
            with tempfile.NamedTemporaryFile(dir=where, prefix=".write_check"):
                pass
        else:
            existed = path.exists()
            with open(path, "ab"):
                pass
            if not existed:
                path.unlink()
    except OSError as e:
        raise UsageError(f"{flag} {path}: {e.strerror or type(e).__name__}") from None
    finally:
        for p in reversed(made):
            try:
                p.rmdir()
            except OSError:
                pass
    return path

