"""An unknown name (a config, a section, a key, an env parameter) is one line naming it, the valid
names nearest it and where every valid one is declared, raised before anything is built or compiled."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from docrl_jax import schema
from docrl_jax.config import ConfigError, config_from_dict, load_config

REPO = Path(__file__).resolve().parent.parent


def test_the_nearest_names_by_spelling_or_word_order_and_only_those_about_as_near():
    keys = ["actor", "actor_lr", "critic_lr", "gamma", "lidar_fov_deg", "sonar_fov_deg"]
    assert schema.did_you_mean("actor_lrr", keys) == "; did you mean 'actor_lr'?"      # a typo
    assert schema.did_you_mean("lr_actr", keys) == "; did you mean 'actor_lr'?"        # words swapped
    # 'sonar_fov_deg' shares most of 'lidar_fov' too, but is much farther than 'lidar_fov_deg'
    assert schema.did_you_mean("lidar_fov", keys) == "; did you mean 'lidar_fov_deg'?"
    assert schema.did_you_mean("learning_rate", keys) == ""                           # nothing near
    assert schema.did_you_mean("x", []) == ""
    assert schema.did_you_mean("wind_sigm", ["wind_sigma", "wind_sigmb", "wind_sigmc", "wind_sigmd"]) == \
        "; did you mean 'wind_sigma', 'wind_sigmb' or 'wind_sigmc'?"                   # at most three
    assert schema.did_you_mean("lr", ["agent.actor_lr", "train.lr"], key=lambda k: k.split(".")[1],
                               shown=str.upper) == "; did you mean 'TRAIN.LR'?"


def _declares(message: str, cls_name: str) -> bool:
    """Whether the file the message names (docrl_jax/....py) declares `cls_name`: the pointer is true."""
    path = re.search(r"(docrl_jax/[\w/]+\.py)", message).group(1)
    return f"class {cls_name}" in (REPO / path).read_text()


def test_an_unknown_config_name_or_file(tmp_path):
    with pytest.raises(ConfigError, match=r"^config 'td3_lsmt' is neither a file nor a packaged config; packaged "
                                          r"configs: ddpg_mlp, .*, td3_lstm_tanks; did you mean 'td3_lstm'\?$"):
        load_config("td3_lsmt")
    (tmp_path / "mine.yaml").write_text("extends: td3_lstm\n")
    with pytest.raises(ConfigError, match=rf"^config file '{tmp_path}/mien.yaml' does not exist; did you mean "
                                          rf"'{tmp_path}/mine.yaml'\?$"):
        load_config(str(tmp_path / "mien.yaml"))


@pytest.mark.parametrize("override, suggestion", [
    ("agent.lr_actr=1e-3", "agent.actor_lr"),
    ("replay.seq_length=8", "replay.seq_len"),
    ("train.eval_evry=5", "train.eval_every"),
])
def test_an_unknown_key_names_the_nearest_and_the_file_that_declares_every_key(override, suggestion):
    key, section = override.split("=")[0], override.split(".")[0]
    with pytest.raises(ConfigError) as e:
        load_config("td3_lstm", [override])
    cls = {"agent": "AgentConfig", "replay": "ReplayConfig", "train": "TrainConfig"}[section]
    assert re.fullmatch(rf"unknown key '{key}'; valid keys: the fields of {cls} in docrl_jax/\S+\.py; "
                        rf"did you mean '{suggestion}'\?", str(e.value)), str(e.value)
    assert _declares(str(e.value), cls)


def test_an_unknown_env_key_or_parameter():
    with pytest.raises(ConfigError) as e:
        load_config("td3_lstm", ["env.lidar_fov=90"])
    assert re.fullmatch(r"unknown key 'env.lidar_fov'; valid keys: env.scenario, env.num_envs and the fields of "
                        r"EnvParams in docrl_jax/\S+\.py; did you mean 'env.lidar_fov_deg'\?", str(e.value)), str(e.value)
    assert _declares(str(e.value), "EnvParams")
    from docrl_jax import envs
    with pytest.raises(ValueError) as e:   # the Python API: no MuJoCo model is built for a bad name
        envs.make(lidar_fov=90, windy=True)
    assert re.fullmatch(r"unknown env parameter 'lidar_fov' \(and 1 more: 'windy'\); valid names: the fields of "
                        r"EnvParams in docrl_jax/\S+\.py; did you mean 'lidar_fov_deg'\?", str(e.value)), str(e.value)
    assert _declares(str(e.value), "EnvParams")


def test_an_unknown_section_or_a_key_without_one():
    with pytest.raises(ConfigError, match=r"^override 'agnt.actor_lr': unknown section 'agnt'; sections: env, agent, "
                                          r"replay, train, levels; did you mean 'agent.actor_lr'\?$"):
        load_config("td3_lstm", ["agnt.actor_lr=1e-3"])
    with pytest.raises(ConfigError, match=r"^override 'critic_lr': expected section.key \(sections: .*\); "
                                          r"did you mean 'agent.critic_lr'\?$"):
        load_config("td3_lstm", ["critic_lr=1e-3"])
    with pytest.raises(ConfigError, match=r"^override 'wind_sigma': .*; did you mean 'env.wind_sigma'\?$"):
        load_config("td3_lstm", ["wind_sigma=0.1"])
    with pytest.raises(ConfigError, match=r"^mine.yaml: unknown top-level key 'agnet'; valid keys: name, env, agent, "
                                          r"replay, train, levels; did you mean 'agent'\?$"):
        config_from_dict({"agnet": {}}, source="mine.yaml")


def test_several_unknown_keys_name_the_first_and_count_the_others():
    with pytest.raises(ConfigError, match=r"^unknown key 'agent.lr_actr' \(and 2 more: 'agent.lr_critc', "
                                          r"'agent.zzz'\); .*; did you mean 'agent.actor_lr'\?$"):
        config_from_dict({"agent": {"zzz": 1, "lr_actr": 1e-3, "lr_critc": 1e-3}})
    with pytest.raises(ConfigError, match=r"^unknown key 'agent.learning_rate'; valid keys: the fields of "
                                          r"AgentConfig in docrl_jax/\S+\.py$"):   # nothing near: no guess
        load_config("td3_lstm", ["agent.learning_rate=0.1"])


@pytest.mark.parametrize("argv, line", [
    (["--config", "td3_lsmt"], "did you mean 'td3_lstm'?"),
    (["--config", "td3_lstm", "--set", "agent.lr_actr=1e-3"], "did you mean 'agent.actor_lr'?"),
    (["--config", "td3_lstm", "--set", "env.lidar_fov=90"], "did you mean 'env.lidar_fov_deg'?"),
    (["--config", "td3_lstm", "--set", "agnt.actor_lr=1e-3"], "did you mean 'agent.actor_lr'?"),
])
def test_the_trainer_prints_one_line_and_exits_2(argv, line, capsys, tmp_path):
    from docrl_jax.train import cli
    assert cli.main([*argv, "--run-dir", str(tmp_path / "run")]) == 2
    out = capsys.readouterr()
    assert out.out.strip().splitlines() == [out.out.strip()] and out.out.strip().endswith(line), out
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("command, argv, line", [
    ("evaluate", ["--policy", "td3_lsmt"], "--policy 'td3_lsmt': unknown policy; valid choices: bba, td3_lstm, "
     "sac_lstm, sac_mlp, sac_mlp_generalist, sac_mlp_tanks (or --run RUN_DIR for a trained agent); did you mean "
     "'td3_lstm'?"),
    ("render", ["--policy", "sac_mpl"], "did you mean 'sac_mlp'?"),
    ("export", ["--policy", "sac_lsmt", "--out", "x"], "did you mean 'sac_lstm'?"),
    ("evaluate", ["--policy", "bba", "--env", "wnd=false"], "--env 'wnd': unknown env parameter; valid names: the "
     "fields of EnvParams in docrl_jax/envs/param_fields.py; did you mean 'wind'?"),
    ("robustness", ["--policy", "bba", "--tests", "tank", "--out", "x"], "--tests 'tank': unknown test 'tank'; "
     "valid tests: perturbations, random_trips, held_out_layouts, structured, tanks (comma-separated); did you "
     "mean 'tanks'?"),
    ("robustness", ["--policy", "bba", "--perturbations", "motor_lag,wind_gust", "--out", "x"],
     "unknown perturbation 'wind_gust'; valid perturbations: wind_gusts, "),
])
def test_every_name_a_user_types_names_the_nearest(command, argv, line, tmp_path):
    """Through the `docrl` command line, as a user meets it: one line, exit status 2, nothing written."""
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, "-m", "docrl_jax", command, *argv], capture_output=True, text=True,
                          cwd=tmp_path, env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(err) == 1 and line in err[0], proc.stderr
    if "unknown perturbation" in line:
        assert err[0].endswith("did you mean 'wind_gusts'?")
    assert not list(tmp_path.iterdir())
