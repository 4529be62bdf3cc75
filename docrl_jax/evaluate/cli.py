"""The paper's evaluation protocol: N trials per scenario and direction, Table I, CSV/JSON, figures.

    python -m docrl_jax.evaluate --policy bba --trials 100 --scenarios 1,2,3 --out results/bba
    python -m docrl_jax.evaluate --run runs/docrl_d --seed-index 0 --out results/docrl_d
    python -m docrl_jax.evaluate --run runs/td3_seed0 runs/td3_seed1 runs/td3_seed2 --out results/td3  # 3 launches
    python -m docrl_jax.evaluate --curves runs/docrl_d runs/docrl_s --out results/curves

Protocol (paper, "Experimental Results"; shared/research/original-code.md section 7):
  * For each scenario and both directions ("air_to_water" A-W, "water_to_air" W-A), N trials from
    the paper's start to its target (`docrl_jax.envs.eval_pair`).
  * A trial ends at arrival (3-D distance < 0.5 m, the env's `arrival_distance`), at a collision or
    leaving the vertical bounds (the env's `terminated`), or after `max_steps` = 500 control steps
    (100 s simulated; the paper's episode limit. The original's test had no time limit at all).
  * Trials differ by seed only: the wind (an OU process started from its stationary distribution),
    range noise (`sensor_noise_std`, default 0.01 m here: the order of the original sensors'
    quantisation, 0.015 m LIDAR resolution and 0.02 m sonar bins), the policy's own key, and a
    start jitter: x and y uniform in +-0.1 m around the paper's start, yaw uniform in +-0.1 rad
    around the nominal yaw (0 for A-W: the original's spawn; -pi/2 for W-A: the original's
    commented water spawn, yaw -1.57). See `DEFAULT_EVAL_ENV` and `TrialSpec`.
  * All trials of one (scenario, direction) run as ONE `jit(vmap(lax.scan))`: the vehicle state
    freezes once a trial is done, so per-step records past the end repeat the final pose.

Per scenario and direction: successes out of N; t_air and t_water, mean +- std (population std,
ddof 0) over the successful trials, in simulated seconds: a control step counts as air or water by
the vehicle's medium at the start of the step (z >= 0 air, z < 0 water), so t_air + t_water is
exactly the trial time (steps * control_dt); collisions (walls, floor, obstacles), out-of-bounds,
time-outs; path length (sum of the per-step displacements), mean +- std over successful trials.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import yaml

# What a trial is (env settings, nominal yaw, jitter) lives in docrl_jax.protocol, shared with the
# trainer's training-time estimate of the protocol (train_eval).
from docrl_jax.protocol import DEFAULT_EVAL_ENV, DIRECTIONS, NOMINAL_YAW, TrialSpec, trial_starts

SHORT = {"air_to_water": "A-W", "water_to_air": "W-A"}
POLICIES = ("bba",)
SCENARIOS = (1, 2, 3)
OUTCOMES = ("success", "collision", "out_of_bounds", "timeout", "diverged")

# ---------------------------------------------------------------------------------------- core

_ENVS: dict = {}


def make_eval_env(scenario: int, max_steps: int = 500, **overrides):
    """The environment of the evaluation: episodes end at arrival; `max_steps` steps at most.

    Cached per settings, so repeated evaluations in one process reuse the env and its compiled rollouts."""
    import docrl_jax.envs as envs
    kw = dict(DEFAULT_EVAL_ENV)
    kw.update({k: tuple(v) if isinstance(v, list) else v for k, v in overrides.items()})
    kw["terminate_on_arrival"] = True
    kw["max_episode_steps"] = int(max_steps)
    key = (int(scenario), tuple(sorted(kw.items())))
    if key not in _ENVS:
        _ENVS[key] = envs.make(scenario=scenario, **kw)
    return _ENVS[key]


_ROLLOUTS: dict = {}


def make_rollout(env, policy, max_steps: int):
    """jit(vmap(scan)) over trials: (params, keys (N,2), positions (N,3), yaws (N,), goal (3,)) -> records.

    Cached per (env, policy.act, max_steps), so calling again with other params or trials reuses the
    compiled function (a new N retraces once).
    """
    cache_key = (id(env), id(policy.act), id(policy.init_carry), int(max_steps))
    if cache_key in _ROLLOUTS:
        return _ROLLOUTS[cache_key][0]
    import jax
    import jax.numpy as jnp

    def one_trial(params, key, position, yaw, goal):
        k_reset, k_policy = jax.random.split(key)
        state0 = env.reset_to(k_reset, position, yaw, goal)
        carry0 = policy.init_carry()

        def body(c, k):
            state, pcarry, done = c
            new_pcarry, action = policy.act(params, pcarry, state.obs, state.info, k)
            new_state = env.step(state, action)
            keep = lambda new, old: jnp.where(done, old, new)
            next_state = jax.tree.map(keep, new_state, state)
            next_pcarry = jax.tree.map(keep, new_pcarry, pcarry)
            rec = {"position": next_state.info["position"], "underwater_before": state.info["underwater"],
                   "taken": ~done, "action": jnp.where(done, 0.0, jnp.asarray(action, jnp.float32)),
                   "reward": jnp.where(done, 0.0, new_state.reward)}
            return (next_state, next_pcarry, done | new_state.done), rec

        keys = jax.random.split(k_policy, max_steps)
        (final, _, _), rec = jax.lax.scan(body, (state0, carry0, jnp.zeros((), bool)), keys)
        info = final.info
        return {
            "positions": jnp.concatenate([state0.info["position"][None], rec["position"]], 0),
            "underwater_before": rec["underwater_before"], "taken": rec["taken"], "actions": rec["action"],
            "rewards": rec["reward"],
            "arrived": info["arrived"], "collision": info["collision"], "out_of_bounds": info["out_of_bounds"],
            "terminated": info["terminated"], "final_distance": info["distance"],
        }

    fn = jax.jit(jax.vmap(one_trial, in_axes=(None, 0, 0, 0, None)))
    _ROLLOUTS[cache_key] = (fn, env, policy)  # keep env/policy alive so the ids stay unique
    return fn


def run_trials(env, policy, start, goal, key, num_trials: int, max_steps: int = 500,
               yaw: float = 0.0, spec: TrialSpec = TrialSpec()) -> dict[str, np.ndarray]:
    """Runs `num_trials` trials of `policy` from (jittered) `start` to `goal` as one vmapped rollout.

    Returns numpy arrays, leading axis = trial: positions (N, T+1, 3) (frozen after the end),
    steps (N,), outcome (N,) index into OUTCOMES, t_air/t_water/time (N,) simulated seconds,
    path_length (N,), success/collision/out_of_bounds/timeout/diverged (N,) bool, final_distance,
    episode_return, start_positions (N, 3), start_yaws (N,), and the raw per-step records.
    """
    import jax
    if not getattr(env.params, "terminate_on_arrival", False):
        raise ValueError("run_trials needs an env with terminate_on_arrival=True (use make_eval_env)")
    if num_trials <= 0:
        raise ValueError(f"num_trials={num_trials}: must be a positive integer")
    if max_steps <= 0:
        raise ValueError(f"max_steps={max_steps}: must be a positive integer")
    k_start, k_trials = jax.random.split(key)
    positions, yaws = trial_starts(k_start, start, num_trials, yaw, spec)
    keys = jax.random.split(k_trials, num_trials)
    fn = make_rollout(env, policy, max_steps)
    out = jax.device_get(fn(policy.params, keys, positions, yaws, jax.numpy.asarray(goal, jax.numpy.float32)))
    out = {k: np.asarray(v) for k, v in out.items()}
    return _trial_metrics(out, env.control_dt, np.asarray(positions), np.asarray(yaws))


def _trial_metrics(out: dict[str, np.ndarray], dt: float, start_positions, start_yaws) -> dict[str, np.ndarray]:
    taken = out["taken"].astype(bool)                       # (N, T)
    water = out["underwater_before"].astype(bool)
    steps = taken.sum(1)
    success = out["arrived"].astype(bool)
    collision = out["collision"].astype(bool) & ~success
    oob = out["out_of_bounds"].astype(bool) & ~success & ~collision
    diverged = out["terminated"].astype(bool) & ~success & ~collision & ~oob
    timeout = ~success & ~out["terminated"].astype(bool)
    outcome = np.select([success, collision, oob, timeout, diverged], [0, 1, 2, 3, 4], 4)
    disp = np.linalg.norm(np.diff(out["positions"], axis=1), axis=-1)   # (N, T), zero after the end
    res = dict(out)
    res.update(
        steps=steps, time=steps * dt, t_air=(taken & ~water).sum(1) * dt, t_water=(taken & water).sum(1) * dt,
        path_length=(disp * taken).sum(1), success=success, collision=collision, out_of_bounds=oob,
        timeout=timeout, diverged=diverged, outcome=outcome, episode_return=out["rewards"].sum(1),
        start_positions=start_positions, start_yaws=start_yaws)
    return res


def _mean_std(x: np.ndarray) -> tuple[float, float]:
    if x.size == 0:
        return float("nan"), float("nan")
    return float(np.mean(x)), float(np.std(x))


def summarize(trials: dict[str, np.ndarray]) -> dict[str, Any]:
    """Counts and mean/std over successful trials (the paper's statistics) of one `run_trials` result."""
    ok = trials["success"]
    s: dict[str, Any] = {"trials": int(ok.size), "successes": int(ok.sum()),
                         "success_rate": float(ok.mean()) if ok.size else float("nan"),
                         "collisions": int(trials["collision"].sum()),
                         "out_of_bounds": int(trials["out_of_bounds"].sum()),
                         "timeouts": int(trials["timeout"].sum()), "diverged": int(trials["diverged"].sum())}
    for name in ("t_air", "t_water", "time", "path_length"):
        s[f"{name}_mean"], s[f"{name}_std"] = _mean_std(trials[name][ok])
    s["path_length_all_mean"], s["path_length_all_std"] = _mean_std(trials["path_length"])
    s["final_distance_mean"], s["final_distance_std"] = _mean_std(trials["final_distance"])
    return s


# ---------------------------------------------------------------------------------------- tables

def _pm(mean: float, std: float, digits: int = 2) -> str:
    if mean is None or not np.isfinite(mean):
        return "–"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


def markdown_table(rows: Sequence[dict[str, Any]], paper: bool = True, seed_rows: Sequence[dict] = ()) -> str:
    """Markdown tables in the paper's format (Test | t_air (s) | t_water (s) | Success), one per
    scenario, with our extra columns, and the paper's published rows beside ours (scenario 2).
    `seed_rows` (from `aggregate_seeds`) adds a table of mean and spread over seeds."""
    from docrl_jax import paper_results
    out = [markdown_seed_table(list(seed_rows))] if seed_rows else []
    if seed_rows:
        out.append("## Per seed\n")
    for scen in sorted({r["scenario"] for r in rows}):
        out.append(f"### Scenario {scen}\n")
        out.append("| Test | t_air (s) | t_water (s) | Success | Collisions | Out of bounds | Time-outs | "
                   "Path (m) |")
        out.append("|---|---|---|---|---|---|---|---|")
        for r in rows:
            if r["scenario"] != scen:
                continue
            seed = "" if r.get("seed_index") is None else f" #{r['seed_index']}"
            out.append(f"| {SHORT[r['direction']]} {r['method']}{seed} | {_pm(r['t_air_mean'], r['t_air_std'])} | "
                       f"{_pm(r['t_water_mean'], r['t_water_std'])} | {r['successes']}/{r['trials']} | "
                       f"{r['collisions']} | {r['out_of_bounds']} | {r['timeouts']} | "
                       f"{_pm(r['path_length_mean'], r['path_length_std'])} |")
        if paper and scen == paper_results.TABLE_I_SCENARIO:
            for p in paper_results.TABLE_I:
                out.append(f"| {SHORT[p['direction']]} {p['method']} (paper) | {_pm(p['t_air'][0], p['t_air'][1])} | "
                           f"{_pm(p['t_water'][0], p['t_water'][1])} | {p['success']}/100 | | | | |")
        out.append("")
    if paper:
        out.append(paper_results.NOTE)
    return "\n".join(out) + "\n"


CSV_FIELDS = ("method", "seed_index", "scenario", "direction", "trials", "successes", "success_rate", "collisions",
              "out_of_bounds", "timeouts", "diverged", "t_air_mean", "t_air_std", "t_water_mean", "t_water_std",
              "time_mean", "time_std", "path_length_mean", "path_length_std", "path_length_all_mean",
              "path_length_all_std", "final_distance_mean", "final_distance_std", "compile_s", "run_s")
TRIAL_FIELDS = ("method", "seed_index", "scenario", "direction", "trial", "outcome", "steps", "time", "t_air", "t_water",
                "path_length", "final_distance", "episode_return", "start_x", "start_y", "start_z", "start_yaw")


def write_outputs(out_dir: Path, rows: list[dict], trial_rows: list[dict], meta: dict,
                  seed_rows: Sequence[dict] = ()) -> None:
    """results.md (tables), results.csv (one row per scenario, direction and seed), trials.csv (one
    row per trial), results.json (all of it, plus the run's settings in "meta")."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "results.md").write_text(markdown_table(rows, seed_rows=seed_rows))
    r4 = lambda d: {k: round(v, 4) if isinstance(v, float) and math.isfinite(v) else v for k, v in d.items()}
    rows, seed_rows = [r4(r) for r in rows], [r4(r) for r in seed_rows]
    with open(out_dir / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    with open(out_dir / "trials.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=TRIAL_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(trial_rows)

    def clean(x):
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x
    (out_dir / "results.json").write_text(json.dumps(clean({"meta": meta, "results": rows, "over_seeds": list(seed_rows),
                                                            "trials": trial_rows}),
                                                     indent=1))


def trial_table(method: str, scenario: int, direction: str, trials: dict[str, np.ndarray]) -> list[dict]:
    rows = []
    for i in range(trials["success"].size):
        sp = trials["start_positions"][i]
        rows.append({"method": method, "scenario": scenario, "direction": direction, "trial": i,
                     "outcome": OUTCOMES[int(trials["outcome"][i])], "steps": int(trials["steps"][i]),
                     "time": round(float(trials["time"][i]), 4), "t_air": round(float(trials["t_air"][i]), 4),
                     "t_water": round(float(trials["t_water"][i]), 4),
                     "path_length": round(float(trials["path_length"][i]), 4),
                     "final_distance": round(float(trials["final_distance"][i]), 4),
                     "episode_return": round(float(trials["episode_return"][i]), 4),
                     "start_x": round(float(sp[0]), 4), "start_y": round(float(sp[1]), 4),
                     "start_z": round(float(sp[2]), 4), "start_yaw": round(float(trials["start_yaws"][i]), 4)})
    return rows


# ---------------------------------------------------------------------------------------- CLI

class UsageError(ValueError):
    """A bad command line; the message lists the valid choices."""


def parse_scenarios(text: str) -> list[int]:
    try:
        vals = [int(t) for t in text.split(",") if t.strip() != ""]
    except ValueError:
        raise UsageError(f"--scenarios {text!r}: valid scenarios are 1, 2, 3 (comma-separated, e.g. 1,2,3)") from None
    bad = [v for v in vals if v not in SCENARIOS]
    if not vals or bad:
        raise UsageError(f"--scenarios {text!r}: valid scenarios are 1, 2, 3 (comma-separated, e.g. 1,2,3)")
    return sorted(set(vals))


def parse_directions(text: str) -> list[str]:
    aliases = {"a-w": "air_to_water", "w-a": "water_to_air", "air_to_water": "air_to_water",
               "water_to_air": "water_to_air"}
    vals = [t.strip().lower() for t in text.split(",") if t.strip()]
    bad = [v for v in vals if v not in aliases]
    if not vals or bad:
        raise UsageError(f"--directions {text!r}: valid directions are air_to_water (A-W), water_to_air (W-A)")
    return list(dict.fromkeys(aliases[v] for v in vals))


def parse_env_overrides(items: Sequence[str]) -> dict[str, Any]:
    from docrl_jax.envs import param_docs
    valid = param_docs()
    out = {}
    for item in items:
        if "=" not in item:
            raise UsageError(f"--env {item!r}: expected KEY=VALUE, e.g. --env sensor_noise_std=0.02")
        k, v = item.split("=", 1)
        if k not in valid:
            raise UsageError(f"--env {k!r}: unknown env parameter; valid names: {', '.join(sorted(valid))}")
        if k in ("terminate_on_arrival", "max_episode_steps", "scenario"):
            raise UsageError(f"--env {k}: set by the evaluator (use --max-steps / --scenarios)")
        out[k] = yaml.safe_load(v)
    return out


def build_parser() -> argparse.ArgumentParser:
    from docrl_jax.policy import CHECKPOINT_POLICIES
    p = argparse.ArgumentParser(prog="python -m docrl_jax.evaluate", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group()
    src.add_argument("--run", metavar="RUN_DIR", nargs="+",
                     help="a trainer run directory (config.yaml + checkpoints); several run directories of one "
                          "config (separate launches, e.g. one per seed) are evaluated as the seeds of one method")
    src.add_argument("--policy", metavar="NAME", help=f"a built-in policy: {', '.join(POLICIES)}")
    p.add_argument("--seed-index", default="all",
                   help="seed(s) of --run to evaluate, comma-separated, e.g. 0 or 0,1,2; default 'all': every seed "
                        "the run trained (train.num_seeds in its config.yaml). Several seeds also give a table of "
                        "mean and spread over seeds. With several run directories each gives these seeds, "
                        "numbered 0, 1, ... in the order given (results.json maps them back)")
    p.add_argument("--which", default="final", choices=CHECKPOINT_POLICIES,
                   help="with --run: the final policy of the latest checkpoint (default; what tables report) "
                        "or each seed's best evaluated policy kept beside it (train.track_best_policy)")
    p.add_argument("--label", help="method name in the tables (default: 'BBA' or the run dir's name)")
    p.add_argument("--trials", type=int, default=100, help="trials per scenario and direction (default 100)")
    p.add_argument("--scenarios", default="1,2,3", help="comma-separated scenarios (default 1,2,3)")
    p.add_argument("--directions", default="air_to_water,water_to_air",
                   help="comma-separated: air_to_water (A-W), water_to_air (W-A) (default both)")
    p.add_argument("--max-steps", type=int, default=500, help="step limit of a trial (default 500, the paper's)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of the trials (default 0)")
    p.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                   help=f"env parameter override (repeatable); defaults here: {DEFAULT_EVAL_ENV}")
    p.add_argument("--bba-depth-phase", default="after", help="BBA only, order of the depth phase: after (default, the DoCRL script), first (the JINT copy), concurrent, in_air (climb first / descend last)")
    p.add_argument("--out", default="eval_out", help="output directory (default ./eval_out)")
    p.add_argument("--figures", type=int, default=10, metavar="K",
                   help="trajectories drawn per figure (0 = no trajectory figures; default 10)")
    p.add_argument("--curves", nargs="+", metavar="RUN_DIR",
                   help="also plot learning curves from these run dirs' metrics.csv (or metrics.csv files)")
    return p


def validate_args(args: argparse.Namespace) -> dict[str, Any]:
    """Checks the command line before anything is compiled; raises UsageError naming valid choices."""
    from docrl_jax.baselines.bba import DEPTH_PHASES
    from docrl_jax.policy import RunDirError
    if args.run is None and args.policy is None and not args.curves:
        raise UsageError("nothing to do: give --run RUN_DIR or --policy NAME "
                         f"(valid policies: {', '.join(POLICIES)}), and/or --curves RUN_DIR ...")
    if args.policy is not None and args.policy.lower() not in POLICIES:
        raise UsageError(f"--policy {args.policy!r}: unknown policy; valid choices: {', '.join(POLICIES)} "
                         "(or --run RUN_DIR for a trained agent)")
    if args.trials <= 0:
        raise UsageError(f"--trials {args.trials}: must be a positive integer")
    if args.max_steps <= 0:
        raise UsageError(f"--max-steps {args.max_steps}: must be a positive integer")
    if args.bba_depth_phase not in DEPTH_PHASES:
        raise UsageError(f"--bba-depth-phase {args.bba_depth_phase!r}: valid choices are {', '.join(DEPTH_PHASES)}")
    cfg = {"scenarios": parse_scenarios(args.scenarios), "directions": parse_directions(args.directions),
           "env": parse_env_overrides(args.env), "seed_indices": parse_seed_indices(args.seed_index)}
    for run in args.run or []:
        check_run_dir(run)
        if cfg["seed_indices"] is None:
            run_num_seeds(run)   # a readable train.num_seeds, checked before any compile
    if args.run and len(args.run) > 1 and args.label is None:
        names = {config_name(run) for run in args.run}
        if len(names) != 1:
            raise UsageError(f"--run: the run directories hold different configs ({', '.join(sorted(names))}); "
                             "evaluate one config at a time, or name the method with --label")
    from docrl_jax.plotting import find_metrics_csv  # evaluate -> plotting, never the other way
    for d in args.curves or []:
        try:
            find_metrics_csv(d)
        except RunDirError as e:
            raise UsageError(str(e)) from None
    return cfg


def _run_config(run_dir: str | os.PathLike) -> dict:
    with open(Path(run_dir) / "config.yaml") as f:
        return yaml.safe_load(f) or {}


def check_run_dir(run_dir: str | os.PathLike) -> Path:
    """Cheap checks of a run directory before load_policy: exists, is a directory, has config.yaml."""
    from docrl_jax.policy import RunDirError
    path = Path(run_dir)
    if not path.exists():
        raise RunDirError(f"run directory {str(path)!r} does not exist")
    if not path.is_dir():
        raise RunDirError(f"run directory {str(path)!r} is not a directory")
    if not (path / "config.yaml").is_file():
        found = sorted(x.name for x in path.iterdir())[:20]
        raise RunDirError(f"run directory {str(path)!r} has no config.yaml (is it a trainer run dir? "
                          f"it contains: {found or 'nothing'})")
    return path


def evaluate_policy(policy, method: str = "policy", scenarios: Sequence[int] = SCENARIOS,
                    directions: Sequence[str] = DIRECTIONS, num_trials: int = 100, max_steps: int = 500,
                    seed: int = 0, env_overrides: dict | None = None, seed_index: int | None = None,
                    on_result=None) -> list[tuple[dict, dict]]:
    """The whole protocol for one policy: for each scenario and direction, `num_trials` trials.

    Returns [(row, trials)]: `row` = `summarize` plus method, seed_index, scenario, direction and the
    seconds taken (`compile_s` when this call compiled the rollout, else `run_s`); `trials` = the
    `run_trials` arrays. The trial seeds depend only on (seed, scenario, direction), so every method
    and seed index meets the same wind, noise and start jitter. `on_result(row, trials, env, start,
    goal)` is called after each (scenario, direction)."""
    import jax
    import docrl_jax.envs as envs
    base = jax.random.PRNGKey(seed)
    results = []
    for scenario in scenarios:
        env = make_eval_env(scenario, max_steps, **(env_overrides or {}))
        for direction in directions:
            start, goal = envs.eval_pair(scenario, direction)
            key = jax.random.fold_in(jax.random.fold_in(base, scenario), DIRECTIONS.index(direction))
            fresh = (id(env), id(policy.act), id(policy.init_carry), int(max_steps)) not in _ROLLOUTS
            t0 = time.time()
            trials = run_trials(env, policy, start, goal, key, num_trials, max_steps, NOMINAL_YAW[direction])
            elapsed = round(time.time() - t0, 2)
            row = {"method": method, "seed_index": seed_index, "scenario": scenario, "direction": direction,
                   **summarize(trials), "compile_s": elapsed if fresh else None, "run_s": None if fresh else elapsed}
            if on_result is not None:
                on_result(row, trials, env, start, goal)
            results.append((row, trials))
    return results


def parse_seed_indices(text: str) -> list[int] | None:
    """The --seed-index list; None for 'all' (every seed of each run, see policy_sources)."""
    if str(text).strip().lower() == "all":
        return None
    try:
        vals = [int(t) for t in str(text).split(",") if t.strip() != ""]
    except ValueError:
        raise UsageError(f"--seed-index {text!r}: expected 'all' or integers >= 0, comma-separated (e.g. 0 or 0,1,2)") from None
    if not vals or any(v < 0 for v in vals):
        raise UsageError(f"--seed-index {text!r}: expected 'all' or integers >= 0, comma-separated (e.g. 0 or 0,1,2)")
    return list(dict.fromkeys(vals))


def config_name(run_dir: str | os.PathLike) -> str:
    """The `name` in a run directory's config.yaml (its folder's name if it has none)."""
    return str(_run_config(run_dir).get("name") or Path(run_dir).resolve().name)


def run_num_seeds(run_dir: str | os.PathLike) -> int:
    """How many seeds a run directory trained (vmapped in one process): train.num_seeds of its config.yaml."""
    train = _run_config(run_dir).get("train") or {}
    try:
        return max(1, int(train.get("num_seeds", 1)))
    except (TypeError, ValueError):
        raise UsageError(f"{run_dir}: config.yaml has train.num_seeds={train.get('num_seeds')!r}, "
                         "not a positive integer; pass --seed-index explicitly") from None


def policy_sources(args, seed_indices: list[int] | None) -> list[tuple[str, int]]:
    """(run dir, seed index within it) for each evaluated seed of --run, in the order given;
    seed_indices None = every seed each run trained."""
    return [(run, s) for run in args.run
            for s in (seed_indices if seed_indices is not None else range(run_num_seeds(run)))]


def load_policy_for(args, env_params, seed_index: int, run: str | None = None) -> tuple[Any, str]:
    """(policy, label) for --policy or for one seed of the run directory `run` (the trainer is imported
    lazily). Several run directories are labelled by their config's name, one by its folder's name."""
    from docrl_jax.policy import RunDirError
    if args.policy is not None:
        from docrl_jax.baselines.bba import make_bba
        default = "BBA" if args.bba_depth_phase == "after" else f"BBA ({args.bba_depth_phase})"
        return make_bba(env_params, depth_phase=args.bba_depth_phase), args.label or default
    try:
        from docrl_jax.train import load_policy  # lazily: baselines need no trainer
    except ImportError as e:
        raise RunDirError(f"--run needs the trainer module docrl_jax.train, which cannot be imported here ({e}); "
                          f"built-in policies work without it: --policy {', '.join(POLICIES)}") from None
    policy = load_policy(run, seed_index=seed_index, which=args.which)
    print(f"{Path(run).name}: {policy.source}", flush=True)
    name = config_name(run) if len(args.run) > 1 else Path(run).resolve().name
    return policy, args.label or name + (" (best)" if args.which == "best" else "")


def aggregate_seeds(rows: list[dict]) -> list[dict]:
    """One row per (method, scenario, direction) over seeds: success mean/std over seeds (counts and
    rates), and t_air/t_water/path pooled over every seed's successful trials (weighted by successes)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["method"], r["scenario"], r["direction"]), []).append(r)
    out = []
    for (method, scen, direction), rs in groups.items():
        succ = np.array([r["successes"] for r in rs], float)
        rate = np.array([r["success_rate"] for r in rs], float)
        agg = {"method": method, "scenario": scen, "direction": direction, "seeds": [r["seed_index"] for r in rs],
               "trials": rs[0]["trials"], "successes_mean": float(succ.mean()), "successes_std": float(succ.std()),
               "successes_per_seed": [int(x) for x in succ], "success_rate_mean": float(rate.mean()),
               "success_rate_std": float(rate.std())}
        for key in ("collisions", "out_of_bounds", "timeouts"):
            agg[f"{key}_mean"] = float(np.mean([r[key] for r in rs]))
        for name in ("t_air", "t_water", "time", "path_length"):
            # pooled mean/std from per-seed (n, mean, std): exact for population statistics
            n = np.array([r["successes"] for r in rs], float)
            m = np.array([r[f"{name}_mean"] if r["successes"] else 0.0 for r in rs], float)
            sd = np.array([r[f"{name}_std"] if r["successes"] else 0.0 for r in rs], float)
            if n.sum() == 0:
                agg[f"{name}_mean"] = agg[f"{name}_std"] = float("nan")
            else:
                mu = float((n * m).sum() / n.sum())
                agg[f"{name}_mean"] = mu
                agg[f"{name}_std"] = float(np.sqrt((n * (sd ** 2 + (m - mu) ** 2)).sum() / n.sum()))
        out.append(agg)
    return out


def markdown_seed_table(aggs: list[dict]) -> str:
    out = ["## Over seeds\n", "Success: mean ± std over seeds (per seed in brackets); times and path: pooled over "
           "every seed's successful trials.\n"]
    for scen in sorted({a["scenario"] for a in aggs}):
        out.append(f"### Scenario {scen}\n")
        out.append("| Test | t_air (s) | t_water (s) | Success | Seeds | Path (m) |")
        out.append("|---|---|---|---|---|---|")
        for a in aggs:
            if a["scenario"] != scen:
                continue
            out.append(f"| {SHORT[a['direction']]} {a['method']} | {_pm(a['t_air_mean'], a['t_air_std'])} | "
                       f"{_pm(a['t_water_mean'], a['t_water_std'])} | {_pm(a['successes_mean'], a['successes_std'], 1)}"
                       f"/{a['trials']} {a['successes_per_seed']} | {len(a['seeds'])} | "
                       f"{_pm(a['path_length_mean'], a['path_length_std'])} |")
        out.append("")
    return "\n".join(out) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from docrl_jax.policy import RunDirError
    try:
        cfg = validate_args(args)
    except (UsageError, RunDirError) as e:
        parser.error(str(e))  # exits with status 2 and the usage line
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    if args.curves:
        from docrl_jax import plotting
        csvs = [plotting.find_metrics_csv(d) for d in args.curves]
        paths = plotting.plot_learning_curves(csvs, out_dir)
        print("learning curves:", ", ".join(str(p) for p in paths))
    if args.run is None and args.policy is None:
        return 0

    import jax
    if args.run is None:
        sources, seed_indices = [(None, None)], [None]
    else:   # one run: its own seed indices; several: the evaluated seeds numbered 0, 1, ... in order
        sources = policy_sources(args, cfg["seed_indices"])
        seed_indices = [s for _, s in sources] if len(args.run) == 1 else list(range(len(sources)))
    # Each run's agent settings: runs with the same ones share their networks (and compiled rollout).
    agents = {run: json.dumps(_run_config(run).get("agent"), sort_keys=True) for run in args.run or []}
    rows, trial_rows = [], []
    meta = {"command": " ".join(["python -m docrl_jax.evaluate", *(argv if argv is not None else sys.argv[1:])]),
            "run": args.run, "which": args.which if args.run else None, "policy": args.policy,
            "seed_indices": seed_indices, "policy_sources": {},
            "seed_runs": {str(i): {"run": run, "seed_index": s} for i, (run, s) in zip(seed_indices, sources)}
            if args.run is not None else {}, "trials": args.trials,
            "max_steps": args.max_steps, "seed": args.seed, "env_overrides": {**DEFAULT_EVAL_ENV, **cfg["env"]},
            "trial_spec": asdict(TrialSpec()), "nominal_yaw": NOMINAL_YAW,
            "bba_depth_phase": args.bba_depth_phase if args.policy else None,
            "jax_backend": jax.default_backend(), "devices": [str(d) for d in jax.devices()]}
    policies: dict = {}
    first_with_nets: dict = {}   # agent settings -> the first policy loaded with them
    t_start = time.time()

    def report(row, trials, env, start, goal):
        seed_index = row["seed_index"]
        tag = "" if seed_index is None else f" seed {seed_index}"
        fresh = row["compile_s"] is not None
        print(f"scenario {row['scenario']} {SHORT[row['direction']]} {row['method']}{tag}: {row['successes']}/"
              f"{row['trials']} success, {row['collisions']} collisions, {row['out_of_bounds']} out of bounds, "
              f"{row['timeouts']} time-outs ({row['compile_s'] if fresh else row['run_s']:.1f} s"
              f"{' incl. compile' if fresh else ''})", flush=True)
        stem = f"s{row['scenario']}_{row['direction']}" + ("" if seed_index is None else f"_seed{seed_index}")
        np.savez_compressed(out_dir / f"trajectories_{stem}.npz", positions=trials["positions"].astype(np.float32),
                            steps=trials["steps"], outcome=trials["outcome"], start=np.asarray(start),
                            goal=np.asarray(goal))
        if args.figures > 0:
            from docrl_jax import plotting
            plotting.plot_trajectories(env.mj_model, trials["positions"], trials["steps"], trials["outcome"],
                                       start, goal, out_dir / f"trajectory_{stem}.png",
                                       title=f"{row['method']}{tag}, scenario {row['scenario']}, "
                                             f"{SHORT[row['direction']]}", max_trajectories=args.figures)

    for scenario in cfg["scenarios"]:
        env = make_eval_env(scenario, args.max_steps, **cfg["env"])
        for seed_index, (run, run_seed) in zip(seed_indices, sources):
            if seed_index not in policies:
                try:
                    policy, method = load_policy_for(args, env.params, run_seed, run)
                except RunDirError as e:
                    parser.error(str(e))
                # Seeds with the same agent settings share their networks: keep the first one's
                # functions so the compiled rollout (cached per act function) serves every seed.
                nets = agents.get(run)
                if nets in first_with_nets:
                    policy = replace(first_with_nets[nets], params=policy.params, source=policy.source)
                else:
                    first_with_nets[nets] = policy
                policies[seed_index] = (policy, method)
                if policy.source:
                    meta["policy_sources"][str(seed_index)] = policy.source
            policy, method = policies[seed_index]
            for row, trials in evaluate_policy(policy, method, [scenario], cfg["directions"], args.trials,
                                               args.max_steps, args.seed, cfg["env"], seed_index, report):
                rows.append(row)
                trial_rows += [{**t, "seed_index": seed_index}
                               for t in trial_table(method, scenario, row["direction"], trials)]
    meta["wall_time_s"] = round(time.time() - t_start, 2)
    aggs = aggregate_seeds(rows) if args.run is not None else []
    write_outputs(out_dir, rows, trial_rows, meta, aggs)
    print(markdown_table(rows, seed_rows=aggs))
    print(f"wrote {out_dir}/results.md, results.csv, results.json, trials.csv ({meta['wall_time_s']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
