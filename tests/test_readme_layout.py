"""The README is a front page: short, its set-up and test commands the ones CI runs, a quickstart of the
four commands for a GPU and a CPU, one results table, every docs page linked, and no dead link."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MAX_WORDS = 1500
SECTIONS = ("Install", "Quickstart", "Results", "Documentation")
QUICKSTART_COMMANDS = ("docrl_jax.train", "docrl_jax.evaluate", "docrl_jax.render", "docrl_jax.export")
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)")


def ci_commands(ci_script: str) -> list[str]:
    """The set-up and test commands .ci/run runs: its lines after the cd and the clean-up."""
    lines = [line.strip() for line in ci_script.splitlines()]
    return [line for line in lines if line.startswith(("python3 -m venv", ". .venv/bin/activate"))]


def sections(text: str) -> dict[str, str]:
    """'## Title' -> the text under it, up to the next '## '."""
    parts = re.split(r"^## +(.+)$", text, flags=re.M)
    return {title.strip(): body for title, body in zip(parts[1::2], parts[2::2])}


def tables(text: str) -> int:
    """The number of Markdown tables (header rows followed by a |---| row)."""
    return len(re.findall(r"^\|.*\|\n\|[-| :]+\|$", text, flags=re.M))


def problems(readme: str, ci_script: str, root: Path) -> list[str]:
    """Everything that keeps `readme` from being the front page; empty when it is one."""
    found = []
    words = len(readme.split())
    if words > MAX_WORDS:
        found.append(f"{words} words, more than {MAX_WORDS}")
    code_lines = {line.strip() for line in readme.splitlines() if line.startswith("    ")}
    commands = ci_commands(ci_script)
    if len(commands) != 2:
        found.append(f".ci/run should run a set-up and a test command, found {commands}")
    for command in commands:
        if command not in code_lines:
            found.append(f"README does not give .ci/run's command as a code line: {command}")
    body = sections(readme)
    missing = [s for s in SECTIONS if s not in body]
    if missing:
        found.append(f"sections missing: {missing}")
    order = [s for s in body if s in SECTIONS]
    if order != [s for s in SECTIONS if s in body]:
        found.append(f"sections out of order: {order}, expected {list(SECTIONS)}")
    quick = body.get("Quickstart", "")
    for path in ("On a GPU", "On a CPU"):
        part = quick.split(f"**{path}.**", 1)[1] if f"**{path}.**" in quick else ""
        part = re.split(r"\*\*On a [CG]PU\.\*\*", part)[0]
        runs = [c for c in QUICKSTART_COMMANDS if any(f"python -m {c} " in line for line in part.splitlines()
                                                      if line.startswith("    "))]
        if path == "On a GPU" and runs != list(QUICKSTART_COMMANDS):
            found.append(f"the GPU quickstart should run {QUICKSTART_COMMANDS}, runs {runs}")
        if path == "On a CPU" and runs != list(QUICKSTART_COMMANDS[1:]):
            found.append(f"the CPU quickstart should run {QUICKSTART_COMMANDS[1:]}, runs {runs}")
    if tables(body.get("Results", "")) != 1:
        found.append(f"the Results section should hold one table, holds {tables(body.get('Results', ''))}")
    for target in LINK.findall(readme):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        path = target.split("#", 1)[0]
        if not (root / path).exists():
            found.append(f"dead link: {target}")
    linked = {t.split("#", 1)[0] for t in LINK.findall(readme)}
    for page in sorted((root / "docs").glob("*.md")):
        if page.relative_to(root).as_posix() not in linked:
            found.append(f"docs page not linked: {page.relative_to(root).as_posix()}")
    return found


def test_the_readme_is_a_front_page():
    readme = (ROOT / "README.md").read_text()
    assert problems(readme, (ROOT / ".ci" / "run").read_text(), ROOT) == []


def test_each_check_can_fail():
    """A README that breaks each rule once gets one problem per rule."""
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    setup = ci_commands(ci)[0]
    broken = {
        "words": readme + " word" * MAX_WORDS,
        ".ci/run's command": readme.replace(setup, setup.replace(".[test]", ".[docs]")),
        "sections missing": readme.replace("## Results", "## Numbers"),
        "GPU quickstart": readme.replace("python -m docrl_jax.export --run runs/d", "python -m docrl_jax.exprt"),
        "one table": readme.replace("## Results\n", "## Results\n\n| a |\n|---|\n| b |\n"),
        "dead link": readme + "\n[gone](docs/NO_SUCH_PAGE.md)\n",
        "not linked": readme.replace("(docs/LEVELS.md)", "(docs/TANKS.md)"),
    }
    for rule, text in broken.items():
        found = problems(text, ci, ROOT)
        assert any(rule in p for p in found), (rule, found)
