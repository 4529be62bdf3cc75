"""The evaluator on scripted policies with known outcomes, its metrics, outputs and CLI errors.

One env and one compiled rollout per module (the scripted oracle and the diver share it)."""

from __future__ import annotations

import csv
import dataclasses
import json

import jax
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax import evaluate
from docrl_jax.evaluate import cli, curves, paper_results, plotting, rollout, run_dirs
from docrl_jax.baselines.scripted import straight_line
from docrl_jax.errors import RunDirError

from _evaluator_world import LOW_FLOOR, MAX_STEPS, N


@pytest.fixture(scope="module")
def env():
    # Scenario 1 (empty tank). The vertical bound is lowered below the floor (top -1.3) so a dive
    # ends on the floor (a collision) rather than at the -1.1 bound.
    return evaluate.make_eval_env(1, MAX_STEPS, z_bounds=LOW_FLOOR)


@pytest.fixture(scope="module")
def oracle_trials(env):
    start, goal = envs.eval_pair(1, "air_to_water")
    return evaluate.run_trials(env, straight_line(), start, goal, jax.random.PRNGKey(0), N, MAX_STEPS)


@pytest.fixture(scope="module")
def dive_trials(env):
    start, goal = envs.eval_pair(1, "air_to_water")
    return evaluate.run_trials(env, straight_line(dive=True), start, goal, jax.random.PRNGKey(1), N, MAX_STEPS)


def test_oracle_always_arrives_in_empty_tank(oracle_trials):
    assert oracle_trials["success"].all(), evaluate.summarize(oracle_trials)
    assert (oracle_trials["final_distance"] < 0.5).all()
    s = evaluate.summarize(oracle_trials)
    assert s["successes"] == N and s["collisions"] == s["timeouts"] == s["out_of_bounds"] == 0
    # Straight line (0,0,2.5) -> (2,3,-1) is 4.9 m; the path is barely longer.
    assert 4.0 < s["path_length_mean"] < 6.5
    # It starts in air and ends in water: both times positive.
    assert s["t_air_mean"] > 0 and s["t_water_mean"] > 0


def test_dive_always_collides_with_floor(dive_trials):
    assert dive_trials["collision"].all(), evaluate.summarize(dive_trials)
    assert not dive_trials["success"].any()
    final_z = dive_trials["positions"][np.arange(N), dive_trials["steps"], 2]
    assert (final_z < -1.1).all() and (final_z > -1.4).all()


@pytest.mark.parametrize("which", ["oracle", "dive"])
def test_t_air_plus_t_water_is_trial_time(which, oracle_trials, dive_trials, env):
    t = oracle_trials if which == "oracle" else dive_trials
    np.testing.assert_allclose(t["t_air"] + t["t_water"], t["steps"] * env.control_dt, atol=1e-6)
    np.testing.assert_allclose(t["time"], t["steps"] * env.control_dt, atol=1e-6)
    assert (t["steps"] >= 1).all() and (t["steps"] <= MAX_STEPS).all()
    # Records are frozen after the end: the last recorded pose repeats the terminal one.
    i = int(np.argmin(t["steps"]))
    np.testing.assert_allclose(t["positions"][i, t["steps"][i]:], t["positions"][i, -1][None].repeat(
        MAX_STEPS + 1 - t["steps"][i], 0))


def test_trials_differ_by_seed_and_starts_are_jittered(oracle_trials):
    sp = oracle_trials["start_positions"]
    assert np.abs(sp[:, :2]).max() <= 0.1 + 1e-6 and np.ptp(sp[:, 0]) > 0
    assert np.abs(oracle_trials["start_yaws"]).max() <= 0.1 + 1e-6
    assert len(set(np.round(oracle_trials["path_length"], 4))) > 1


def test_rollout_and_env_are_cached(env):
    p1, p2 = straight_line(), straight_line(dive=True)
    assert evaluate.make_rollout(env, p1, MAX_STEPS) is evaluate.make_rollout(env, p2, MAX_STEPS)
    assert evaluate.make_eval_env(1, MAX_STEPS, z_bounds=list(LOW_FLOOR)) is env


def test_metrics_on_synthetic_records():
    # Outcome, time split and path length from hand-made records (no compile): trial 0 runs out of
    # steps, trial 1 arrives after 2 steps.
    T = 4
    out = {"taken": np.array([[1, 1, 1, 1], [1, 1, 0, 0]], bool),
           "underwater_before": np.array([[0, 0, 1, 1], [1, 1, 1, 1]], bool),
           "positions": np.cumsum(np.ones((2, T + 1, 3)), axis=1),
           "rewards": np.zeros((2, T)), "arrived": np.array([False, True]), "collision": np.array([False, False]),
           "out_of_bounds": np.array([False, False]), "terminated": np.array([False, False]),
           "final_distance": np.array([3.0, 0.1])}
    out["positions"][1, 3:] = out["positions"][1, 2]
    m = evaluate.trial_metrics(out, 0.2, np.zeros((2, 3)), np.zeros(2))
    assert list(m["outcome"]) == [evaluate.OUTCOMES.index("timeout"), evaluate.OUTCOMES.index("success")]
    np.testing.assert_allclose(m["t_air"], [0.4, 0.0])
    np.testing.assert_allclose(m["t_water"], [0.4, 0.4])
    np.testing.assert_allclose(m["path_length"], [4 * np.sqrt(3), 2 * np.sqrt(3)])
    s = evaluate.summarize(m)
    assert s["successes"] == 1 and s["timeouts"] == 1 and s["t_water_mean"] == pytest.approx(0.4)


def test_env_must_terminate_on_arrival():
    env = envs.make(scenario=1)
    with pytest.raises(ValueError, match="terminate_on_arrival"):
        evaluate.run_trials(env, straight_line(), (0, 0, 2.5), (2, 3, -1), jax.random.PRNGKey(0), 2)


# ------------------------------------------------------------------ outputs

def test_outputs_table_csv_json(tmp_path, oracle_trials):
    row = {"method": "oracle", "scenario": 2, "direction": "air_to_water", **evaluate.summarize(oracle_trials),
           "compile_s": 1.0, "run_s": None}
    trial_rows = evaluate.trial_table("oracle", 2, "air_to_water", oracle_trials)
    evaluate.write_outputs(tmp_path, [row], trial_rows, {"x": 1})
    md = (tmp_path / "results.md").read_text()
    assert "| Test | t_air (s) | t_water (s) | Success |" in md
    assert "A-W oracle" in md and f"{N}/{N}" in md
    assert "A-W DoCRL-D (paper) | 14.55 ± 0.87 | 11.19 ± 2.86 | 100/100" in md
    rows = list(csv.DictReader(open(tmp_path / "results.csv")))
    assert rows[0]["successes"] == str(N)
    trials = list(csv.DictReader(open(tmp_path / "trials.csv")))
    assert len(trials) == N and all(t["outcome"] == "success" for t in trials)
    js = json.loads((tmp_path / "results.json").read_text())
    assert js["results"][0]["successes"] == N and len(js["trials"]) == N


def test_trajectory_figure(tmp_path, env, oracle_trials):
    start, goal = envs.eval_pair(1, "air_to_water")
    path = plotting.plot_trajectories(env.mj_model, oracle_trials["positions"], oracle_trials["steps"],
                                      oracle_trials["outcome"], start, goal, tmp_path / "t.png", title="oracle")
    assert path.stat().st_size > 10_000


def test_scene_solids_scenario_3():
    import mujoco
    from docrl_jax.envs.huauv import scene_path
    s = plotting.scene_solids(mujoco.MjModel.from_xml_path(scene_path(3)))
    assert s["tank"] == pytest.approx(4.9) and s["floor_top"] == pytest.approx(-2.0)
    assert len(s["boxes"]) + len(s["capsules"]) == 15


def test_paper_table():
    assert len(paper_results.TABLE_I) == 10
    assert paper_results.lookup("BBA", "water_to_air")["success"] == 32
    assert paper_results.lookup("DoCRL-D", "air_to_water")["t_air"] == (14.55, 0.87)
    with pytest.raises(KeyError, match="methods"):
        paper_results.lookup("PPO", "air_to_water")


# ------------------------------------------------------------------ learning curves

def _write_metrics(path, seeds, n=20, offset=0.0):
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["env_steps", "wall_time_s", "seed", "success_rate", "episode_return", "extra"])
        for s in seeds:
            for i in range(n):
                w.writerow([i * 1000 + s * 7, i * 2.0 + s, s, min(1.0, i / n + offset), 10 * i + s, ""])


def test_learning_curves(tmp_path):
    a, b = tmp_path / "docrl_d" / "metrics.csv", tmp_path / "docrl_s" / "metrics.csv"
    _write_metrics(a, [0, 1, 2])
    _write_metrics(b, [0, 1], offset=0.2)
    (out,) = curves.plot_learning_curves([a, b], tmp_path / "figs")
    assert out.exists() and out.stat().st_size > 10_000
    seeds = curves.read_metrics(a)
    assert sorted(seeds) == [0, 1, 2]
    grid, mean, std, n = curves.aggregate_curves([(s["env_steps"], s["episode_return"]) for s in seeds.values()])
    assert n == 3 and grid[0] == pytest.approx(14) and grid[-1] == pytest.approx(19000)
    assert np.all(std >= 0) and mean[-1] == pytest.approx(np.mean([190 + s for s in range(3)]), abs=0.5)


def test_learning_curves_paper_pair_rows(tmp_path):
    """A metrics.csv with the trainer's paper-pair columns gets two more rows (A-W, W-A success)."""
    import matplotlib.image as mpimg
    plain = tmp_path / "plain" / "metrics.csv"
    _write_metrics(plain, [0])
    pairs = tmp_path / "pairs" / "metrics.csv"
    pairs.parent.mkdir()
    with open(pairs, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["env_steps", "wall_time_s", "seed", "success_rate", "episode_return",
                    "success_air_to_water", "success_water_to_air"])
        for i in range(20):
            w.writerow([i * 1000, i * 2.0, 0, i / 20, 10 * i, i / 20, 1 - i / 20])
    (a,) = curves.plot_learning_curves([plain], tmp_path / "a")
    (b,) = curves.plot_learning_curves([pairs], tmp_path / "b")
    assert mpimg.imread(b).shape[0] == pytest.approx(2 * mpimg.imread(a).shape[0], rel=0.02)


def test_learning_curves_missing_column(tmp_path):
    p = tmp_path / "metrics.csv"
    p.write_text("env_steps,seed\n1,0\n")
    with pytest.raises(ValueError, match="success_rate"):
        curves.read_metrics(p)


# ------------------------------------------------------------------ run dirs and the CLI

def test_check_run_dir(tmp_path):
    with pytest.raises(RunDirError, match="does not exist"):
        run_dirs.check_run_dir(tmp_path / "nope")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "metrics.csv").write_text("x\n")
    with pytest.raises(RunDirError, match="no config.yaml"):
        run_dirs.check_run_dir(tmp_path / "run")
    (tmp_path / "file").write_text("")
    with pytest.raises(RunDirError, match="not a directory"):
        run_dirs.check_run_dir(tmp_path / "file")
    (tmp_path / "run" / "config.yaml").write_text("a: 1\n")
    assert run_dirs.check_run_dir(tmp_path / "run") == tmp_path / "run"


@pytest.fixture
def no_compile(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("compiled before the arguments were checked")
    monkeypatch.setattr(rollout, "make_rollout", boom)
    monkeypatch.setattr(rollout, "make_eval_env", boom)


@pytest.mark.parametrize("argv, message", [
    (["--policy", "ppo"], "valid choices: bba"),
    (["--policy", "bba", "--scenarios", "1,4"], "valid scenarios are 1, 2, 3"),
    (["--policy", "bba", "--scenarios", "one"], "valid scenarios are 1, 2, 3"),
    (["--policy", "bba", "--trials", "0"], "--trials 0: must be a positive integer"),
    (["--policy", "bba", "--trials", "-3"], "must be a positive integer"),
    (["--policy", "bba", "--max-steps", "0"], "must be a positive integer"),
    (["--policy", "bba", "--directions", "up"], "valid directions are air_to_water"),
    (["--policy", "bba", "--env", "windy=1"], "unknown env parameter; valid names:"),
    (["--policy", "bba", "--env", "wind"], "expected KEY=VALUE"),
    (["--policy", "bba", "--env", "hull_volume=abc"], "--env hull_volume=abc: must be a finite number"),
    (["--policy", "bba", "--env", "water_current=(0.1,0)"], "--env water_current=(0.1,0): must be a sequence of 3"),
    (["--policy", "bba", "--env", "sensor_noise_std=-1e-3"], "--env sensor_noise_std=-1e-3: must be >= 0"),
    (["--policy", "bba", "--bba-depth-phase", "never"], "valid choices are after, first"),
    ([], "nothing to do"),
    (["--run", "/nonexistent/run_dir"], "does not exist"),
    (["--curves", "/nonexistent/run_dir"], "no metrics.csv"),
])
def test_cli_errors(argv, message, capsys, no_compile, tmp_path):
    with pytest.raises(SystemExit) as e:
        cli.main([*argv, "--out", str(tmp_path / "o")])
    assert e.value.code == 2
    assert message in capsys.readouterr().err


def test_env_overrides_take_what_a_user_types():
    """YAML 1.1 reads 4e-5 as a string and (0.1,0,0) as text: --env takes both as numbers."""
    assert cli.parse_env_overrides(["hull_volume=4e-5", "sensor_noise_std=1e3", "water_current=(0.1,0,0)",
                                    "z_bounds=[-3, 4.8]", "wind=false", "arrival_distance=.5"]) == {
        "hull_volume": 4e-5, "sensor_noise_std": 1000.0, "water_current": (0.1, 0, 0), "z_bounds": (-3, 4.8),
        "wind": False, "arrival_distance": 0.5}
    assert cli.parse_env_overrides(["water_current= ( 0.1, 0 ,-2e-2 ) "]) == {"water_current": (0.1, 0, -0.02)}


def test_cli_bad_env_value_is_one_line(capsys, no_compile, tmp_path):
    with pytest.raises(SystemExit) as e:
        cli.main(["--policy", "bba", "--env", "water_current=(0.1,0,0,0)", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "Traceback" not in err and err.strip().splitlines()[-1].startswith(
        "python -m docrl_jax.evaluate: error: --env water_current=(0.1,0,0,0)")
    assert not (tmp_path / "o").exists()


def test_cli_curves_need_out(tmp_path, capsys, no_compile, monkeypatch):
    _write_metrics(tmp_path / "runA" / "metrics.csv", [0])
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        cli.main(["--curves", "runA"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "--curves writes learning_curves.png: give --out DIR" in err
    assert sorted(x.name for x in tmp_path.iterdir()) == ["runA"]


def test_cli_policy_without_out_writes_nothing(tmp_path, capsys, monkeypatch):
    """BBA, 2 trials of 5 steps: the tables are printed and no folder appears in the current directory."""
    monkeypatch.chdir(tmp_path)
    assert cli.main(["--policy", "bba", "--trials", "2", "--max-steps", "5", "--scenarios", "1",
                     "--directions", "a-w"]) == 0
    out = capsys.readouterr().out
    assert "| A-W BBA | " in out and "nothing written" in out
    assert list(tmp_path.iterdir()) == []


def test_cli_run_dir_without_config(tmp_path, capsys, no_compile):
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.csv").write_text("env_steps\n")
    with pytest.raises(SystemExit) as e:
        cli.main(["--run", str(run), "--out", str(tmp_path / "o")])
    assert e.value.code == 2 and "no config.yaml" in capsys.readouterr().err


def test_cli_run_and_policy_are_exclusive(capsys, no_compile):
    with pytest.raises(SystemExit):
        cli.main(["--run", "x", "--policy", "bba"])
    assert "not allowed with" in capsys.readouterr().err


def test_cli_curves_only(tmp_path, no_compile):
    _write_metrics(tmp_path / "runA" / "metrics.csv", [0, 1])
    assert cli.main(["--curves", str(tmp_path / "runA"), "--out", str(tmp_path / "o")]) == 0
    assert (tmp_path / "o" / "learning_curves.png").exists()


# ------------------------------------------------------------------ --run through a stand-in trainer

@pytest.fixture
def fake_trainer(monkeypatch, tmp_path):
    """A stand-in `docrl_jax.runs.load_policy` that returns the scripted oracle for seeds 0-1, as a run that kept
    best policies gives them (which=None: the best)."""
    oracle = straight_line()

    def load_policy(run_dir, seed_index=0, which=None):
        run_dirs.check_run_dir(run_dir)
        if seed_index > 1:
            raise RunDirError(f"run directory {run_dir!r} has seeds 0, 1; no seed index {seed_index}")
        which = which or "best"
        return dataclasses.replace(oracle, source=f"{which} policy of seed index {seed_index}", which=which)
    monkeypatch.setattr("docrl_jax.runs.load_policy", load_policy)
    run = tmp_path / "oracle_run"
    run.mkdir()
    (run / "config.yaml").write_text("algo: oracle\n")
    return run


def test_cli_run_over_seeds(fake_trainer, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["--run", str(fake_trainer), "--which", "final", "--seed-index", "0,1", "--trials", str(N),
                          "--scenarios", "1",
                          "--directions", "a-w", "--max-steps", str(MAX_STEPS), "--figures", "2",
                          "--env", f"z_bounds=[{LOW_FLOOR[0]}, {LOW_FLOOR[1]}]",  # the module's env and N: no new compile
                          "--out", str(out)]) == 0
    md = (out / "results.md").read_text()
    assert "## Over seeds" in md and "| A-W oracle_run | " in md and f"{N:.1f} ± 0.0/{N} [{N}, {N}]" in md
    js = json.loads((out / "results.json").read_text())
    assert [r["seed_index"] for r in js["results"]] == [0, 1] and js["over_seeds"][0]["successes_mean"] == N
    assert len(js["trials"]) == 2 * N and js["meta"]["seed_indices"] == [0, 1]
    assert js["meta"]["which"] == {"0": "final", "1": "final"}   # asked for explicitly: no " (best)" in the label
    assert js["meta"]["policy_sources"] == {"0": "final policy of seed index 0", "1": "final policy of seed index 1"}
    printed = capsys.readouterr().out
    assert "oracle_run: final policy of seed index 1" in printed
    assert (out / "trajectory_s1_air_to_water_seed0.png").exists()
    assert (out / "trajectories_s1_air_to_water_seed1.npz").exists()
    # the closing line names every file written, the trajectories and figures too
    closing = printed.strip().splitlines()[-1]
    assert closing.startswith(f"wrote {out}/: results.md, results.csv, results.json, trials.csv, "), closing
    listed = closing.split(": ", 1)[1].rsplit(" (", 1)[0].split(", ")
    assert sorted(listed) == sorted(p.name for p in out.iterdir()), closing


def test_cli_run_writes_into_the_run_by_default(fake_trainer, tmp_path, monkeypatch):
    """Without --out an evaluation of --run goes to <first run dir>/evaluation, not the current directory."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    assert cli.main(["--run", str(fake_trainer), "--seed-index", "0", "--trials", str(N), "--scenarios", "1",
                     "--directions", "a-w", "--max-steps", str(MAX_STEPS), "--figures", "0",
                     "--env", f"z_bounds=[{LOW_FLOOR[0]}, {LOW_FLOOR[1]}]"]) == 0
    assert (fake_trainer / "evaluation" / "results.json").exists() and list(cwd.iterdir()) == []


def test_cli_run_bad_seed_index(fake_trainer, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--run", str(fake_trainer), "--seed-index", "7", "--scenarios", "1", "--out", str(tmp_path)])
    assert e.value.code == 2 and "no seed index 7" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        cli.main(["--run", str(fake_trainer), "--seed-index", "-1", "--out", str(tmp_path)])
    assert e.value.code == 2 and "expected 'all' or integers >= 0" in capsys.readouterr().err


def test_figure3_and_plotting_cli(tmp_path, oracle_trials, dive_trials):
    start, goal = envs.eval_pair(1, "air_to_water")
    for name, t in (("oracle", oracle_trials), ("dive", dive_trials)):
        d = tmp_path / name
        d.mkdir()
        (d / "results.json").write_text(json.dumps({"results": [{"method": name}]}))
        for direction in evaluate.DIRECTIONS:  # the same trials stand in for both directions
            np.savez(d / f"trajectories_s1_{direction}.npz", positions=t["positions"], steps=t["steps"],
                     outcome=t["outcome"], start=np.asarray(start), goal=np.asarray(goal))
    out = plotting.plot_figure3([tmp_path / "oracle", tmp_path / "dive"], 1, tmp_path / "fig3.png")
    assert out.stat().st_size > 20_000
    # a seed of a multi-seed evaluation beside a seedless one (a baseline); a missing seed is an error
    for direction in evaluate.DIRECTIONS:
        (tmp_path / "oracle" / f"trajectories_s1_{direction}.npz").rename(
            tmp_path / "oracle" / f"trajectories_s1_{direction}_seed1.npz")
    assert plotting.main(["figure3", str(tmp_path / "oracle"), str(tmp_path / "dive"), "--scenario", "1",
                          "--seed-index", "1", "--out", str(tmp_path / "s.png")]) == 0
    with pytest.raises(SystemExit):
        plotting.main(["figure3", str(tmp_path / "oracle"), "--scenario", "1", "--seed-index", "0",
                       "--out", str(tmp_path / "t.png")])
    assert plotting.main(["figure3", str(tmp_path / "oracle"), "--scenario", "1", "--out",
                          str(tmp_path / "f.png")]) == 0
    with pytest.raises(SystemExit):
        plotting.main(["figure3", str(tmp_path / "oracle"), "--scenario", "2", "--out", str(tmp_path / "g.png")])


@pytest.mark.parametrize("argv", [["figure3", "results/a", "--scenario", "2"], ["curves", "runs/a"]])
def test_plotting_commands_write_nowhere_unasked(argv, tmp_path, monkeypatch, capsys):
    """No figure lands in the current directory by default: --out is required."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        plotting.main(argv)
    assert e.value.code == 2 and "--out" in capsys.readouterr().err and not list(tmp_path.iterdir())


def test_an_unwritable_out_is_one_line(tmp_path, capsys, no_compile):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(SystemExit) as e:   # checked with the other arguments (docrl_jax.arguments.check_out)
        cli.main(["--policy", "bba", "--trials", "2", "--out", str(blocker / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and err == [f"python -m docrl_jax.evaluate: error: --out {blocker / 'out'}: Not a directory"]


def test_aggregate_seeds_pools_exactly():
    rng = np.random.default_rng(0)
    samples = [rng.normal(10, 2, 7), rng.normal(14, 1, 3), np.array([])]   # seed 2: no successes
    rows = []
    for k, x in enumerate(samples):
        mean, std = evaluate.mean_std(x)
        rows.append({"method": "m", "seed_index": k, "scenario": 2, "direction": "water_to_air", "trials": 10,
                     "successes": x.size, "success_rate": x.size / 10, "collisions": 10 - x.size,
                     "out_of_bounds": 0, "timeouts": 0, **{f"{n}_{s}": v for n in ("t_air", "t_water", "time",
                                                                                   "path_length")
                                                           for s, v in (("mean", mean), ("std", std))}})
    (agg,) = evaluate.aggregate_seeds(rows)
    pooled = np.concatenate(samples)
    assert agg["t_air_mean"] == pytest.approx(pooled.mean()) and agg["t_air_std"] == pytest.approx(pooled.std())
    assert agg["successes_per_seed"] == [7, 3, 0] and agg["successes_mean"] == pytest.approx(10 / 3)
    assert agg["successes_std"] == pytest.approx(np.std([7, 3, 0]))
    md = evaluate.markdown_table(rows, seed_rows=[agg])
    assert "## Over seeds" in md and "[7, 3, 0]" in md and "W-A m #2" in md


def test_evaluate_policy_is_deterministic_per_seed(env):
    kw = dict(scenarios=[1], directions=["air_to_water"], num_trials=N, max_steps=MAX_STEPS,
              env_overrides={"z_bounds": LOW_FLOOR})
    (row_a, a), = evaluate.evaluate_policy(straight_line(), "oracle", seed=5, **kw)
    (row_b, b), = evaluate.evaluate_policy(straight_line(), "oracle", seed=5, **kw)
    (_, c), = evaluate.evaluate_policy(straight_line(), "oracle", seed=6, **kw)
    assert row_a["compile_s"] is None and row_a["run_s"] is not None   # the module's compiled rollout
    np.testing.assert_array_equal(a["positions"], b["positions"])
    assert not np.array_equal(a["positions"], c["positions"])
    assert row_a["successes"] == N and row_a["scenario"] == 1 and row_a["direction"] == "air_to_water"


def test_cli_run_seeds_share_one_compile(monkeypatch, tmp_path):
    """Each seed's own parameters are used, through one compiled rollout (the seeds of a run share
    their networks): seed 1's parameters make the scripted policy dive, seed 0's fly straight."""
    import jax.numpy as jnp
    from docrl_jax.policy import Policy
    base = straight_line()

    def load_policy(run_dir, seed_index=0, which=None):  # fresh closures on every call, as the real loader makes
        return Policy(name="p", params={"dive": jnp.asarray(seed_index == 1)},
                      init_carry=lambda: base.init_carry(), act=lambda *a: base.act(*a))
    monkeypatch.setattr("docrl_jax.runs.load_policy", load_policy)
    run = tmp_path / "two_seeds"
    run.mkdir()
    (run / "config.yaml").write_text("algo: scripted\n")
    out = tmp_path / "out"
    assert cli.main(["--run", str(run), "--seed-index", "0,1", "--trials", str(N), "--scenarios", "1",
                          "--directions", "a-w", "--max-steps", str(MAX_STEPS), "--figures", "0",
                          "--env", f"z_bounds=[{LOW_FLOOR[0]}, {LOW_FLOOR[1]}]", "--out", str(out)]) == 0
    rows = json.loads((out / "results.json").read_text())["results"]
    assert [(r["seed_index"], r["successes"], r["collisions"]) for r in rows] == [(0, N, 0), (1, 0, N)]
    assert rows[0]["compile_s"] is not None and rows[1]["compile_s"] is None and rows[1]["run_s"] is not None


def test_cli_several_runs_are_the_seeds_of_one_method(monkeypatch, tmp_path, capsys):
    """Separate launches of one config (one run dir per seed, as time_to_success makes them) are
    evaluated as one method: seeds numbered in the order given, each run's own parameters (run B's
    make the scripted policy dive), one compiled rollout, the mapping back to the runs in results.json."""
    import jax.numpy as jnp
    from docrl_jax.policy import Policy
    base = straight_line()

    def load_policy(run_dir, seed_index=0, which=None):
        return Policy(name="p", params={"dive": jnp.asarray(str(run_dir).endswith("B"))},
                      init_carry=lambda: base.init_carry(), act=lambda *a: base.act(*a), source=f"{run_dir}")
    monkeypatch.setattr("docrl_jax.runs.load_policy", load_policy)
    runs = []
    for name in ("A", "B"):
        run = tmp_path / f"td3_lstm_seed{name}"
        run.mkdir()
        (run / "config.yaml").write_text("name: td3_lstm\nagent: {algo: td3}\n")
        runs.append(str(run))
    out = tmp_path / "out"
    common = ["--trials", str(N), "--scenarios", "1", "--directions", "a-w", "--max-steps", str(MAX_STEPS),
              "--figures", "0", "--env", f"z_bounds=[{LOW_FLOOR[0]}, {LOW_FLOOR[1]}]"]
    assert cli.main(["--run", *runs, *common, "--out", str(out)]) == 0
    js = json.loads((out / "results.json").read_text())
    rows = js["results"]
    assert [(r["method"], r["seed_index"], r["successes"], r["collisions"]) for r in rows] == [
        ("td3_lstm", 0, N, 0), ("td3_lstm", 1, 0, N)]
    assert rows[1]["compile_s"] is None   # run B reused run A's compiled rollout (same agent settings)
    assert js["meta"]["seed_runs"] == {"0": {"run": runs[0], "seed_index": 0}, "1": {"run": runs[1], "seed_index": 0}}
    assert "| A-W td3_lstm | " in (out / "results.md").read_text()
    # runs of different configs need a --label
    (tmp_path / "td3_lstm_seedB" / "config.yaml").write_text("name: sac_lstm\nagent: {algo: sac}\n")
    with pytest.raises(SystemExit) as e:
        cli.main(["--run", *runs, *common, "--out", str(out)])
    assert e.value.code == 2 and "different configs (sac_lstm, td3_lstm)" in capsys.readouterr().err


def test_cli_run_defaults_to_every_trained_seed(fake_trainer, tmp_path, capsys):
    """Without --seed-index a run of 2 vmapped seeds is evaluated as 2 seeds (not silently seed 0 only)."""
    (fake_trainer / "config.yaml").write_text("algo: oracle\ntrain:\n  num_seeds: 2\n")
    out = tmp_path / "out"
    assert cli.main(["--run", str(fake_trainer), "--trials", str(N), "--scenarios", "1", "--directions", "a-w",
                          "--max-steps", str(MAX_STEPS), "--figures", "0",
                          "--env", f"z_bounds=[{LOW_FLOOR[0]}, {LOW_FLOOR[1]}]", "--out", str(out)]) == 0
    js = json.loads((out / "results.json").read_text())
    assert [r["seed_index"] for r in js["results"]] == [0, 1] and {r["method"] for r in js["results"]} == {
        "oracle_run (best)"}   # the run's policy by default, and the label says which it was
    assert js["meta"]["which"] == {"0": "best", "1": "best"}
    assert js["meta"]["policy_sources"] == {"0": "best policy of seed index 0", "1": "best policy of seed index 1"}
    (fake_trainer / "config.yaml").write_text("algo: oracle\ntrain:\n  num_seeds: many\n")
    with pytest.raises(SystemExit) as e:
        cli.main(["--run", str(fake_trainer), "--out", str(tmp_path / "bad")])
    assert e.value.code == 2 and "num_seeds='many'" in capsys.readouterr().err


def test_old_names_say_where_evaluation_lives():
    """The old module names fail naming the new ones; the documented commands stay importable by name."""
    import importlib
    for old, new in (("docrl_jax.protocol", "docrl_jax.evaluate.protocol"),
                     ("docrl_jax.paper_results", "docrl_jax.evaluate.paper_results")):
        with pytest.raises(ModuleNotFoundError, match=f"import {new} instead"):
            importlib.import_module(old)
    from docrl_jax import compare as compare_command, plotting as plotting_command
    with pytest.raises((AttributeError, ImportError), match="import load_eval from docrl_jax.evaluate.compare"):
        compare_command.load_eval
    with pytest.raises((AttributeError, ImportError), match="import plot_figure3 from docrl_jax.evaluate.plotting"):
        plotting_command.plot_figure3


def test_cli_run_is_flown_in_its_vehicle(fake_trainer, tmp_path):
    """A run trained with a vehicle setting (env.vel_i_rate) is evaluated in that vehicle, not the
    default one; its training-only env keys (starts, randomisation ranges) are not; --env still wins."""
    (fake_trainer / "config.yaml").write_text(
        "algo: oracle\nenv:\n  vel_i_rate: 0.3\n  goal_clearance: 0.6\n  dr_mass_scale: [0.8, 1.2]\n")
    low = {"z_bounds": list(LOW_FLOOR)}
    vehicle = run_dirs.run_vehicle(fake_trainer)
    assert rollout.flown_env(vehicle, low) == {"vel_i_rate": 0.3, **low}
    assert rollout.flown_env(vehicle, {"vel_i_rate": 0.0}) == {"vel_i_rate": 0.0}
    assert rollout.flown_env(run_dirs.run_vehicle(None), low) == low
    out = tmp_path / "out"
    assert cli.main(["--run", str(fake_trainer), "--seed-index", "0", "--trials", str(N), "--scenarios", "1",
                     "--directions", "a-w", "--max-steps", str(MAX_STEPS), "--figures", "0",
                     "--env", f"z_bounds=[{LOW_FLOOR[0]}, {LOW_FLOOR[1]}]", "--out", str(out)]) == 0
    assert json.loads((out / "results.json").read_text())["meta"]["vehicles"] == {"0": {"vel_i_rate": 0.3}}
    # The same trials again through the library in the rate-0.3 env: its rollout is the one the command
    # compiled (no compile now), and the paths are the command's.
    from docrl_jax import runs
    policy = runs.load_policy(str(fake_trainer))
    (row, trials), = evaluate.evaluate_policy(policy, "oracle", [1], ["air_to_water"], N, MAX_STEPS,
                                              env_overrides={"z_bounds": LOW_FLOOR, "vel_i_rate": 0.3})
    assert row["compile_s"] is None
    saved = np.load(out / "trajectories_s1_air_to_water_seed0.npz")
    np.testing.assert_array_equal(saved["positions"], trials["positions"].astype(np.float32))


class _CountingEnv:
    """A stand-in env for make_rollout's contract: it only counts its steps (its own "step" offset by 100 so
    the policy's can be told from it) and never ends."""
    control_dt = 0.1

    def _state(self, steps):
        import jax.numpy as jnp
        no = jnp.zeros((), bool)
        info = {"position": jnp.zeros(3), "underwater": no, "step": steps + 100, "arrived": no, "collision": no,
                "out_of_bounds": no, "terminated": no, "distance": jnp.float32(1.0)}
        return envs.EnvState(sim=steps, obs=jnp.zeros(26), reward=jnp.float32(0.0), done=no, info=info)

    def reset_to(self, key, position, yaw, goal):
        return self._state(jax.numpy.zeros((), jax.numpy.int32))

    def step(self, state, action):
        return self._state(state.sim + 1)


def test_the_policy_is_given_the_rollouts_step_one_value_for_all_trials():
    """make_rollout's policy reads info["step"] = the scan's counter (0, 1, ...), the same for every trial: under
    vmap a cond on it stays a cond (one branch runs); on a per-trial value vmap turns it into a select."""
    import jax.numpy as jnp

    from docrl_jax.policy import Policy

    def act(params, carry, obs, info, key):
        parity = jax.lax.cond(info["step"] % 2 == 0, lambda: 1.0, lambda: -1.0)
        return carry, jnp.stack([info["step"].astype(jnp.float32), parity, 0.0])

    policy = Policy(name="step echo", params=None, init_carry=lambda: jnp.zeros(()), act=act)
    fn = evaluate.make_rollout(_CountingEnv(), policy, 6)
    args = (None, jax.random.split(jax.random.PRNGKey(0), 3), jnp.zeros((3, 3)), jnp.zeros(3), jnp.zeros(3))
    actions = np.asarray(fn(*args)["actions"])
    np.testing.assert_array_equal(actions[..., 0], np.tile(np.arange(6), (3, 1)))
    np.testing.assert_array_equal(actions[..., 1], np.tile([1, -1, 1, -1, 1, -1], (3, 1)))
    assert "cond[" in str(jax.make_jaxpr(fn)(*args))
    per_trial = jax.make_jaxpr(jax.vmap(lambda s: act(None, None, None, {"step": s}, None)[1]))(jnp.arange(3))
    assert "cond[" not in str(per_trial)
