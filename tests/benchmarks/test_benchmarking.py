"""The benchmark shelf (docrl_jax.benchmarking): result files, time to success, the run goal, packs, the peers'
recipes and the chunk timer, against hand-made inputs."""

from __future__ import annotations

import io
import json
import tarfile

import pytest

from docrl_jax import benchmarking as bench

META = {"command": "python benchmarks/x.py", "gpu": "none", "date": "2026-01-01T00:00:00+00:00", "versions": {}}


def test_write_results_writes_the_rows_and_a_table(tmp_path):
    rows = [{"n": 4096, "sps": 1.5}, {"n": 64, "sps": True}]
    table = bench.write_results(str(tmp_path), "t", "Title", META, rows, [("envs", "n"), ("steps/s", "sps")])
    assert json.loads((tmp_path / "t.json").read_text()) == {**META, "results": rows}
    assert (tmp_path / "t.md").read_text() == table
    assert table.splitlines()[0] == "# Title (none, 2026-01-01T00:00:00+00:00)"
    assert table.splitlines()[-2:] == ["| 4,096 | 1.5 |", "| 64 | True |"]


def test_reached_is_the_first_row_at_the_target_both_ways(tmp_path):
    assert bench.read_rows(str(tmp_path / "missing.csv")) == []
    (tmp_path / "metrics.csv").write_text("env_steps,success_air_to_water,success_water_to_air\n"
                                          "10,0.95,0.5\n20,,\n30,0.9,0.9\n40,1.0,1.0\n")
    rows = bench.read_rows(str(tmp_path / "metrics.csv"))
    assert bench.reached(rows, 0.9)["env_steps"] == "30"
    assert bench.reached(rows, 0.99)["env_steps"] == "40"
    assert bench.reached(rows[:3], 0.95) is None


def test_chunk_steps_per_s_is_the_median_of_the_learning_chunks(tmp_path):
    log = tmp_path / "train.log"
    log.write_text("40,960 steps  9,000 steps/s  ETA once learning starts\n"
                   "81,920 steps  100,000 steps/s  ETA 1 min\n"
                   "evaluation: A-W 10 %\n"
                   "122,880 steps  120,000 steps/s  ETA 50 s\n"
                   "163,840 steps  300,000 steps/s  ETA 40 s\n")
    assert bench.chunk_steps_per_s(str(log)) == 120_000.0


def test_the_goal_counts_each_bar():
    full = {(s, d): 1.0 for s in (1, 2, 3) for d in bench.DIRS}
    weak2 = {**full, (2, "water_to_air"): 0.94}
    weak3 = {**full, (3, "air_to_water"): 0.89}
    assert [bench.meets_goal(e) for e in (full, weak2, weak3, None)] == [True, False, False, None]
    assert bench.goal_counts([full, weak2, weak3]) == (2, 2, 1)
    assert bench.pair(weak2, 2) == "100 / 94" and bench.pair(None, 2) == "–" and bench.pct(None) == "–"


def test_unpack_takes_runs_evaluations_and_times_from_a_jobs_tar(tmp_path):
    def tgz(path, name, text):
        with tarfile.open(path, "w:gz") as t:
            data = text.encode()
            info = tarfile.TarInfo(name)
            info.size = len(data)
            t.addfile(info, io.BytesIO(data))
    pack = tmp_path / "job" / "pack"
    pack.mkdir(parents=True)
    tgz(pack / "runs_a.tgz", "a/metrics.csv", "env_steps\n")
    tgz(pack / "eval_a.tgz", "eval/a/table.md", "| |\n")
    (pack / "times").write_text("a 12.5\n")
    with tarfile.open(tmp_path / "out.tar", "w") as t:
        t.add(pack, arcname="pack")
    into = bench.unpack(str(tmp_path / "out.tar"), tmp_path / "work")
    assert (into / "runs" / "a" / "metrics.csv").read_text() == "env_steps\n"
    assert (into / "eval" / "a" / "table.md").is_file() and (into / "times").read_text() == "a 12.5\n"


def test_a_peer_recipe_is_a_copy_and_a_wrong_name_lists_the_valid_ones():
    cfg, nets = bench.peer_recipe(bench.DEFAULT_PEER_RECIPE, "sac")
    cfg["num_envs"] = -1
    assert bench.PEER_RECIPES[bench.DEFAULT_PEER_RECIPE]["sac"][0]["num_envs"] == 128
    with pytest.raises(SystemExit, match="valid: brax_ant, playground_dm_control, playground_locomotion"):
        bench.peer_recipe("brax_antt", "sac")
    with pytest.raises(SystemExit, match="has no sac recipe; it has: ppo"):
        bench.peer_recipe("playground_locomotion", "sac")
    cfg, nets = bench.peer_recipe("playground_dm_control", "sac")
    assert nets["q_network_layer_norm"] is True and cfg["grad_updates_per_step"] == 8


def test_time_chunks_warms_up_once_then_times_each_call():
    import jax.numpy as jnp
    calls = []

    def chunk(state):
        calls.append(state)
        return state + 1, {"learn_iters": jnp.array([state * 10, state * 10 + 3])}
    state, times, learn = bench.time_chunks(chunk, 0, repeats=3)
    assert calls == [0, 1, 2, 3] and state == 4
    assert len(times) == 3 and all(t >= 0 for t in times)
    assert learn == [10, 20, 30]


def test_no_benchmark_script_imports_a_sibling_or_a_package_private():
    import re
    from pathlib import Path
    root = Path(__file__).resolve().parents[2] / "benchmarks"
    scripts = {p.stem for p in root.glob("*.py")}
    for path in root.glob("*.py"):
        text = path.read_text()
        assert "sys.path.insert" not in text or "export" in text.split("sys.path.insert", 1)[1][:30], path.name
        siblings = set(re.findall(r"^\s*(?:from|import) (\w+)", text, flags=re.M)) & scripts
        assert not siblings, (path.name, siblings)
        assert not re.search(r"from docrl_jax[\w.]* import (?:\w+, )*_\w", text), path.name
        assert not re.search(r"\b(?:programs|trainer|replay|export)\._[a-z]\w*\(", text), path.name
