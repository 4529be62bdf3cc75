"""benchmarks/every_seed_table.py: a job's two sides are told apart by the settings their runs' configs
differ in, and by nothing that differs between the launches of one side (the seed, the run's name)."""

import os
import sys

from docrl_jax.config import differences, load_config

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
import every_seed_table as est  # noqa: E402


def _launch(side: str, seed: int, *sets: str) -> dict:
    return {"side": side, "config": load_config("td3_lstm", [f"train.seed={seed}", f"name=s{seed}", *sets])}


def test_the_sides_differ_only_in_what_set_them_apart():
    launches = [_launch("new", s, "agent.gamma=0.995", "env.collision_margin=0.09") for s in (5601, 5602)]
    launches += [_launch("old", s) for s in (5601, 5602, 5603)]
    assert est.side_settings(launches, "new", "old") == {"agent.gamma": 0.995, "env.collision_margin": 0.09}
    assert est.side_settings(launches, "old", "new") == {"agent.gamma": 0.99, "env.collision_margin": 0.15}
    # a setting that varies inside a side is not the sides' difference, even where the sides' first launches differ
    launches[1] = _launch("new", 5602, "agent.gamma=0.99", "env.collision_margin=0.09")
    assert est.side_settings(launches, "new", "old") == {"env.collision_margin": 0.09}


def test_a_side_without_loadable_configs_names_nothing():
    launches = [_launch("new", 1, "agent.gamma=0.995"), {"side": "old", "config": None}]
    assert est.side_settings(launches, "new", "old") == {}


def test_differences_names_each_changed_key_with_both_values():
    a, b = load_config("td3_lstm"), load_config("td3_lstm", ["agent.gamma=0.995", "train.seed=3"])
    assert differences(a, b) == {"agent.gamma": (0.99, 0.995), "train.seed": (0, 3)}
    assert differences(a, a) == {}
