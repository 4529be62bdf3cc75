"""The hyperparameter sweep (docrl_jax.sweep) on CPU: the grid's refusals before compiling, the
table's arithmetic, a 2-value grid end to end (table, figures, per-combination metrics), a
1-combination sweep of 2 seeds against plain runs, and each row of the 2-value program against such sweeps."""

from __future__ import annotations

import csv
import functools
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from _trainer_common import EASY, finished_run, tmp_dir

from docrl_jax.train import cli, sweep, sweep_cli, sweep_report
from docrl_jax.errors import ConfigError, RunDirError


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _easy_yaml():
    path = tmp_dir("sweep_configs") / "easy.yaml"
    path.write_text(yaml.safe_dump(EASY))
    return str(path)


def test_grid_refuses_unknown_and_unsweepable_keys_before_compiling(tmp_path):
    assert sweep.parse_grid(["agent.actor_lr=1e-4,3e-4", "agent.critic_hidden=[64,64],[128,128]"]) == {
        "agent.actor_lr": [1e-4, 3e-4], "agent.critic_hidden": [[64, 64], [128, 128]]}
    with pytest.raises(ConfigError, match=r"agent\.bogus: unknown key; traced keys .*agent\.actor_lr.*"
                                          r"compiled-in keys .*replay\.batch_size"):
        sweep.parse_grid(["agent.bogus=1,2"])
    with pytest.raises(ConfigError, match=r"train\.num_seeds: not sweepable \(use --seeds\)"):
        sweep.parse_grid(["train.num_seeds=1,2"])
    with pytest.raises(ConfigError, match="given twice"):
        sweep.parse_grid(["agent.tau=0.1", "agent.tau=0.2"])
    with pytest.raises(ConfigError, match="combination agent.tau=2.*must be in \\(0, 1\\]"):
        sweep.plan(_easy_yaml(), [], {"agent.tau": [0.1, 2.0]}, 1)
    d = tmp_path / "s"
    assert sweep_cli.main(["--config", _easy_yaml(), "--grid", "agent.nope=1,2", "--run-dir", str(d)]) == cli.EXIT_CONFIG
    assert sweep_cli.main(["--run-dir", str(d), "--resume"]) == cli.EXIT_CONFIG
    assert not d.exists()  # nothing written, nothing compiled
    d.mkdir()
    (d / sweep.SWEEP_FILE).write_text("{}")
    assert sweep_cli.main(["--config", _easy_yaml(), "--grid", "agent.tau=0.1", "--run-dir", str(d)]) == cli.EXIT_CONFIG
    with pytest.raises(RunDirError, match="is a sweep.*cannot be resumed"):
        cli._resolve(cli.build_parser().parse_args(["--run-dir", str(d), "--resume"]))
    assert cli.main(["--run-dir", str(d), "--resume"]) == cli.EXIT_CONFIG


def test_traced_keys_are_exactly_the_config_fields_hparams_reads():
    """sweep traces HPARAM_KEYS and neutralises them when grouping combinations into programs: a key
    listed but not read by HParams.from_agent_config would merge combinations that differ in a value
    compiled into the program; a key read but not listed would split them needlessly."""
    from docrl_jax.algorithms.common import HPARAM_KEYS, HParams
    from docrl_jax.config import AgentConfig

    class Recorder:
        def __init__(self):
            self.read, self._a = set(), AgentConfig()

        def __getattr__(self, name):
            self.read.add(name)
            return getattr(self._a, name)

    rec = Recorder()
    HParams.from_agent_config(rec)
    assert rec.read - {"n_step"} == set(HPARAM_KEYS)  # n_step shapes the discount tuple: compiled in
    assert len(HPARAM_KEYS) == len(set(HPARAM_KEYS))


def test_plan_groups_traced_keys_into_one_program_and_shapes_into_several():
    combos, groups = sweep.plan(_easy_yaml(), [], {"agent.actor_lr": [1e-4, 1e-3], "agent.tau": [0.01, 0.02],
                                                   "replay.batch_size": [32, 64]}, 2, check_memory=False)
    assert len(combos) == 8 and [len(g.combinations) for g in groups] == [4, 4]
    assert [g.config.replay.batch_size for g in groups] == [32, 64]
    assert all(g.config.train.num_seeds == 8 for g in groups)          # 4 combinations x 2 seeds
    assert combos[5].values == {"agent.actor_lr": 1e-3, "agent.tau": 0.01, "replay.batch_size": 64}
    assert combos[5].config.agent.actor_lr == 1e-3 and combos[5].config.train.num_seeds == 2


def test_table_time_to_90_and_final_success(tmp_path):
    """The table's arithmetic on hand-written metrics: time to 90 % is the wall-clock of the first
    evaluation with both directions >= 0.9, over the seeds that reached it."""
    grid = {"agent.tau": [0.01, 0.02]}
    (tmp_path / sweep.SWEEP_FILE).write_text(json.dumps({"grid": grid, "combinations": [
        {"name": "c00", "values": {"agent.tau": 0.01}}, {"name": "c01", "values": {"agent.tau": 0.02}}]}))
    cols = sweep_report.columns(grid)
    def write(name, rows):
        (tmp_path / name).mkdir()
        with open(tmp_path / name / "metrics.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, cols, restval="nan")
            w.writeheader()
            for steps, wall, seed, sr, a2w, w2a, ret in rows:
                w.writerow({"env_steps": steps, "wall_time_s": wall, "seed": seed, "success_rate": sr,
                            "success_air_to_water": a2w, "success_water_to_air": w2a, "episode_return": ret})
    write("c00", [(0, 5, 0, 0.0, 0.0, 0.0, -10), (10, 20, 0, 0.9, 0.95, 0.9, 50), (20, 30, 0, 1.0, 1.0, 1.0, 90),
                  (0, 5, 1, 0.0, 0.0, 0.0, -10), (10, 20, 1, 0.5, 0.95, 0.5, 10), (20, 40, 1, 0.8, 0.9, 0.92, 70)])
    write("c01", [(0, 5, 0, 0.0, 0.0, 0.0, -10), (20, 30, 0, 0.5, 0.5, 0.95, 0)])
    paths = sweep_report.write_summary(tmp_path, grid)
    recs = _rows(tmp_path / "sweep.csv")
    assert float(recs[0]["time_to_90_s_mean"]) == 30 and float(recs[0]["time_to_90_s_std"]) == 10
    assert float(recs[0]["final_success_mean"]) == pytest.approx(0.9)
    assert float(recs[0]["final_return_mean"]) == 80 and float(recs[0]["final_return_std"]) == 10
    assert recs[1]["seeds_reached_90"] == "0"
    md = (tmp_path / "sweep.md").read_text()
    assert "| c00 | 0.01 | 2 | 30 ± 10 | 0.90 ± 0.10 | 0.95 ± 0.05 | 0.96 ± 0.04 | 80.0 ± 10.0 |" in md
    assert "| c01 | 0.02 | 1 | not reached |" in md
    assert (tmp_path / "curves_agent.tau.png").stat().st_size > 10_000 and len(paths) == 3


@functools.lru_cache(maxsize=None)
def _sweep(*grid: str, seeds: int = 1) -> Path:
    """Run directory of a sweep of the easy config, one chunk (4,000 env steps) per row."""
    d = tmp_dir("sweeps") / ("_".join(g.replace("=", "-").replace(",", "+") for g in grid) + f"_seeds{seeds}")
    argv = ["--config", _easy_yaml(), "--seeds", str(seeds), "--set", "train.total_env_steps=4000",
            "--run-dir", str(d), "--compile-cache", "off"]
    for g in grid:
        argv += ["--grid", g]
    assert sweep_cli.main(argv) == cli.EXIT_OK
    return d


def _assert_close_rows(ours, theirs):
    """metrics.csv rows of one chunk (evaluations at 0 and 4,000) of two runs of one configuration
    whose programs differ only in float rounding, with the tolerance of
    test_train.test_vmapped_seeds_equal_separate_runs: counts exactly, losses to 1e-3 relative; the
    step-0 evaluation (same initial weights) exactly, the one after the chunk to one episode."""
    assert [r["env_steps"] for r in ours] == [r["env_steps"] for r in theirs] == ["0", "4000"]
    for a, b in zip(ours, theirs):
        for k, v in b.items():
            if k in ("wall_time_s", "combination") or k.startswith("agent."):
                continue
            if k in ("env_steps", "seed", "train_episodes", "grad_updates", "policy_freq") or a is ours[0]:
                assert a[k] == v, (a["env_steps"], k)
            elif k == "success_rate":
                assert abs(float(a[k]) - float(v)) <= 1 / EASY["train"]["eval_episodes"] + 1e-9
            elif k != "episode_return":  # a return sums 64 episodes' rewards: it follows success_rate
                np.testing.assert_allclose(float(a[k]), float(v), rtol=1e-3, atol=1e-5, err_msg=k)


def _seed_rows(rows, seed: int):
    return [r for r in rows if r["seed"] == str(seed)]


def test_one_combination_sweep_matches_a_plain_run():
    """A 1-combination sweep of 2 seeds (the easy config's own tau, traced) against
    docrl_jax.train.run.run of that config and each seed: the same computation, but not bit-identical:
    XLA rewrites Adam's step around a constant learning rate differently from a traced one (1 ulp in
    some weights per update; measured), and training amplifies that like the float rounding of vmapped
    seeds. Its 2 rows (1 combination x 2 seeds) are the program of the 2-value grid below (2 x 1):
    compiled once for both tests."""
    ours = _rows(_sweep("agent.tau=0.01", seeds=2) / "c00" / "metrics.csv")
    assert [r["combination"] for r in ours] == ["c00"] * 4 and {r["agent.tau"] for r in ours} == {"0.01"}
    for seed in (0, 1):
        plain = finished_run(train__total_env_steps=4000, train__seed=seed) / "metrics.csv"
        _assert_close_rows(_seed_rows(ours, seed), _rows(plain))


def test_two_value_grid_end_to_end_and_rows_match_separate_runs():
    d = _sweep("agent.tau=0.01,0.02")
    md = (d / "sweep.md").read_text()
    assert "| c00 | 0.01 | 1 | n/a (train.eval_paper_pairs false) |" in md and "| c01 | 0.02 | 1 |" in md
    recs = _rows(d / "sweep.csv")
    assert [r["agent.tau"] for r in recs] == ["0.01", "0.02"] and all(r["final_env_steps"] == "4000" for r in recs)
    assert (d / "curves_agent.tau.png").stat().st_size > 10_000
    assert json.loads((d / "sweep.json").read_text())["groups"] == [["c00", "c01"]]  # one program
    for name, tau in (("c00", "0.01"), ("c01", "0.02")):
        rows = _rows(d / name / "metrics.csv")
        assert {r["agent.tau"] for r in rows} == {tau} and {r["combination"] for r in rows} == {name}
        assert int(rows[-1]["grad_updates"]) == (4000 - 2000) // 16 * 2
        assert yaml.safe_load((d / name / "config.yaml").read_text())["agent"]["tau"] == float(tau)
        # Each row of the 2-row (vmapped) program against seed 0 of a 1-combination, 2-seed sweep of its value.
        _assert_close_rows(rows, _seed_rows(_rows(_sweep(f"agent.tau={tau}", seeds=2) / "c00" / "metrics.csv"), 0))
    c00, c01 = (_rows(d / n / "metrics.csv")[-1] for n in ("c00", "c01"))
    assert c00["critic_loss"] != c01["critic_loss"]  # each row trained with its own tau
