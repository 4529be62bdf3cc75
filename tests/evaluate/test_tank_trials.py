"""Trials in tank files (docrl_jax.evaluate.tank_trials): `evaluate --tank`, the robustness benchmark's
`tanks` and `structured` tests, the one-line errors of a bad --tank in every command, `train --tank`.

Two tiny hand-written tanks; the BBA, 4 trials, 40 steps, scenario 0 with the evaluator's settings: the
evaluator and the benchmark (without perturbations) share one env and one compiled rollout."""

from __future__ import annotations

import contextlib
import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest

from docrl_jax.evaluate import cli, robustness, robustness_cli, rollout, tank_sets, tank_trials, video

STEPS, TRIALS = 40, 4
# (air region, water region) of each tank, as written in its file: the starts and goals must lie inside.
REGIONS = {
    "wall": (((-4.0, -4.0, 1.0), (-2.0, 4.0, 3.0)), ((2.0, -4.0, -0.9), (4.0, 4.0, -0.5))),
    "open": (((1.0, -3.0, 1.0), (3.0, -1.0, 2.0)), ((-3.0, 1.0, -1.0), (-1.0, 3.0, -0.5))),
}
TANKS = {
    "a_wall.yaml": """name: wall
floor_top: -1.3
air: {min: [-4.0, -4.0, 1.0], max: [-2.0, 4.0, 3.0]}
water: {min: [2.0, -4.0, -0.9], max: [4.0, 4.0, -0.5]}
solids:
  - {type: box, name: wall_south, center: [0.0, -3.0, 1.7], half_extents: [0.15, 2.0, 3.0]}
""",
    "b_open.yaml": """name: open
floor_top: -1.5
air: {min: [1.0, -3.0, 1.0], max: [3.0, -1.0, 2.0]}
water: {min: [-3.0, 1.0, -1.0], max: [-1.0, 3.0, -0.5]}
solids:
  - {type: capsule, name: pipe, from: [0.0, 4.0, -1.4], to: [0.0, 4.0, 2.0], radius: 0.3}
""",
}
BROKEN = "floor_top: -1.3\nsolids:\n  - {type: sphere, center: [0, 0, 0]}\n"


@pytest.fixture(scope="module")
def tank_dir(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("tanks") / "set"
    folder.mkdir()
    for name, text in TANKS.items():
        (folder / name).write_text(text)
    (folder.parent / "broken.yaml").write_text(BROKEN)
    return folder


@pytest.fixture(scope="module")
def evaluated(tank_dir):
    """`evaluate --tank` of the set: its printed output and written folder."""
    out = tank_dir.parent / "eval"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert cli.main(["--policy", "bba", "--tank", str(tank_dir), "--trials", str(TRIALS), "--max-steps",
                         str(STEPS), "--figures", "1", "--out", str(out)]) == 0
    return out, printed.getvalue()


def _stand_in_set(n, p):
    """For structures.held_out_set, whose generator and flyability filter cost ~90 s to compile on a CPU
    (tested beside them, tests/envs): this set's tanks repeated to n, so the rows' plumbing is tested here."""
    from docrl_jax.envs import structures
    calls.append((n, p))
    return structures.HeldOutSet(tank_sets.repeat(tank_sets.load(SET[0], p)[1], n), *([None] * 4))


calls: list = []
SET: list = []


@pytest.fixture(scope="module")
def benchmarked(tank_dir, evaluated):
    """The robustness benchmark's tanks and structured tests on the same set, trials and steps."""
    from docrl_jax.envs import structures
    out = tank_dir.parent / "robustness"
    with contextlib.redirect_stdout(io.StringIO()), pytest.MonkeyPatch.context() as mp:
        mp.setattr(structures, "held_out_set", _stand_in_set)
        SET[:] = [str(tank_dir)]
        assert robustness_cli.main(["--policy", "bba", "--tests", "tanks,structured", "--tank", str(tank_dir),
                                    "--trials", str(TRIALS), "--layouts", str(TRIALS), "--perturbations", "none",
                                    "--max-steps", str(STEPS), "--out", str(out)]) == 0
    with open(out / "robustness.csv") as f:
        return out, list(csv.DictReader(f))


def _inside(points, box) -> np.ndarray:
    lo, hi = np.asarray(box[0]) - 1e-4, np.asarray(box[1]) + 1e-4
    return np.all((points >= lo) & (points <= hi), axis=-1)


def test_evaluate_tank_prints_and_writes_a_table_per_tank(evaluated):
    out, printed = evaluated
    assert "### Per tank" in printed and "| wall | BBA |" in printed and "| open | BBA |" in printed
    with open(out / "tanks.csv") as f:
        rows = list(csv.DictReader(f))
    for direction in ("air_to_water", "water_to_air"):
        mine = {r["tank"]: r for r in rows if r["direction"] == direction}
        assert set(mine) == {"wall", "open", "all"}
        assert [int(mine[t]["trials"]) for t in ("wall", "open", "all")] == [2, 2, TRIALS]   # trial i: tank i mod 2
        for key in ("successes", "collisions", "out_of_bounds", "timeouts"):
            assert int(mine["wall"][key]) + int(mine["open"][key]) == int(mine["all"][key])
    with open(out / "results.csv") as f:
        results = list(csv.DictReader(f))
    assert [(r["scenario"], r["direction"], r["trials"]) for r in results] == [
        ("0", "air_to_water", str(TRIALS)), ("0", "water_to_air", str(TRIALS))]
    assert "### Per tank" in (out / "results.md").read_text()
    meta = json.loads((out / "results.json").read_text())["meta"]
    assert meta["tank"] == str(evaluated[0].parent / "set") and meta["tank_names"] == ["wall", "open"]
    assert sorted(p.name for p in out.glob("trajectory_*.png")) == [
        f"trajectory_s0_{d}_{t}.png" for d in ("air_to_water", "water_to_air") for t in ("open", "wall")]
    # the tables are the tank set's, not a "scenario 0" the command refuses; the closing line names every file
    for text in (printed, (out / "results.md").read_text()):
        assert f"### Tanks: {evaluated[0].parent / 'set'}" in text and "Scenario 0" not in text
    closing = printed.strip().splitlines()[-1]
    listed = closing.split(": ", 1)[1].rsplit(" (", 1)[0].split(", ")
    assert closing.startswith(f"wrote {out}/: ") and sorted(listed) == sorted(p.name for p in out.iterdir()), closing


def test_starts_and_goals_lie_in_each_tanks_regions(evaluated):
    """A-W starts in the tank's air region and heads for its water region, W-A the reverse; trial i in
    tank i mod 2 (the regions of the files, not the env's)."""
    out, _ = evaluated
    for direction, (start_medium, goal_medium) in (("air_to_water", (0, 1)), ("water_to_air", (1, 0))):
        npz = np.load(out / f"trajectories_s0_{direction}.npz")
        np.testing.assert_array_equal(npz["tank"], np.arange(TRIALS) % 2)
        for i in range(TRIALS):
            regions = REGIONS[str(npz["tank_names"][npz["tank"][i]])]
            assert _inside(npz["start"][i], regions[start_medium]), (direction, i, npz["start"][i])
            assert _inside(npz["goal"][i], regions[goal_medium]), (direction, i, npz["goal"][i])
        assert len({tuple(s) for s in npz["start"].round(3)}) == TRIALS   # random starts, not one point


def test_benchmark_tanks_rows_name_the_tank_and_fly_the_evaluators_trials(evaluated, benchmarked):
    out, rows = benchmarked
    tanks = [r for r in rows if r["test"] == "tanks"]
    assert [(r["direction"], r["tank"], r["trials"]) for r in tanks] == [
        (d, t, n) for d in ("air_to_water", "water_to_air") for t, n in (("all", "4"), ("wall", "2"), ("open", "2"))]
    with open(evaluated[0] / "tanks.csv") as f:
        evaluator = {(r["direction"], r["tank"]): r for r in csv.DictReader(f)}
    for r in tanks:   # the same trials: every count and mean agrees
        e = evaluator[(r["direction"], r["tank"])]
        for key in ("successes", "collisions", "timeouts", "final_distance_mean"):
            assert float(r[key]) == pytest.approx(float(e[key]), abs=1e-3), (key, r, e)
    md = (out / "robustness.md").read_text()
    assert "## Per tank" in md and "| wall | BBA |" in md and "| Tanks | BBA |" in md
    meta = json.loads((out / "robustness.json").read_text())["meta"]
    assert meta["tank_names"] == ["wall", "open"] and meta["tests"] == ["structured", "tanks"]


def test_benchmark_structured_rows(benchmarked):
    _, rows = benchmarked
    assert [(n, p.scenario, p.max_episode_steps) for n, p in calls] == [(TRIALS, 0, STEPS)]
    structured = [r for r in rows if r["test"] == "structured"]
    assert [(r["scenario"], r["direction"], r["tank"], r["trials"]) for r in structured] == [
        ("0", d, "", str(TRIALS)) for d in ("air_to_water", "water_to_air")]
    for r in structured:
        counts = [int(r[k]) for k in ("successes", "collisions", "out_of_bounds", "timeouts", "diverged")]
        assert sum(counts) == TRIALS


def test_per_tank_table_by_hand():
    rows = [{"method": "M", "seed_index": None, "direction": "air_to_water", "tank": t, "trials": n, "successes": s,
             "collisions": c, "out_of_bounds": 0, "timeouts": n - s - c}
            for t, n, s, c in (("a", 2, 1, 1), ("b", 0, 0, 0), ("all", 2, 1, 1))]
    md = tank_trials.markdown(rows, "set")
    assert "| a | M | 1/2 (1, 0, 0) |" in md and "| b | M | – |" in md and "| **all** | M | 1/2 (1, 0, 0) |" in md
    np.testing.assert_array_equal(tank_sets.tank_index(5, 3), [0, 1, 2, 0, 1])


@pytest.fixture
def no_compile(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("compiled before the arguments were checked")
    for name in ("make_rollout", "make_eval_env", "run_from_states"):
        monkeypatch.setattr(rollout, name, boom)
    monkeypatch.setattr(robustness, "run_benchmark", boom)


@pytest.mark.parametrize("command", ["evaluate", "render", "robustness"])
@pytest.mark.parametrize("tank, message", [
    ("no_such_tank", "tank 'no_such_tank': no such file or folder, nor a packaged tank; packaged: "),
    ("broken.yaml", "solid 1: unknown type 'sphere'; valid types: box, capsule"),
])
def test_a_bad_tank_is_one_line_exit_2(command, tank, message, tank_dir, tmp_path, monkeypatch, capsys, no_compile):
    monkeypatch.chdir(tank_dir.parent)
    main, argv = {"evaluate": (cli.main, []), "render": (video.main, ["--out", str(tmp_path / "v.gif")]),
                  "robustness": (robustness_cli.main, ["--tests", "tanks", "--out", str(tmp_path / "r")])}[command]
    with pytest.raises(SystemExit) as exit_:
        main(["--policy", "bba", "--tank", tank, *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(err) == 1, err
    assert err[0].startswith(f"python -m docrl_jax.{command}: error: ") and message in err[0], err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("main, argv, message", [
    (cli.main, ["--scenarios", "1"], "a tank set's trials fly in scenario 0, in place of the scenarios' paper pairs"),
    (cli.main, ["--env", "start_water_fraction=1"], "--env start_water_fraction: set by --tank"),
    (cli.main, ["--env", "tank=x"], "--env tank: set by the evaluator (use --tank)"),
    (video.main, ["--scenario", "2", "--out", "v.gif"], "a tank set's trials fly in scenario 0"),
    (video.main, ["--direction", "random", "--out", "v.gif"], "with --tank, give air_to_water"),
    (robustness_cli.main, ["--tests", "random_trips", "--out", "r"], "only the tanks test flies a tank set"),
])
def test_tank_usage_errors(main, argv, message, tmp_path, monkeypatch, capsys, no_compile):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["--policy", "bba", "--tank", "gallery", *argv])
    assert exit_.value.code == 2 and message in capsys.readouterr().err


def test_train_tank_sets_scenario_0_and_fails_in_one_line(tank_dir, tmp_path, monkeypatch):
    from docrl_jax.config import env_kwargs
    from docrl_jax.train import cli as train_cli
    monkeypatch.chdir(tank_dir.parent)
    config, _ = train_cli._resolve(train_cli.build_parser().parse_args(["--config", "td3_lstm", "--tank", "set"]))
    assert config.env.scenario == 0 and env_kwargs(config)["tank"] == str(tank_dir.resolve())   # absolute
    config, _ = train_cli._resolve(train_cli.build_parser().parse_args(["--config", "td3_lstm", "--tank", "gallery"]))
    assert env_kwargs(config)["tank"] == "gallery"
    console = train_cli.make_console(file=io.StringIO(), width=300)
    monkeypatch.setattr(train_cli, "make_console", lambda **kw: console)
    assert train_cli.main(["--config", "td3_lstm", "--tank", "broken.yaml", "--run-dir", str(tmp_path / "run"),
                           "--compile-cache", "off"]) == train_cli.EXIT_CONFIG
    lines = console.file.getvalue().strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "unknown type 'sphere'" in lines[0], lines
    assert not (tmp_path / "run").exists()
