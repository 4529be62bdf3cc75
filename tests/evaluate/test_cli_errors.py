"""Bad input to `python -m docrl_jax.evaluate`, `render` and `export` is one line on stderr, exit status
2, without argparse's usage block, before anything compiles; `--policy` takes the shipped policies'
names and an unknown one lists them all."""

from __future__ import annotations

import pytest

from docrl_jax import pretrained
from docrl_jax.evaluate import cli, cli_run, run_dirs, video
from docrl_jax.export import cli as export_cli

VALID = "valid choices: bba, td3_lstm, sac_lstm, sac_mlp, sac_mlp_generalist, sac_mlp_tanks"


@pytest.fixture
def no_compile(monkeypatch):
    def refuse(*a, **k):
        pytest.fail("a bad command line reached the rollout")
    monkeypatch.setattr(cli_run, "evaluate", refuse)
    monkeypatch.setattr(video, "trials_to_render", refuse)


def _one_line(capsys, main, argv, prog) -> str:
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1 and err[0].startswith(f"python -m docrl_jax.{prog}: error: "), err
    return err[0]


@pytest.mark.parametrize("argv, message", [
    # the line a new user met below the 10-line usage block
    (["--policy", "nope"], f"--policy 'nope': unknown policy; {VALID} (or --run RUN_DIR for a trained agent)"),
    (["--policy", "td3_lstm", "--trials", "x"], "argument --trials: invalid int value: 'x'"),
    (["--policy", "td3_lstm", "--scenarios", "9"], "--scenarios '9': valid scenarios are 1, 2, 3"),
    (["--run", "x", "--policy", "bba"], "argument --policy: not allowed with argument --run"),
    (["--bogus"], "unrecognized arguments: --bogus"),
    ([], "nothing to do: give --run RUN_DIR or --policy NAME (valid policies: bba, td3_lstm,"),
])
def test_evaluate_errors_are_one_line(argv, message, capsys, no_compile):
    assert message in _one_line(capsys, cli.main, argv, "evaluate")


@pytest.mark.parametrize("argv, message", [
    (["--scenario", "9"], "--scenarios '9': valid scenarios are 1, 2, 3"),   # likewise: render's --scenarios
    (["--policy", "nope"], f"--policy 'nope': unknown policy; {VALID}"),
    (["--policy", "td3_lstm", "--width", "abc"], "argument --width: invalid int value: 'abc'"),
    (["--out", "x.avi"], "valid suffixes are .mp4, .gif"),
])
def test_render_errors_are_one_line(argv, message, capsys, no_compile, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert message in _one_line(capsys, video.main, argv, "render")
    assert not list(tmp_path.iterdir())


def test_export_takes_shipped_policies_only(capsys, tmp_path):
    out = str(tmp_path / "out")
    for argv, message in ((["--policy", "bba", "--out", out], "bba is a controller, not a network"),
                          (["--policy", "nope", "--out", out], "valid choices: td3_lstm, sac_lstm, sac_mlp,"),
                          (["--policy", "td3_lstm", "--which", "best", "--out", out], "one seed's final policy"),
                          (["--out", out], "one of the arguments --run --policy is required")):
        code = None
        try:
            code = export_cli.main(argv)
        except SystemExit as e:   # argparse's own errors
            code = e.code
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and message in err[0], err
    assert not (tmp_path / "out").exists()


def test_every_command_takes_every_shipped_policy(no_compile, tmp_path):
    """The names the --policy help lists pass each command's checks (and the robustness benchmark's
    list stays the baselines it flies)."""
    assert cli.POLICIES == pretrained.BASELINES
    for name in pretrained.POLICY_NAMES:
        args = cli.build_parser().parse_args(["--policy", name.upper(), "--scenarios", "2"])
        assert cli.validate_args(args)["scenarios"] == [2] and args.policy == name
        args = video.build_parser().parse_args(["--policy", name, "--out", str(tmp_path / "x.gif")])
        cfg = video.validate_args(args)
        assert cfg["env"] == run_dirs.run_vehicle(None, name) and args.every == video.GIF_EVERY
    assert run_dirs.run_vehicle(None, "sac_mlp_generalist")["vertical_beams"] is True
