"""Config loading and validation: errors come before any compile and name key, value and choices."""

from __future__ import annotations

import dataclasses

import jax
import pytest
import yaml

from docrl_jax import config as cfg
from docrl_jax.config import ConfigError, config_from_dict, load_config, observation_size, packaged_configs_dir, to_yaml

PACKAGED = ["td3_lstm", "sac_lstm", "ddpg_mlp", "sac_mlp"]
PAPER = [f"{n}_paper" for n in PACKAGED]


@pytest.mark.parametrize("name", PACKAGED + PAPER)
def test_packaged_configs_load_with_the_contract_keys(name):
    c = load_config(name)
    d = cfg.to_dict(c)
    for sec, key in [("env", "scenario"), ("env", "num_envs"), ("train", "total_env_steps"), ("train", "seed"),
                     ("train", "num_seeds"), ("train", "eval_every"), ("train", "checkpoint_every")]:
        assert key in d[sec]
    assert c.name == name and c.agent.gamma == 0.99 and c.env.scenario == 2
    if name.endswith("_paper"):  # the paper's optimiser and minibatch, one-step targets, the trained actor
        assert c.agent.actor_lr == c.agent.critic_lr == 1e-3 and c.replay.batch_size == 256
        assert c.agent.n_step == 1 and c.agent.policy_average_tau == 1.0 and not c.agent.critic_layer_norm
    elif name == "ddpg_mlp":  # the recipe learned nothing for DDPG: the measured Table I settings instead
        assert c.agent.actor_lr == c.agent.critic_lr == 1e-3 and c.replay.batch_size == 256
        assert c.agent.tau == 0.005 and c.replay.buffer_size == 524288 and c.agent.n_step == 1
        assert c.agent.policy_average_tau == 1.0 and not c.agent.critic_layer_norm
    else:  # the measured recipe (docs/BENCHMARKS.md): every departure is one of these keys
        assert c.agent.actor_lr == c.agent.critic_lr == 2e-3 and c.replay.batch_size == 1024
        assert c.agent.n_step == 5 and c.agent.policy_average_tau == 0.001 and c.agent.critic_layer_norm
        assert c.agent.lr_end_scale == 0.1 and c.agent.tau == 0.02
        # bf16 critics: measured for td3_lstm only (BENCHMARKS.md, "What an update costs")
        assert c.agent.critic_dtype == ("bfloat16" if name == "td3_lstm" and jax.default_backend() != "cpu"
                                        else "float32")
        # 8 updates per vectorised step over half the env steps: measured for td3_lstm only (BENCHMARKS.md,
        # "Learner lever 2"); the run's update count, hence its schedules, stays that of 4 over 50 M
        t = c.train
        assert (t.updates_per_step, t.total_env_steps) == ((8, 25_000_000) if name == "td3_lstm" else (4, 50_000_000))
        # the policy average's falling rate: measured for td3_lstm only (BENCHMARKS.md, "Why the defaults")
        assert c.agent.policy_average_tau_start == (0.01 if name == "td3_lstm" else 0.0)
        assert t.updates_per_step * t.total_env_steps == 200_000_000
        # training starts near the risers (the paper's W-A start is 1.05 m from one): measured for the LSTM agents
        # only; td3_lstm's 0.7 leaves room for its training margin of 0.15 m (BENCHMARKS.md, "Time to 90 % and
        # every seed"), the one config with a margin here
        env = dict(c.env.overrides)
        assert env.get("goal_clearance", 1.0) == {"td3_lstm": 0.7, "sac_lstm": 0.6}.get(name, 1.0)
        assert env.get("collision_margin", 0.0) == (0.15 if name == "td3_lstm" else 0.0)
        # the controller's integral outside its band (ROBUSTNESS.md): measured for the LSTM agents only
        assert env.get("vel_i_rate", 0.0) == (0.3 if name.endswith("_lstm") else 0.0)
    # Evaluations alongside training on a GPU for the 4,096-env defaults (BENCHMARKS.md); the paper
    # recipes keep their evaluations between chunks.
    assert c.train.eval_alongside == (not name.endswith("_paper") and jax.default_backend() != "cpu")


def test_generalist_trains_in_procedural_tanks_under_randomisation():
    g = load_config("td3_lstm_generalist")
    env = dict(g.env.overrides)
    assert g.env.scenario == 0 and g.train.eval_paper_pairs and g.train.eval_pair_scenario == 2
    # the envelope holds the benchmark's goal perturbations: 2x gusts, 0.25 m/s currents, motor lag x5,
    # one step of latency, 10 % dropouts
    assert env["dr_wind_scale"][1] >= 2 and env["dr_current_speed"][1] >= 0.25 and env["dr_motor_tau_scale"][1] >= 5
    assert env["dr_action_latency"][1] >= 1 and env["dr_obs_latency"][1] >= 1 and env["dr_beam_dropout"][1] >= 0.1
    # a randomised mass only with the integral that takes it up (docs/ROBUSTNESS.md)
    assert env["dr_mass_scale"] == (0.8, 1.2) and env["vel_i_rate"] == 0.3
    # the beams up and down, which the actor and critics see as two more observation floats
    assert env["vertical_beams"] and observation_size(load_config("td3_lstm")) == 26
    # a collision margin in training only (the pairs, in scenario 2, get their own env)
    assert env["collision_margin"] == 0.2 and env["goal_clearance"] == 0.8 and not g.train.eval_alongside
    # and a margin around the hull, for what the fan does not see; no evaluation runs with either
    assert env["hull_margin"] == 0.1 and {"collision_margin", "hull_margin"}.isdisjoint(cfg.evaluation_env_kwargs(g))
    # a collision costs what arriving earns (the paper: -10); the evaluations keep the run's reward
    assert env["reward_collide"] == -100.0 and cfg.evaluation_env_kwargs(g)["reward_collide"] == -100.0
    # two rings of 8 slanted beams (16 more floats), and the progress term that keeps every seed learning
    # with them (without it, 1 of 6 seeds waited out the clock)
    assert env["slant_beams"] == 8 and env["slant_elevation_deg"] == 30 and observation_size(g) == 44
    assert env["progress_reward_scale"] == 2.0 and cfg.evaluation_env_kwargs(g)["progress_reward_scale"] == 2.0
    for key, value in env.items():
        if key.startswith("dr_"):
            assert value[0] <= value[1], key
    # the default's learner (measured better for the generalist than 4 updates per step with fp32 critics)
    d = load_config("td3_lstm")
    # (but the policy average's falling rate, measured for the default only)
    assert dataclasses.replace(g.agent, policy_average_tau_start=0.01) == d.agent and g.replay == d.replay
    assert g.agent.policy_average_tau_start == 0.0
    assert g.train.updates_per_step == d.train.updates_per_step == 8


def test_sac_mlp_generalist_is_sac_mlps_learner_on_the_generalists_env():
    g, s, t = load_config("sac_mlp_generalist"), load_config("sac_mlp"), load_config("td3_lstm_generalist")
    assert g.name == "sac_mlp_generalist" and g.agent == s.agent and g.replay == s.replay
    assert g.env == t.env and observation_size(g) == 44
    # the in-training evaluation flies the paper's scenario-2 pairs with the nominal plant, paused
    assert g.train == dataclasses.replace(s.train, eval_pair_scenario=2, eval_alongside=False)


def test_a_config_extends_another_and_takes_whole_sections_by_name(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "env_only.yaml").write_text("env: {scenario: 3, num_envs: auto, wind: false}\n")
    (tmp_path / "sub" / "list.yaml").write_text("- td3_lstm\n")
    (tmp_path / "mine.yaml").write_text("name: mine\nextends: td3_lstm\nagent: {actor_lr: 1.0e-3}\n"
                                        "env: sub/env_only.yaml\n")
    mine, base = load_config(str(tmp_path / "mine.yaml")), load_config("td3_lstm")
    # keys replace the base's one by one; a section named by a config replaces the base's section whole
    assert mine.name == "mine" and mine.agent == dataclasses.replace(base.agent, actor_lr=1e-3)
    assert mine.replay == base.replay and mine.train == base.train
    # not td3_lstm's env with two keys changed: its goal_clearance and vel_i_rate are gone
    assert mine.env.scenario == 3 and dict(mine.env.overrides) == {"wind": False}
    # what is written in the run directory is the composed config, which loads without its bases
    (tmp_path / "saved.yaml").write_text(to_yaml(mine))
    assert load_config(str(tmp_path / "saved.yaml")) == mine
    (tmp_path / "a.yaml").write_text("extends: b.yaml\n")
    (tmp_path / "b.yaml").write_text("extends: ./a.yaml\n")
    with pytest.raises(ConfigError, match="cycle.*a.yaml -> .*b.yaml -> .*a.yaml"):
        load_config(str(tmp_path / "a.yaml"))
    for text, match in [("extends: td4_lstm\n", r"'td4_lstm' is neither a file nor a packaged config; packaged configs: ddpg_mlp, "),
                        ("extends: [td3_lstm]\n", r"'extends' must name a config .* got \['td3_lstm'\]"),
                        ("agent: sub/env_only.yaml\n", r"'sub/env_only.yaml' names a config without a 'agent' section"),
                        ("extends: sub/missing.yaml\n", "does not exist"),
                        ("extends: sub/list.yaml\n", r"'sub/list.yaml' is not a config \(its top level is not a mapping\)")]:
        (tmp_path / "bad.yaml").write_text(text)
        with pytest.raises(ConfigError, match=match):
            load_config(str(tmp_path / "bad.yaml"))


def test_eval_alongside_auto_is_on_where_possible_and_true_where_impossible_is_refused():
    notes = []
    raw = yaml.safe_load((packaged_configs_dir() / "td3_lstm.yaml").read_text())
    assert config_from_dict(raw, backend="gpu", notes=notes).train.eval_alongside
    assert "train.eval_alongside auto -> true" in notes
    assert not config_from_dict(raw, backend="cpu").train.eval_alongside   # every lane costs its share there
    # Where the pairs need an env of their own (procedural tanks, domain randomisation) or a second policy is
    # evaluated on the same episodes, auto says why it is off, and true is an error naming the fix.
    notes = []
    generalist = yaml.safe_load((packaged_configs_dir() / "td3_lstm_generalist.yaml").read_text())
    assert not config_from_dict(generalist, backend="gpu", notes=notes).train.eval_alongside
    assert any(n.startswith("train.eval_alongside auto -> false (the paper pairs run in scenario 2") for n in notes)
    for sets in (["train.eval_alongside=true", "env.scenario=0"], ["train.eval_alongside=true", "env.dr_wind_scale=[1.0, 2.0]"],
                 ["train.eval_alongside=true", "train.eval_trained_actor=true"]):
        with pytest.raises(ConfigError, match="train.eval_alongside.*not possible here.*set it false"):
            load_config("td3_lstm", sets)
    # Pairs of the training env's own scenario and plant, or no pairs: possible.
    assert load_config("td3_lstm", ["train.eval_alongside=true", "env.scenario=3"]).train.eval_alongside
    assert load_config("td3_lstm", ["train.eval_alongside=true", "env.scenario=0",
                                    "train.eval_paper_pairs=false"]).train.eval_alongside
    # The training-only margins (td3_lstm's collision margin): every evaluation runs without them, the lanes
    # too (they clear them in their episodes' states), so neither the pairs nor the lanes need another env.
    margin = load_config("td3_lstm", ["env.collision_margin=0.2", "env.goal_clearance=0.8"])
    assert not cfg.pairs_own_env(margin) and "collision_margin" not in cfg.nominal_env_kwargs(margin)
    assert cfg.evaluation_env_kwargs(margin) == {k: v for k, v in cfg.env_kwargs(margin).items() if k != "collision_margin"}
    hull = load_config("td3_lstm", ["env.hull_margin=0.2", "train.eval_alongside=auto"])
    assert "hull_margin" in cfg.env_kwargs(hull) and "hull_margin" not in cfg.evaluation_env_kwargs(hull)
    assert cfg.alongside_blocker(hull) is None and cfg.alongside_blocker(margin) is None
    assert cfg.env_kwargs(config_from_dict(raw, backend="gpu"))["collision_margin"] > 0   # the default's lanes
    with pytest.raises(ConfigError, match="eval_alongside='maybe': must be a bool .* or 'auto'"):
        load_config("td3_lstm", ["train.eval_alongside=maybe"])


def test_auto_sizes_resolve_per_backend_and_say_so():
    notes = []
    raw = yaml.safe_load((packaged_configs_dir() / "td3_lstm.yaml").read_text())
    gpu = config_from_dict(raw, backend="gpu", notes=notes)
    assert gpu.env.num_envs == cfg.AUTO_NUM_ENVS["gpu"] == 4096
    assert gpu.replay.buffer_size == 4096 * cfg.AUTO_STEPS_PER_ENV["gpu"]
    assert gpu.train.log_every == 4096 * 100 == 409_600  # the chunk every GPU measurement used
    assert any("num_envs auto -> 4,096" in n for n in notes) and any("buffer_size auto" in n for n in notes)
    assert any("log_every auto -> 409,600" in n for n in notes)
    cpu = config_from_dict(raw, backend="cpu")
    assert cpu.env.num_envs == 64 and cpu.replay.buffer_size == 64 * cfg.AUTO_STEPS_PER_ENV["cpu"]
    assert cpu.train.log_every == 64 * cfg.AUTO_ITERS_PER_CHUNK["cpu"]  # a progress line within a minute
    # bf16 critics where they were measured faster (an H100), float32 where bf16 is emulated (a CPU)
    assert (gpu.agent.critic_dtype, cpu.agent.critic_dtype) == ("bfloat16", "float32")
    assert any("critic_dtype auto -> bfloat16" in n for n in notes)
    with pytest.raises(ConfigError, match="critic_dtype.*bfloat16"):
        load_config("td3_lstm", ["agent.critic_dtype=float16"])
    # An explicit size wins over auto, and a bad word names the choices.
    assert load_config("td3_lstm", ["env.num_envs=32"]).env.num_envs == 32
    with pytest.raises(ConfigError, match="num_envs"):
        load_config("td3_lstm", ["env.num_envs=automatic"])


def test_paper_and_original_sizes():
    td3, sac, ddpg, sac_mlp = (load_config(n) for n in PACKAGED)
    assert td3.agent.actor_hidden == (32,) and td3.agent.critic_hidden == (512, 512)
    assert sac.agent.critic_hidden == (256, 256) and sac.agent.algo == "sac"
    assert ddpg.agent.actor_hidden == (512, 512) and ddpg.agent.algo == "ddpg"
    assert sac_mlp.agent.actor_hidden == (256, 256) and sac_mlp.agent.actor == "mlp"


def test_bare_name_and_path_resolve_to_the_same_config(tmp_path):
    path = packaged_configs_dir() / "td3_lstm.yaml"
    assert load_config("td3_lstm") == load_config("td3_lstm.yaml") == load_config(str(path))
    copy = tmp_path / "mine.yaml"
    copy.write_text(path.read_text())
    assert load_config(str(copy)) == load_config("td3_lstm")
    with pytest.raises(ConfigError, match="does not exist"):
        load_config(str(tmp_path / "missing.yaml"))
    with pytest.raises(ConfigError, match=r"packaged configs: ddpg_mlp, ddpg_mlp_paper, sac_lstm, .*sac_mlp_generalist, "
                                          r".*td3_lstm, td3_lstm_generalist, td3_lstm_paper, td3_lstm_tanks; did you "
                                          r"mean 'td3_lstm'\?$"):
        load_config("td4_lstm")


def test_unknown_keys_say_where_the_valid_ones_are():  # and the nearest of them: tests/test_did_you_mean.py
    with pytest.raises(ConfigError, match=r"unknown key 'env.windy'; valid keys: env.scenario, env.num_envs and "
                                          r"the fields of EnvParams"):
        load_config("td3_lstm", ["env.windy=false"])
    with pytest.raises(ConfigError, match="valid keys: name, env, agent, replay, train, levels"):
        config_from_dict({"trainer": {}})
    with pytest.raises(ConfigError, match="expected section.key"):
        load_config("td3_lstm", ["lr=0.1"])


@pytest.mark.parametrize("override, message", [
    ("agent.actor_lr=fast", r"agent.actor_lr='fast': must be a number"),
    ("env.num_envs=2.5", r"env.num_envs=2.5: must be an integer"),
    ("agent.memory=maybe", r"agent.memory=.maybe.: must be a bool"),
    ("agent.critic_hidden=[256, -1]", r"non-empty list of positive integers"),
    ("env.wind=3", r"wind=3: must be a bool"),
])
def test_wrong_types_are_rejected(override, message):
    with pytest.raises(ConfigError, match=message):
        load_config("td3_lstm", [override])


@pytest.mark.parametrize("overrides, message", [
    (["agent.algo=ppo"], r"valid choices are \['td3', 'sac', 'ddpg'\]"),
    (["env.scenario=4"], r"valid choices are \[0, 1, 2, 3\]"),
    (["replay.burn_in=16"], r"must be < replay.seq_len=16"),
    (["agent.gamma=1.0"], r"must be in \[0, 1\)"),
    (["agent.actor=mlp", "agent.actor_hidden=[64]"], r"burn_in=8: an mlp actor has no carry to warm up: set burn_in 0"),
    (["agent.memory=false"], r"memoryless LSTM\) has no carry to warm up"),
    (["env.num_envs=4096", "replay.buffer_size=50000"], r"buffer_size >= 69632"),
    (["agent.algo=ddpg", "agent.policy_freq=1"], r"ddpg has no target-policy smoothing"),
    (["env.max_goal_distance=0.5"], r"must exceed min_goal_distance"),
    (["train.num_seeds=0"], r"train.num_seeds=0: must be >= 1"),
])
def test_impossible_values_name_the_problem(overrides, message):
    with pytest.raises(ConfigError, match=message):
        load_config("td3_lstm", overrides)


def test_overrides_are_yaml_scalars():
    c = load_config("td3_lstm", ["agent.actor_lr=3e-4", "env.z_bounds=[-1.0, 4.5]", "env.wind=false",
                                 "agent.memory=false", "replay.seq_len=1", "replay.burn_in=0", "agent.n_step=1"])
    assert c.agent.actor_lr == pytest.approx(3e-4) and isinstance(c.agent.actor_lr, float)
    assert cfg.env_kwargs(c)["z_bounds"] == [-1.0, 4.5] and cfg.env_kwargs(c)["wind"] is False
    assert hash(c) == hash(load_config("td3_lstm", ["agent.actor_lr=0.0003", "env.z_bounds=[-1.0, 4.5]",
                                                    "env.wind=false", "agent.memory=false", "replay.seq_len=1",
                                                    "replay.burn_in=0", "agent.n_step=1"]))


def test_resolved_yaml_round_trips():
    c = load_config("sac_lstm", ["env.max_goal_distance=2.0", "train.num_seeds=3"])
    assert config_from_dict(yaml.safe_load(to_yaml(c))) == c


def test_recurrent_is_an_lstm_actor_with_memory():
    assert load_config("td3_lstm").agent.recurrent
    assert not load_config("td3_lstm", ["agent.memory=false", "replay.burn_in=0"]).agent.recurrent
    assert not load_config("sac_mlp").agent.recurrent
    assert not cfg.AgentConfig(actor="mlp", memory=True).recurrent
