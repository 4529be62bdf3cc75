"""The robustness benchmark: a tiny sweep through the command, its files and rows, the one-line errors,
and that a perturbation reaches the env (the host env's trials with a perturbed plant are, bit for bit,
those of an env built with the perturbation's overrides).

One command run per module (the BBA, scenario 1, 2 trials, 2 layouts, 40 steps); the library tests
reuse its compiled programs (the envs and the BBA are cached per settings in the process)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax.evaluate import robustness, robustness_cli, rollout
from docrl_jax.evaluate.protocol import NOMINAL_YAW

STEPS, TRIALS, LAYOUTS = 40, 2, 2
TRAINED = Path(__file__).resolve().parents[1] / "data" / "trained"
ARGV = ["--policy", "bba", "--scenarios", "1", "--trials", str(TRIALS), "--layouts", str(LAYOUTS),
        "--perturbations", "action_latency", "--quick", "--max-steps", str(STEPS),
        "--tests", "perturbations,random_trips,held_out_layouts"]   # structured, tanks: test_tank_trials.py
HOST = {"dr_action_latency": (0, 2)}   # the host env of ARGV's sweep: queues for the 2-step latency


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("robustness") / "bba"
    assert robustness_cli.main([*ARGV, "--out", str(out)]) == 0
    with open(out / "robustness.csv") as f:
        rows = list(csv.DictReader(f))
    return out, rows, json.loads((out / "robustness.json").read_text())


def test_sweep_writes_consistent_rows(sweep):
    out, rows, data = sweep
    for name in ("robustness.csv", "robustness.json", "robustness.md", "robustness.png"):
        assert (out / name).stat().st_size > 0, name
    # nominal + the strongest action latency (2 steps), random trips: scenario 1 x 2 directions; layouts: 2 directions
    keys = [(r["test"], r["perturbation"], r["magnitude"], r["scenario"], r["direction"]) for r in rows]
    assert keys == [("perturbations", p, m, "1", d) for p, m in (("nominal", ""), ("action_latency", "2 steps"))
                    for d in ("air_to_water", "water_to_air")] + [
        (t, "none", "", s, d) for t, s in (("random_trips", "1"), ("held_out_layouts", "0"))
        for d in ("air_to_water", "water_to_air")]
    for r in rows:
        counts = [int(r[k]) for k in ("successes", "collisions", "out_of_bounds", "timeouts", "diverged")]
        expected = LAYOUTS if r["test"] == "held_out_layouts" else TRIALS
        assert int(r["trials"]) == expected == sum(counts), r
        assert float(r["success_rate"]) == counts[0] / expected and r["method"] == "BBA"
    meta = data["meta"]
    assert meta["command"].startswith("python -m docrl_jax.robustness --policy bba")
    assert meta["versions"]["jax"] == jax.__version__ and meta["date"] and meta["trials"] == TRIALS
    assert meta["host_env_overrides"]["BBA"]["dr_action_latency"] == [0, 2] and meta["vehicles"] == {"BBA": {}}
    assert meta["perturbations"]["action_latency"]["magnitudes"] == {"2 steps": {"dr_action_latency": [2, 2]}}
    assert len(data["rows"]) == len(rows) and len(data["over_seeds"]) == len(rows)
    md = (out / "robustness.md").read_text()
    assert "| Action latency (`dr_action_latency`) | BBA | 2 steps: " in md and "| Held-out layouts" in md


def test_perturbation_reaches_the_env(sweep):
    """Same seeds, nominal vs a 2-step action latency: other paths (in the command's rows and in
    the trials); and the host's trials of a plant are those of the env built with its overrides."""
    _, rows, _ = sweep
    aw = {r["perturbation"]: r for r in rows if r["test"] == "perturbations" and r["direction"] == "air_to_water"}
    assert aw["nominal"]["path_length_all_mean"] != aw["action_latency"]["path_length_all_mean"]

    host = rollout.make_eval_env(1, STEPS, **HOST)
    from docrl_jax.evaluate.policies import policy_for
    policy, _ = policy_for(host)        # the command's BBA: its compiled rollout is reused
    start, goal = envs.eval_pair(1, "air_to_water")
    key = rollout.trial_key(0, 1, "air_to_water")
    args = (start, goal, key, TRIALS, STEPS, NOMINAL_YAW["air_to_water"])
    lagged = rollout.eval_params(1, STEPS, dr_action_latency=(2, 2))
    via_host = rollout.run_trials(host, policy, *args, plants_of=lagged)
    nominal = rollout.run_trials(host, policy, *args, plants_of=rollout.eval_params(1, STEPS))
    own = rollout.run_trials(rollout.make_eval_env(1, STEPS, dr_action_latency=(2, 2)), policy, *args)
    np.testing.assert_array_equal(via_host["positions"], own["positions"])
    np.testing.assert_array_equal(via_host["start_yaws"], own["start_yaws"])
    assert np.abs(via_host["positions"] - nominal["positions"]).max() > 0.05


def test_layout_trips_start_in_held_out_layouts_with_forced_media(sweep):
    params = rollout.eval_params(0, STEPS, **HOST)
    for direction, in_water in (("air_to_water", False), ("water_to_air", True)):
        sampler = rollout.make_eval_env(0, STEPS, **HOST, start_water_fraction=float(in_water),
                                        goal_water_fraction=float(not in_water))
        keys = robustness.trip_keys(0, "held_out_layouts", 0, direction, LAYOUTS)
        k_reset, _ = jax.vmap(rollout.split_trial_key, out_axes=1)(keys)
        states = rollout.reset_states(sampler, k_reset, robustness.held_out_layouts(params, LAYOUTS),
                                      rollout.plants_for(rollout.eval_params(0, STEPS), k_reset))
        np.testing.assert_array_equal(states.sim.layout.index, np.arange(LAYOUTS))
        assert (np.asarray(states.info["underwater"]) == in_water).all()
        assert ((np.asarray(states.info["goal"])[:, 2] < 0) == (not in_water)).all()
        np.testing.assert_array_equal(states.sim.plant.action_latency, 0)   # the nominal plant, not the host's
    # Trial i's key does not depend on how many trials run.
    np.testing.assert_array_equal(robustness.trip_keys(0, "random_trips", 2, "water_to_air", 5)[:3],
                                  robustness.trip_keys(0, "random_trips", 2, "water_to_air", 3))


def test_settings_and_host():
    settings = robustness.sweep_settings(["wind_gusts", "buoyancy"])
    assert [(s.perturbation, s.magnitude) for s in settings] == [
        ("nominal", ""), ("wind_gusts", "x1.5"), ("wind_gusts", "x2"), ("wind_gusts", "x3"), ("wind_gusts", "x4"),
        ("buoyancy", "x0"), ("buoyancy", "x4")]
    assert [s.magnitude for s in robustness.sweep_settings(["motor_lag", "buoyancy"], quick=True)] == ["", "x10", "x4"]
    every = robustness.sweep_settings(list(robustness.PERTURBATIONS))
    host = robustness.host_overrides({"sensor_noise_std": 0.0}, every)
    assert host["dr_action_latency"] == host["dr_obs_latency"] == (0, 2)
    assert host["dr_beam_dropout"] == (0.0, 0.2) and host["dr_hull_volume_scale"] == (0.0, 4.0)
    assert host["sensor_noise_std"] == 0.0
    for p in robustness.ENVELOPE:   # every magnitude is a valid env in every scenario
        for v in p.magnitudes:
            for scenario in (0, 1, 2, 3):
                rollout.eval_params(scenario, 500, **p.overrides(v))


@pytest.mark.parametrize("argv, message", [
    ([], "nothing to benchmark: give --run RUN_DIR"),
    (["--policy", "ppo"], "valid choices: bba"),
    (["--policy", "bba", "--perturbations", "gusts"], "unknown perturbation 'gusts'; valid perturbations: wind_gusts, "
                                                     "water_current"),
    (["--policy", "bba", "--tests", "sweeps,maze"], "unknown test 'sweeps'; valid tests: perturbations, random_trips, "
                                                   "held_out_layouts"),
    # names are exact: a test's name in the singular is no alias of it
    (["--policy", "bba", "--tests", "tank"], "unknown test 'tank'; valid tests: perturbations, random_trips, "
                                            "held_out_layouts, structured, tanks (comma-separated); did you mean "
                                            "'tanks'?"),
    (["--policy", "bba", "--scenarios", "0"], "valid scenarios are 1, 2, 3"),
    (["--policy", "bba", "--directions", "up"], "air_to_water (A-W), water_to_air (W-A)"),
    (["--policy", "bba", "--layouts", "0"], "--layouts 0: must be in 1..10000"),
    (["--policy", "bba", "--trials", "-1"], "--trials -1: must be a positive integer"),
    (["--policy", "bba", "--env", "dr_mass_scale=(0,1)"], "dr_mass_scale"),
    (["--policy", "bba", "--label", "a", "--label", "b"], "--label given 2 time(s) for 1 method(s)"),
    (["--policy", "bba", "--env", "start_water_fraction=1"], "--env start_water_fraction: set by the benchmark"),
    (["--run", "no/such/run"], "does not exist"),
    (["--run", str(TRAINED / "td3_lstm"), "--seed-index", "1"], "valid 0..0"),
    (["--run", str(TRAINED / "td3_lstm"), str(TRAINED / "sac_lstm")], "hold different configs"),
    (["--run", str(TRAINED / "td3_lstm"), "--run", str(TRAINED / "td3_lstm")], "give each method its own --label"),
    (["--policy", "bba"], "--out DIR"),
    (["--policy", "bba", "--out", "no/such/dir"], "--out no/such/dir: No such file or directory"),
])
def test_bad_input_is_one_line_before_compiling(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(robustness, "run_benchmark", lambda *a, **k: pytest.fail("ran despite a bad input"))
    out = [] if "--out" in argv or message == "--out DIR" else ["--out", "res"]
    with pytest.raises(SystemExit) as exit_:
        robustness_cli.main([*argv, *out])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and err[-1].startswith("python -m docrl_jax.robustness: error:"), err
    assert not list(tmp_path.iterdir())   # nothing written


def test_command_name_and_out_under_a_file(tmp_path):
    """The short command name runs the command: an --out whose parent is a file is one line, exit 2."""
    (tmp_path / "file").write_text("")
    proc = subprocess.run([sys.executable, "-m", "docrl_jax.robustness", "--policy", "bba", "--out",
                           str(tmp_path / "file" / "res")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1].endswith("/file/res: Not a directory"), proc.stderr
    listed = subprocess.run([sys.executable, "-m", "docrl_jax.robustness", "--list"], capture_output=True, text=True)
    assert listed.returncode == 0 and "wind_gusts" in listed.stdout and "dr_current_speed=(0.5, 0.5)" in listed.stdout


def test_methods_side_by_side_and_the_median_over_seeds(tmp_path):
    """Each --run is a method (its directories its seeds), then --policy; the table and figure show
    the median over seeds of the rate averaged over scenarios."""
    args = robustness_cli.build_parser().parse_args(
        ["--run", str(TRAINED / "td3_lstm"), str(TRAINED / "td3_lstm"), "--run", str(TRAINED / "sac_lstm"),
         "--policy", "bba", "--label", "D", "--label", "S", "--label", "B", "--out", str(tmp_path)])
    methods = robustness_cli.validate_args(args)["methods"]
    assert [(m.label, m.seed_indices) for m in methods] == [("D", [0, 1]), ("S", [0]), ("B", [None])]
    assert [s for _, s in methods[0].sources] == [0, 0]

    from docrl_jax.evaluate import robustness_report as report
    rows = []
    for seed, rates in ((0, (1.0, 0.5)), (1, (0.5, 0.5)), (2, (0.0, 0.0))):   # scenario means 0.75, 0.5, 0
        for scenario, rate in zip((1, 2), rates):
            for method, r in (("D", rate), ("B", 1.0)):
                rows.append({"method": method, "seed_index": seed if method == "D" else None, "test": "perturbations",
                             "perturbation": "wind_gusts", "magnitude": "x2", "value": 2.0,
                             "parameter": "dr_wind_scale", "scenario": scenario, "direction": "air_to_water",
                             "trials": 4, "successes": int(4 * r), "success_rate": r, "collisions": 4 - int(4 * r),
                             "out_of_bounds": 0, "timeouts": 0})
    assert report.cell_rates(rows)[("D", "perturbations", "wind_gusts", "x2", "air_to_water")] == 0.5
    per_scenario = report.cell_rates(rows, per_scenario=True)
    assert per_scenario[("D", "perturbations", "wind_gusts", "x2", "air_to_water", 1)] == 0.5
    agg = [a for a in report.over_seeds(rows) if a["method"] == "D" and a["scenario"] == 1][0]
    assert agg["successes_per_seed"] == [4, 2, 0] and agg["success_rate_median"] == 0.5 and agg["seeds"] == [0, 1, 2]
    md = report.markdown(rows, {"trials": 4, "layouts": 0}, robustness.PERTURBATIONS)
    assert "| Wind gusts (`dr_wind_scale`) | D (3 seeds) | x2: 50 |" in md and "| B | x2: 100 |" in md
    assert report.plot(rows, tmp_path / "r.png", robustness.PERTURBATIONS).stat().st_size > 0


def test_each_method_is_flown_in_its_runs_vehicle(tmp_path, monkeypatch):
    """A run trained with env.vel_i_rate is benchmarked with it (under every test, beside --env); the
    runs of one method must share their vehicle."""
    import shutil
    runs = {}
    for name, extra in (("plain", ""), ("rate", "  vel_i_rate: 0.3\n")):
        runs[name] = tmp_path / name
        shutil.copytree(TRAINED / "td3_lstm", runs[name])
        text = (runs[name] / "config.yaml").read_text()
        (runs[name] / "config.yaml").write_text(text.replace("env:\n", "env:\n" + extra, 1))
    args = robustness_cli.build_parser().parse_args(
        ["--run", str(runs["plain"]), "--run", str(runs["rate"]), "--label", "A", "--label", "B",
         "--perturbations", "mass", "--env", "wind=false", "--out", str(tmp_path / "o")])
    cfg = robustness_cli.validate_args(args)
    assert [m.vehicle for m in cfg["methods"]] == [{}, {"vel_i_rate": 0.3}]
    built = []

    class Built(Exception):
        pass

    def make_eval_env(scenario, max_steps, **kw):
        built.append(kw)
        raise Built
    monkeypatch.setattr(rollout, "make_eval_env", make_eval_env)
    with pytest.raises(Built):
        robustness.run_benchmark(cfg["methods"][1:], cfg)
    assert built[0]["vel_i_rate"] == 0.3 and built[0]["wind"] is False and built[0]["dr_mass_scale"] == (0.8, 1.2)
    args = robustness_cli.build_parser().parse_args(["--run", str(runs["plain"]), str(runs["rate"]), "--label", "AB",
                                                     "--out", str(tmp_path / "o")])
    with pytest.raises(robustness_cli.UsageError, match="fly different vehicles"):
        robustness_cli.validate_args(args)


def test_a_shipped_policy_is_a_method_in_its_own_vehicle(tmp_path, monkeypatch):
    """--policy takes the shipped policies as it takes bba: the method flies the shipped actor (not the
    BBA) in its config's vehicle; an unknown name is one line naming the valid ones."""
    from docrl_jax import pretrained
    args = robustness_cli.build_parser().parse_args(["--policy", "sac_mlp_generalist", "--out", str(tmp_path / "o")])
    (method,) = robustness_cli.validate_args(args)["methods"]
    assert (method.label, method.shipped, method.runs) == ("sac_mlp_generalist", "sac_mlp_generalist", None)
    assert method.vehicle == pretrained.vehicle("sac_mlp_generalist") and method.vehicle["vertical_beams"] is True
    loaded = []

    class Loaded(Exception):
        pass

    def load(name):
        loaded.append(name)
        raise Loaded
    monkeypatch.setattr(pretrained, "load", load)
    monkeypatch.setattr(rollout, "make_eval_env", lambda *a, **kw: None)
    with pytest.raises(Loaded):
        robustness.run_benchmark([method], robustness_cli.validate_args(args))
    assert loaded == ["sac_mlp_generalist"]
    bad = robustness_cli.build_parser().parse_args(["--policy", "td3_lstn", "--out", str(tmp_path / "o")])
    with pytest.raises(robustness_cli.UsageError, match=r"^--policy 'td3_lstn': unknown policy; valid choices: bba, "):
        robustness_cli.validate_args(bad)


def test_quick_tanks_test_samples_the_whole_set_and_says_so(tmp_path, monkeypatch):
    """--quick's 10 trips in a set of 35 tanks fly 10 tanks spread evenly over it, not its first 10."""
    from docrl_jax.evaluate import tank_sets
    names = [f"tank_{i:02d}" for i in range(35)]
    monkeypatch.setattr(tank_sets, "check", lambda spec, params, flag="--tank": list(names))   # no tank loaded
    args = robustness_cli.build_parser().parse_args(["--policy", "bba", "--quick", "--tests", "tanks",
                                                     "--out", str(tmp_path / "r")])
    cfg = robustness_cli.validate_args(args)
    assert cfg["tank_sample"] == [0, 4, 8, 11, 15, 19, 23, 26, 30, 34]
    assert robustness_cli.sample_line(cfg) == (
        "--quick: the tanks test flies 10 of the 35 tanks of gallery, spread evenly over the set: tank_00, tank_04, "
        "tank_08, tank_11, tank_15, tank_19, tank_23, tank_26, tank_30, tank_34")
    picked, stack = tank_sets.pick(names, {"index": np.arange(35)}, cfg["tank_sample"])
    assert picked == [names[i] for i in cfg["tank_sample"]] and stack["index"].tolist() == cfg["tank_sample"]
    # as many trips as tanks, or more: the whole set, as without --quick
    for argv in (["--quick", "--trials", "35"], ["--trials", "10"]):
        args = robustness_cli.build_parser().parse_args(["--policy", "bba", "--tests", "tanks", *argv,
                                                         "--out", str(tmp_path / "r")])
        cfg = robustness_cli.validate_args(args)
        assert "tank_sample" not in cfg and robustness_cli.sample_line(cfg) is None
    assert tank_sets.spread(3, 2).tolist() == [0, 2] and tank_sets.spread(4, 9).tolist() == [0, 1, 2, 3]
