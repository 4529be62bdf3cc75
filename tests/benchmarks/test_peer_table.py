"""benchmarks/peer_table.py on the committed H200 results: its medians and per-seed times are the ones
time_to_success.py and peers.py measured and recorded themselves, and runs split over files group."""

import json
import math
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "h200x2", "peers")
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
peer_table = pytest.importorskip("peer_table")


def _load(name):
    with open(os.path.join(RESULTS, name)) as f:
        return json.load(f)


def test_groups_match_what_the_scripts_recorded(tmp_path):
    ours = [os.path.join(RESULTS, "ours", "time_to_success_td3_lstm.json")]
    ppo_files = ["peers_ppo_gpu1.json", "peers_ppo_gpu0.json"]   # seeds 0, 1 and seed 2, one configuration
    groups = {**peer_table.our_groups(ours),
              **peer_table.peer_groups([os.path.join(RESULTS, f) for f in ppo_files])}
    td3 = groups["ours: td3_lstm"]
    recorded_median = _load("ours/time_to_success_td3_lstm.json")["summary"]["median_time_to_target_s"]
    assert peer_table.median_time(td3) == recorded_median
    ppo = groups["Brax ppo (Brax's defaults)"]
    assert sorted(r["seed"] for r in ppo) == [0, 1, 2]
    recorded = sorted(r["time_to_target_s"] for f in ppo_files for r in _load(f)["runs"])
    assert sorted(r["time"] for r in ppo) == recorded
    assert peer_table.median_time(ppo) == recorded[1]
    # our curve is on the launch clock: the point where the seed reached the target sits at its time
    for run, rec in zip(td3, _load("ours/time_to_success_td3_lstm.json")["seeds"]):
        assert any(abs(t - rec["time_to_target_s"]) < 1e-6 and v >= 0.9 for t, v in run["curve"])


def test_a_run_that_never_reached_counts_as_slowest():
    runs = [{"reached": True, "time": 10.0}, {"reached": False, "time": None}, {"reached": False, "time": None}]
    assert math.isinf(peer_table.median_time(runs))
    assert peer_table.median_time(runs[:2] + [{"reached": True, "time": 30.0}]) == 30.0


def test_main_writes_table_and_figure(tmp_path):
    assert peer_table.main(["--ours", os.path.join(RESULTS, "ours", "time_to_success_td3_lstm.json"),
                            "--peers", os.path.join(RESULTS, "peers_sac_4096_s12.json"), "--out", str(tmp_path)]) == 0
    md = (tmp_path / "peer_table.md").read_text()
    assert "| ours: td3_lstm | 0, 1, 2 | 72.6, 72.8, 65.6 | 72.6 |" in md
    assert "200.5, no (budget at 304)" in md and (tmp_path / "peer_success_vs_time.png").stat().st_size > 10_000


def test_recipe_runs_group_by_recipe_and_keep_recorded_times():
    new = os.path.join(ROOT, "benchmarks", "results", "h100x4", "peers_2026_11_27", "res")
    files = [os.path.join(new, f"peers_ppo_loco_s{s}.json") for s in (0, 1, 2)]
    groups = peer_table.peer_groups(files + [os.path.join(new, "peers_ppo_e8192_s0.json")])
    loco = groups["Brax ppo (playground_locomotion recipe)"]   # a recipe's own settings are not "changes"
    recorded = sorted(r["time_to_target_s"] for f in files for r in json.load(open(f))["runs"])
    assert sorted(r["time"] for r in loco) == recorded
    assert [r["seed"] for r in groups["Brax ppo (num_envs=8192)"]] == [0]
