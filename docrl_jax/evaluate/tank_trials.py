"""Trials in a tank set (tank files, docrl_jax/envs/tanks.py and docs/TANKS.md), the same for
`python -m docrl_jax.evaluate --tank`, `python -m docrl_jax.render --tank` and the robustness
benchmark's `tanks` test:

  * N trials per direction; trial i flies in tank i mod K (the set's K tanks in `tanks.names` order);
  * it starts at a random point of the start medium's region and heads for a random point of the
    other medium's (A-W: from the tank's `air` region to its `water` region; W-A the reverse), at
    least `goal_clearance` from every solid, with a uniform yaw: `env.reset(key, layout=tank)` of the
    evaluation env with the media forced (`rollout.MEDIA`), scenario 0;
  * the plant is the one the evaluation env's parameters draw (nominal unless --env sets `dr_*`);
  * trial i's key depends on (seed, direction, i) only (`rollout.trip_keys(seed, "tanks", 0, ...)`),
    so the three commands fly the very same trials, and a longer run's first trials are a shorter one's.

The env itself knows nothing of the set (its `tank` parameter stays None): the tanks are data given to
each trial's reset, so every tank set shares the compiled rollout of scenario 0.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from docrl_jax.evaluate.tables import SHORT, summarize
from docrl_jax.evaluate.tank_sets import ALL, TEST, load, repeat, subset, tank_index


def run(policy, stack, direction: str, num_trials: int, max_steps: int, seed: int, env_kw: dict,
        render: bool = False) -> dict[str, np.ndarray]:
    """`num_trials` trials of one direction in the set `stack` (from `load`), run by the rollout of the
    evaluation env of scenario 0 with the overrides `env_kw` (`rollout.make_eval_env`): the arrays of
    `rollout.run_trials` plus `tank` (N,) (each trial's index in the set) and `goals` (N, 3); with
    `render`, the renderer's records too."""
    from docrl_jax.evaluate import rollout
    host = rollout.make_eval_env(0, max_steps, **env_kw)
    start_w, goal_w = rollout.MEDIA[direction]
    sampler = rollout.make_eval_env(0, max_steps, **env_kw, start_water_fraction=start_w, goal_water_fraction=goal_w)
    keys = rollout.trip_keys(seed, TEST, 0, direction, num_trials)
    trials = rollout.trip_trials(host, sampler, policy, keys, host.params, max_steps, repeat(stack, num_trials),
                                    render=render)
    trials["tank"] = tank_index(num_trials, int(np.shape(stack.index)[0]))
    return trials


def evaluate_policy(policy, method: str, spec: str, directions: Sequence[str], num_trials: int, max_steps: int,
                    seed: int, env_kw: dict, seed_index: int | None = None, on_result=None) -> list[tuple]:
    """`python -m docrl_jax.evaluate --tank`'s trials of one policy: per direction, `num_trials` trials in
    the set `spec`. Returns [(row, trials, tank_rows)]: `row` as `rollout.evaluate_policy`'s (scenario 0,
    tank `ALL`), `trials` as `run`'s, `tank_rows` = `per_tank`. `on_result(row, trials, tank_rows, names,
    stack)` is called after each direction."""
    import time

    from docrl_jax.evaluate import rollout
    names, stack = load(spec, rollout.eval_params(0, max_steps, **env_kw))
    host = rollout.make_eval_env(0, max_steps, **env_kw)
    out = []
    for direction in directions:
        fresh = rollout._cache_key(host, policy, max_steps, from_states=True) not in rollout._ROLLOUTS
        t0 = time.time()
        trials = run(policy, stack, direction, num_trials, max_steps, seed, env_kw)
        elapsed = round(time.time() - t0, 2)
        row = {"method": method, "seed_index": seed_index, "scenario": 0, "direction": direction, "tank": ALL,
               **summarize(trials), "compile_s": elapsed if fresh else None, "run_s": None if fresh else elapsed}
        tank_rows = per_tank(names, trials, row)
        if on_result is not None:
            on_result(row, trials, tank_rows, names, stack)
        out.append((row, trials, tank_rows))
    return out


def per_tank(names: Sequence[str], trials: dict[str, np.ndarray], row: dict) -> list[dict]:
    """One row per tank of the set (`summarize` of its trials; none flown: 0 trials), then the row
    over the set (tank `ALL`); each with `row`'s method, seed_index, direction."""
    out = []
    keep = {k: row[k] for k in ("method", "seed_index", "direction") if k in row}
    for i, name in enumerate(names):
        out.append({**keep, "tank": name, **summarize(subset(trials, trials["tank"] == i))})
    return out + [{**keep, "tank": ALL, **summarize(trials)}]


def markdown(rows: Sequence[dict], spec: str) -> str:
    """Successes out of trials per tank (rows of `per_tank`), a column per direction and a row per tank
    and method (and seed), the set's total last."""
    dirs = list(dict.fromkeys(r["direction"] for r in rows))
    methods = list(dict.fromkeys((r["method"], r.get("seed_index")) for r in rows))
    names = list(dict.fromkeys(r["tank"] for r in rows))
    cells = {(r["tank"], r["method"], r.get("seed_index"), r["direction"]): r for r in rows}
    out = [f"### Per tank ({spec})\n", "Successes / trials (collisions, out of bounds, time-outs); trial i flies "
           "in tank i mod the set's size.\n",
           "| Tank | Method | " + " | ".join(SHORT[d] for d in dirs) + " |", "|---|---|" + "---|" * len(dirs)]
    for name in names:
        for method, seed in methods:
            tag = "" if seed is None else f" #{seed}"
            row = []
            for d in dirs:
                r = cells.get((name, method, seed, d))
                row.append("–" if r is None or not r["trials"] else
                           f"{r['successes']}/{r['trials']} ({r['collisions']}, {r['out_of_bounds']}, {r['timeouts']})")
            label = f"**{name}**" if name == ALL else name
            out.append(f"| {label} | {method}{tag} | " + " | ".join(row) + " |")
    return "\n".join(out) + "\n"


CSV_FIELDS = ("method", "seed_index", "tank", "direction", "trials", "successes", "success_rate", "collisions",
              "out_of_bounds", "timeouts", "diverged", "t_air_mean", "t_water_mean", "path_length_mean",
              "final_distance_mean")


def write(out_dir: Path, rows: Sequence[dict], spec: str) -> list[Path]:
    """tanks.csv (a row per tank, direction, method and seed; tank `all`: the set), and the per-tank
    table (`markdown`) appended to results.md."""
    import csv
    import math
    path = out_dir / "tanks.csv"
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows({k: (round(v, 4) if isinstance(v, float) and math.isfinite(v) else
                         (None if isinstance(v, float) else v)) for k, v in r.items()} for r in rows)
    with open(out_dir / "results.md", "a") as f:
        f.write("\n" + markdown(rows, spec))
    return [path]


def plot_flown(stem: Path, stack, names: Sequence[str], trials: dict[str, np.ndarray], title: str,
               max_trajectories: int = 10) -> list[Path]:
    """`plot` of every tank a trial flew in: STEM_TANK.png (the tank's name, other than letters, digits,
    '.', '-' and '_' as '_')."""
    import re
    slug = [re.sub(r"[^\w.-]+", "_", name) for name in names]
    return [plot(stem.with_name(f"{stem.name}_{slug[i]}.png"), stack, names, trials, i, title, max_trajectories)
            for i in np.unique(trials["tank"])]


def plot(path: Path, stack, names: Sequence[str], trials: dict[str, np.ndarray], tank: int, title: str,
         max_trajectories: int = 10) -> Path | None:
    """The trials of one tank (3-D and x-y views, `plotting.draw_trajectories`) with the first one's
    start and goal marked; None when no trial flew in it."""
    import jax

    from docrl_jax.envs import layouts
    from docrl_jax.evaluate import plotting
    mine = np.flatnonzero(trials["tank"] == tank)
    if mine.size == 0:
        return None
    solids = plotting.scene_solids(layouts.mj_model(jax.tree.map(lambda x: np.asarray(x)[tank], stack)))
    solids["boxes"] = [b for b in solids["boxes"] if b[0][2] > -20.0]   # parked slots lie far below the floor
    solids["capsules"] = [c for c in solids["capsules"] if c[0][2] > -20.0]
    fig = plotting.plt.figure(figsize=(12, 5.6))
    ax3, ax2 = fig.add_subplot(1, 2, 1, projection="3d"), fig.add_subplot(1, 2, 2)
    first = mine[0]
    plotting.draw_trajectories(ax3, ax2, solids, trials["positions"][mine], trials["steps"][mine],
                               trials["outcome"][mine], trials["start_positions"][first], trials["goals"][first],
                               max_trajectories)
    ok = int((trials["outcome"][mine] == 0).sum())
    ax2.set_title(f"x-y plane: {ok}/{mine.size} successes (start and goal of trial {first} marked)", fontsize=10)
    fig.suptitle(f"{title}, tank {names[tank]}")
    fig.tight_layout()
    return plotting._save(fig, path)
