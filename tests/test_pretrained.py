"""The policies shipped in the package (docrl_jax.pretrained): each loads into its config's actor, and
`python -m docrl_jax.render` with no arguments draws a shipped policy's success: the generalist's
first scenario-2 W-A trial, then (the same program) its first A-W trial. Table I's three shipped
policies fly the paper's scenario-2 pairs in tests/export/test_export_parity.py, whose compiled env
(the default vehicle) they share; the generalist flies in its own (beams, controller), here."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import yaml

from docrl_jax import pretrained, sharding
from docrl_jax.evaluate import cli, rollout, video
from docrl_jax.export import cli as export_cli


def test_every_name_is_a_policy_of_its_config():
    assert set(pretrained.PRETRAINED) == {"td3_lstm", "sac_lstm", "sac_mlp", "sac_mlp_generalist", "sac_mlp_tanks"}
    assert pretrained.POLICY_NAMES == ("bba", *pretrained.PRETRAINED)
    for name in pretrained.PRETRAINED:
        policy = pretrained.load(name)
        stored = yaml.safe_load(pretrained._file(name, ".yaml").read_text())["agent"]
        algo, actor = name.split("_")[:2]
        assert (stored["algo"], stored["actor"]) == (algo, actor) == (pretrained.config(name).agent.algo,
                                                                       pretrained.config(name).agent.actor)
        leaves = jax.tree.leaves(policy.params)
        assert all(x.dtype == jnp.float32 and bool(jnp.isfinite(x).all()) for x in leaves)
        assert policy.source.startswith(f"shipped policy {name}: ")
    assert sum(pretrained._file(n, ".npz").stat().st_size for n in pretrained.PRETRAINED) < 1_000_000   # lean
    assert pretrained.vehicle("td3_lstm") == {"vel_i_rate": 0.3} and pretrained.vehicle("sac_lstm") == {}
    assert pretrained.vehicle("sac_mlp_generalist") == {"slant_beams": 8, "slant_elevation_deg": 30,
                                                        "vel_i_rate": 0.3, "vertical_beams": True}


def test_a_file_that_does_not_match_its_config_is_refused(tmp_path, monkeypatch):
    """An .npz that lacks a leaf of the actor the config builds (or has one of another shape)."""
    with np.load(pretrained._file("td3_lstm", ".npz")) as f:
        arrays = dict(f)
    arrays.pop("params/head/out/bias")
    np.savez(tmp_path / "td3_lstm.npz", **arrays)
    (tmp_path / "td3_lstm.yaml").write_bytes(pretrained._file("td3_lstm", ".yaml").read_bytes())
    monkeypatch.setattr(pretrained, "_file", lambda name, suffix: tmp_path / f"{name}{suffix}")
    with pytest.raises(ValueError, match="td3_lstm.npz does not match the actor of td3_lstm.yaml"):
        pretrained.load.__wrapped__("td3_lstm")


def test_an_unknown_name_is_one_line_naming_the_valid_ones():
    with pytest.raises(pretrained.UnknownPolicy) as e:
        pretrained.check_name("ppo")
    assert str(e.value) == ("--policy 'ppo': unknown policy; valid choices: bba, td3_lstm, sac_lstm, sac_mlp, "
                            "sac_mlp_generalist, sac_mlp_tanks (or --run RUN_DIR for a trained agent)")


def test_render_by_default_draws_a_shipped_policy_succeeding(tmp_path, monkeypatch, capsys):
    """No arguments: the generalist's first scenario-2 W-A trial, a success, to flight.gif (drawn small
    here; the default 640x240 is 2.5 MB). The same program then flies its first A-W trial."""
    monkeypatch.chdir(tmp_path)
    assert video.main(["--width", "64", "--height", "32"]) == 0
    text = capsys.readouterr().out
    assert "scenario 2 W-A sac_mlp_generalist trial 1/1: success after" in text, text
    steps = int(text.split("success after ")[1].split()[0])
    frames = len(range(0, steps + 1, video.GIF_EVERY)) + (steps % video.GIF_EVERY != 0)   # and the last step
    assert f"wrote flight.gif: {frames} frames of 64x32" in text
    env = rollout.make_eval_env(2, 500, **rollout.flown_env(pretrained.vehicle("sac_mlp_generalist"), {}))
    trials = video.trials_to_render(env, pretrained.load("sac_mlp_generalist"), 2, "air_to_water", 1)
    assert bool(trials["success"][0])


def test_the_cpu_device_line_names_commands_that_run(tmp_path, monkeypatch):
    """On a CPU, the trainer's device line says what to run instead: each command it names passes its
    command's checks (a renamed flag or policy would fail here)."""
    class Cpu:
        platform = "cpu"
    monkeypatch.setattr(sharding.jax, "devices", lambda: [Cpu()])
    monkeypatch.chdir(tmp_path)
    line = sharding.device_line()
    assert "Training needs a GPU" in line
    commands = [c.split() for c in line.split("instead: ")[1].split("; ")]
    assert [c[:3] for c in commands] == [["python", "-m", f"docrl_jax.{m}"] for m in ("evaluate", "render", "export")]
    evaluate, render, export = (c[3:] for c in commands)
    assert cli.validate_args(cli.build_parser().parse_args(evaluate))["scenarios"] == [2]
    args = video.build_parser().parse_args(render)
    video.validate_args(args)
    assert args.policy in pretrained.PRETRAINED and not list(tmp_path.iterdir())
    assert export_cli.build_parser().parse_args(export).policy in pretrained.PRETRAINED
