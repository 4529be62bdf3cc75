"""The files a command line names are checked before anything compiles, and each problem is one line
that names the program, the flag, the path and the problem, the same way in every command: an --out
that cannot be written (docrl_jax.arguments.check_out), a --tank that is not a tank file
(docrl_jax.evaluate.tank_sets.check). Nothing is left behind."""

from __future__ import annotations

import io

import pytest

from docrl_jax import arguments
from docrl_jax.evaluate import cli, compare, robustness_cli, video
from docrl_jax.export import cli as export_cli

GIF = b"GIF89a\x01\x00\x01\x00\x80\xff\x00\xff\xff\xff\x00\x00\x00,\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;"


def _one_line(capsys, main, argv) -> str:
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    return err[0]


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """An empty working folder holding one plain file, `blocker`, and one evaluation to compare."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "blocker").write_text("")
    return tmp_path


COMMANDS = {   # command -> (main, arguments before --out, what --out names)
    "evaluate": (cli.main, ["--policy", "bba"], "out"),
    "render": (video.main, ["--policy", "bba"], "out.gif"),
    "export": (export_cli.main, ["--policy", "td3_lstm"], "out"),
    "robustness": (robustness_cli.main, ["--policy", "bba"], "out"),
    "compare": (compare.main, ["blocker"], "out.md"),
}


@pytest.mark.parametrize("command", COMMANDS)
def test_an_out_that_cannot_be_written_is_one_line_in_every_command(command, folder, capsys):
    main, argv, name = COMMANDS[command]
    out = str(folder / "blocker" / name)   # under a file: no folder can be made there, even by root
    line = _one_line(capsys, main, [*argv, "--out", out])
    assert line == f"python -m docrl_jax.{command}: error: --out {out}: Not a directory"
    assert sorted(p.name for p in folder.iterdir()) == ["blocker"]


@pytest.mark.parametrize("command", ["evaluate", "export", "robustness"])
def test_a_folder_out_that_is_a_file(command, folder, capsys):
    main, argv, _ = COMMANDS[command]
    line = _one_line(capsys, main, [*argv, "--out", "blocker"])
    assert line == f"python -m docrl_jax.{command}: error: --out blocker: is a file, not a folder"


def test_check_out_makes_nothing_it_leaves(tmp_path):
    deep = tmp_path / "a" / "b" / "c"
    assert arguments.check_out(deep) == deep and not (tmp_path / "a").exists()       # parents made, then removed
    assert arguments.check_out(deep / "v.gif", folder=False) == deep / "v.gif" and not (tmp_path / "a").exists()
    with pytest.raises(arguments.UsageError, match=r"^--out .*/a/b/c: No such file or directory$"):
        arguments.check_out(deep, parents=False)                                     # only the folder itself
    with pytest.raises(arguments.UsageError, match=r"^--video .*/a/b/c/v.gif: No such file or directory$"):
        arguments.check_out(deep / "v.gif", flag="--video", folder=False, parents=False)
    (tmp_path / "kept").write_text("data")
    assert arguments.check_out(tmp_path / "kept", folder=False) and (tmp_path / "kept").read_text() == "data"
    with pytest.raises(arguments.UsageError, match="kept: is a file, not a folder$"):
        arguments.check_out(tmp_path / "kept")
    with pytest.raises(arguments.UsageError, match=f"{tmp_path.name}: is a folder, not a file$"):
        arguments.check_out(tmp_path, folder=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept"]


@pytest.fixture
def bad_tanks(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "picture.gif").write_bytes(GIF)
    (tmp_path / "words.yaml").write_text("a tank with a wall\n")
    (tmp_path / "list.json").write_text("[1, 2]\n")
    (tmp_path / "keys.yaml").write_text("floor_top: -1.3\nsolid: []\n")
    return tmp_path


TANK_PROBLEMS = {
    "picture.gif": "not a text file; a tank file is YAML or JSON text (docs/TANKS.md)",
    "words.yaml": "a tank file holds a mapping of keys (name, description, floor_top, air, water, solids), not str",
    "list.json": "a tank file holds a mapping of keys (name, description, floor_top, air, water, solids), not list",
    "keys.yaml": "unknown key 'solid'; valid keys: name, description, floor_top, air, water, solids; did you mean "
                 "'solids'?",
}


@pytest.mark.parametrize("tank", TANK_PROBLEMS)
@pytest.mark.parametrize("command", ["evaluate", "render", "robustness"])
def test_a_tank_that_is_not_a_tank_file_is_one_line(command, tank, bad_tanks, capsys):
    main, argv = {"evaluate": (cli.main, []), "render": (video.main, ["--out", "v.gif"]),
                  "robustness": (robustness_cli.main, ["--tests", "tanks", "--out", "r"])}[command]
    line = _one_line(capsys, main, ["--policy", "bba", "--tank", tank, *argv])
    assert line == f"python -m docrl_jax.{command}: error: --tank {bad_tanks / tank}: {TANK_PROBLEMS[tank]}"
    assert sorted(p.name for p in bad_tanks.iterdir()) == sorted(TANK_PROBLEMS)


def test_train_names_the_flag_of_a_bad_tank(bad_tanks, monkeypatch):
    from docrl_jax.train import cli as train_cli
    console = train_cli.make_console(file=io.StringIO(), width=300)
    monkeypatch.setattr(train_cli, "make_console", lambda **kw: console)
    assert train_cli.main(["--config", "td3_lstm", "--tank", "picture.gif", "--run-dir", "run",
                           "--compile-cache", "off"]) == train_cli.EXIT_CONFIG
    assert console.file.getvalue().strip().splitlines() == [
        f"error: --tank {bad_tanks / 'picture.gif'}: {TANK_PROBLEMS['picture.gif']}"]
    assert not (bad_tanks / "run").exists()


def test_the_readme_commands_write_under_the_ignored_out_folder():
    """What the README's commands write lands in out/, which git ignores, not across the checkout."""
    import re
    from pathlib import Path
    root = Path(__file__).resolve().parent.parent
    outs = re.findall(r"^    (?:python -m docrl_jax\S*|docrl) .*--out (\S+)", (root / "README.md").read_text(), re.M)
    assert len(outs) >= 8 and all(o.startswith("out/") for o in outs), outs
    assert "/out/" in (root / ".gitignore").read_text().splitlines()
