"""The paper's evaluation protocol: N trials per scenario and direction, Table I, CSV/JSON, figures.

    python -m docrl_jax.evaluate --policy bba --trials 100 --scenarios 1,2,3 --out results/bba
    python -m docrl_jax.evaluate --run runs/docrl_d --seed-index 0 --out results/docrl_d
    python -m docrl_jax.evaluate --run runs/td3_seed0 runs/td3_seed1 runs/td3_seed2 --out results/td3  # 3 launches
    python -m docrl_jax.evaluate --curves runs/docrl_d runs/docrl_s --out results/curves
    python -m docrl_jax.evaluate --run runs/docrl_d --tank gallery --trials 20 --out results/tanks

The protocol itself: `docrl_jax.evaluate.protocol`; the rollout and per-trial metrics: `rollout`;
statistics, tables and output files: `tables`; trials in a tank set (`--tank`): `tank_trials`. This
module is the command alone: its arguments, their checks (each bad input one line, before anything
compiles) and which policies of which runs are evaluated; it is over the package's ~350-line guide
because each of the four inputs (--policy, --run, --curves, --tank) brings its own checks.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import yaml

from docrl_jax import runs
from docrl_jax.errors import RunDirError, os_error_line
from docrl_jax.evaluate import rollout, tank_sets, tank_trials
from docrl_jax.evaluate.tank_sets import TankSetError
from docrl_jax.evaluate.protocol import DEFAULT_EVAL_ENV, NOMINAL_YAW, SCENARIOS, TrialSpec
from docrl_jax.evaluate.tables import SHORT, aggregate_seeds, markdown_table, trial_table, write_outputs

POLICIES = ("bba",)


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


# Env parameters the evaluator sets itself.
_EVALUATOR_KEYS = {"terminate_on_arrival": "--max-steps", "max_episode_steps": "--max-steps",
                   "scenario": "--scenarios", "tank": "--tank"}


def parse_env_value(text: str) -> Any:
    """An --env value as a user types it: YAML (true, [0.1, 0, 0], null), plus what YAML 1.1 leaves as
    text: numbers in exponent form (4e-5, 1e3) and tuples in parentheses ((0.1,0,0))."""
    text = text.strip()
    if text.startswith("(") and text.endswith(")"):
        text = "[" + text[1:-1] + "]"
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text

    def number(v):
        if isinstance(v, str):
            try:
                return float(v)
            except ValueError:
                return v
        return v
    if isinstance(value, list):
        return tuple(number(v) for v in value)
    return number(value)


def parse_env_overrides(items: Sequence[str], scenarios: Sequence[int] = SCENARIOS) -> dict[str, Any]:
    """--env KEY=VALUE items -> {key: value}, each checked against `EnvParams` for every scenario
    evaluated, so a bad value is a UsageError naming the key here, not a traceback at the first compile."""
    from docrl_jax.envs import param_docs
    from docrl_jax.envs.params import make_params
    valid = param_docs()
    out, typed = {}, {}
    for item in items:
        if "=" not in item:
            raise UsageError(f"--env {item!r}: expected KEY=VALUE, e.g. --env sensor_noise_std=0.02")
        k, v = item.split("=", 1)
        k = k.strip()
        if k not in valid:
            raise UsageError(f"--env {k!r}: unknown env parameter; valid names: {', '.join(sorted(valid))}")
        if k in _EVALUATOR_KEYS:
            raise UsageError(f"--env {k}: set by the evaluator (use {_EVALUATOR_KEYS[k]})")
        out[k], typed[k] = parse_env_value(v), v
    for scenario in scenarios:
        try:
            make_params(scenario, **{**DEFAULT_EVAL_ENV, **out})
        except (ValueError, TypeError) as e:
            # EnvParams' message reads "env parameter NAME=VALUE: why"; name the key as typed when it is one
            name, _, why = str(e).removeprefix("env parameter ").partition(": ")
            name = name.split("=", 1)[0]
            if name in out and why:
                raise UsageError(f"--env {name}={typed[name].strip()}: {why}") from None
            given = " ".join(f"{k}={v.strip()}" for k, v in typed.items())
            raise UsageError(f"--env {given} (scenario {scenario}): {e}") from None
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
    p.add_argument("--scenarios", default=None, help="comma-separated scenarios (default 1,2,3)")
    p.add_argument("--tank", metavar="PATH|DIR|NAME",
                   help="instead of the scenarios' paper pairs, trials in a tank set: a tank file, a folder of them, a "
                        "packaged tank's name, or gallery (every packaged tank; docs/TANKS.md). --trials per "
                        "direction, trial i in tank i mod the set's size, from a random start in the start medium's "
                        "region to a random goal in the other's, random yaw; a table per tank (printed, tanks.csv)")
    p.add_argument("--directions", default="air_to_water,water_to_air",
                   help="comma-separated: air_to_water (A-W), water_to_air (W-A) (default both)")
    p.add_argument("--max-steps", type=int, default=500, help="step limit of a trial (default 500, the paper's)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of the trials (default 0)")
    p.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                   help="env parameter override (repeatable), e.g. hull_volume=4e-5, water_current=(0.1,0,0) or "
                        f"[0.1,0,0], wind=false; checked before anything runs; defaults here: {DEFAULT_EVAL_ENV}")
    p.add_argument("--bba-depth-phase", default="after", help="BBA only, order of the depth phase: after (default, the DoCRL script), first (the JINT copy), concurrent, in_air (climb first / descend last)")
    p.add_argument("--out", metavar="DIR",
                   help="output directory (results.md/.csv/.json, trials.csv, trajectories, figures). Default "
                        "with --run: <first RUN_DIR>/evaluation; with --policy: none, the tables are printed and "
                        "nothing is written; --curves needs --out (or --run)")
    p.add_argument("--figures", type=int, default=10, metavar="K",
                   help="trajectories drawn per figure (0 = no trajectory figures; default 10)")
    p.add_argument("--curves", nargs="+", metavar="RUN_DIR",
                   help="also plot learning curves from these run dirs' metrics.csv (or metrics.csv files)")
    return p


def validate_args(args: argparse.Namespace) -> dict[str, Any]:
    """Checks the command line before anything is compiled; raises UsageError naming valid choices."""
    from docrl_jax.baselines.bba import DEPTH_PHASES
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
    if args.tank is not None and args.scenarios is not None:
        raise UsageError(f"--tank {args.tank} and --scenarios {args.scenarios}: a tank set's trials replace the "
                         "scenarios' (they fly in scenario 0); give one of them")
    scenarios = [0] if args.tank is not None else parse_scenarios(args.scenarios or "1,2,3")
    cfg = {"scenarios": scenarios, "directions": parse_directions(args.directions),
           "env": parse_env_overrides(args.env, scenarios), "seed_indices": parse_seed_indices(args.seed_index),
           "out": output_dir(args)}
    cfg["tank"] = args.tank
    if args.tank is not None:
        bad = [k for k in rollout.MEDIA_KEYS if k in cfg["env"]]   # --tank forces them per direction
        if bad:
            raise UsageError(f"--env {bad[0]}: set by --tank (A-W starts in air and ends under water, W-A the reverse)")
        cfg["tank_names"] = tank_sets.check(args.tank, rollout.eval_params(0, args.max_steps, **cfg["env"]))
    if args.curves and cfg["out"] is None:
        raise UsageError("--curves writes learning_curves.png: give --out DIR")
    for run in args.run or []:
        check_run_dir(run)
        if cfg["seed_indices"] is None:
            run_num_seeds(run)   # a readable train.num_seeds, checked before any compile
    if args.run and len(args.run) > 1 and args.label is None:
        names = {config_name(run) for run in args.run}
        if len(names) != 1:
            raise UsageError(f"--run: the run directories hold different configs ({', '.join(sorted(names))}); "
                             "evaluate one config at a time, or name the method with --label")
    from docrl_jax.evaluate.curves import find_metrics_csv
    for d in args.curves or []:
        try:
            find_metrics_csv(d)
        except RunDirError as e:
            raise UsageError(str(e)) from None
    return cfg


def output_dir(args: argparse.Namespace) -> Path | None:
    """--out; with --run and no --out, <first run dir>/evaluation; otherwise None (write nothing)."""
    if args.out is not None:
        return Path(args.out)
    if args.run:
        return Path(args.run[0]) / "evaluation"
    return None


def _run_config(run_dir: str | os.PathLike) -> dict:
    # Plain YAML rather than runs.read_config: only name, train.num_seeds and agent are read here, and
    # a config of an older version still gets its policy loaded (or a precise error) by load_policy.
    with open(Path(run_dir) / runs.CONFIG_FILE) as f:
        return yaml.safe_load(f) or {}


def run_vehicle(run_dir: str | os.PathLike | None) -> dict:
    """The vehicle settings of a run's config.yaml (`envs.params.VEHICLE_FIELDS`, e.g. env.vel_i_rate),
    which its policy is flown in; {} for a built-in policy (run_dir None)."""
    from docrl_jax.envs.params import vehicle_overrides
    return {} if run_dir is None else vehicle_overrides(_run_config(run_dir).get("env") or {})


def check_run_dir(run_dir: str | os.PathLike) -> Path:
    """Cheap checks of a run directory before load_policy: exists, is a directory, has config.yaml."""
    path = Path(run_dir)
    if not path.exists():
        raise RunDirError(f"run directory {str(path)!r} does not exist")
    if not path.is_dir():
        raise RunDirError(f"run directory {str(path)!r} is not a directory")
    if not (path / runs.CONFIG_FILE).is_file():
        found = sorted(x.name for x in path.iterdir())[:20]
        raise RunDirError(f"run directory {str(path)!r} has no config.yaml (is it a trainer run dir? "
                          f"it contains: {found or 'nothing'})")
    return path


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


def load_policy_for(args, env, seed_index: int, run: str | None = None) -> tuple[Any, str]:
    """(policy, label) for --policy or for one seed of the run directory `run`. Several run directories
    are labelled by their config's name, one by its folder's name."""
    if args.policy is not None:
        from docrl_jax.evaluate.rollout import policy_for   # one BBA per env: the renderer's and benchmark's too
        policy, label = policy_for(env, None, 0, "final", args.bba_depth_phase)
        return policy, args.label or label
    policy = runs.load_policy(run, seed_index=seed_index, which=args.which)
    print(f"{Path(run).name}: {policy.source}", flush=True)
    name = config_name(run) if len(args.run) > 1 else Path(run).resolve().name
    return policy, args.label or name + (" (best)" if args.which == "best" else "")


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        cfg = validate_args(args)
    except (UsageError, RunDirError) as e:
        parser.error(str(e))  # exits with status 2 and the usage line
    except TankSetError as e:   # a tank file's error: its own line, no usage block
        parser.exit(2, f"{parser.prog}: error: {e}\n")
    try:
        return _evaluate(args, cfg, parser, argv)
    except OSError as e:  # an output folder that cannot be written: one line, as the other bad inputs
        print(f"error: {os_error_line(e)}", file=sys.stderr)
        return 2


def _evaluate(args, cfg: dict, parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> int:
    """Runs what the checked arguments ask for: curves, then the protocol's trials; writes the outputs."""
    out_dir = cfg["out"]
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
    if args.curves:
        from docrl_jax.evaluate import curves
        csvs = [curves.find_metrics_csv(d) for d in args.curves]
        paths = curves.plot_learning_curves(csvs, out_dir)
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
    vehicles = {seed_index: run_vehicle(run) for seed_index, (run, _) in zip(seed_indices, sources)}
    rows, trial_rows, tank_rows = [], [], []
    meta = {"command": " ".join(["python -m docrl_jax.evaluate", *(argv if argv is not None else sys.argv[1:])]),
            "run": args.run, "which": args.which if args.run else None, "policy": args.policy,
            "seed_indices": seed_indices, "policy_sources": {},
            "seed_runs": {str(i): {"run": run, "seed_index": s} for i, (run, s) in zip(seed_indices, sources)}
            if args.run is not None else {}, "trials": args.trials,
            "max_steps": args.max_steps, "seed": args.seed, "env_overrides": {**DEFAULT_EVAL_ENV, **cfg["env"]},
            "vehicles": {str(i): vehicle for i, vehicle in vehicles.items()},
            "trial_spec": asdict(TrialSpec()), "nominal_yaw": NOMINAL_YAW,
            "bba_depth_phase": args.bba_depth_phase if args.policy else None,
            "tank": args.tank, "tank_names": cfg.get("tank_names"),
            "jax_backend": jax.default_backend(), "devices": [str(d) for d in jax.devices()]}
    policies: dict = {}
    first_with_nets: dict = {}   # agent settings -> the first policy loaded with them
    t_start = time.time()

    def report(row, trials, env, start, goal, stack=None):
        seed_index = row["seed_index"]
        tag = "" if seed_index is None else f" seed {seed_index}"
        fresh = row["compile_s"] is not None
        where = f"tanks {args.tank}" if args.tank else f"scenario {row['scenario']}"
        print(f"{where} {SHORT[row['direction']]} {row['method']}{tag}: {row['successes']}/"
              f"{row['trials']} success, {row['collisions']} collisions, {row['out_of_bounds']} out of bounds, "
              f"{row['timeouts']} time-outs ({row['compile_s'] if fresh else row['run_s']:.1f} s"
              f"{' incl. compile' if fresh else ''})", flush=True)
        if out_dir is None:
            return
        stem = f"s{row['scenario']}_{row['direction']}" + ("" if seed_index is None else f"_seed{seed_index}")
        extra = {"tank": trials["tank"], "tank_names": np.asarray(cfg["tank_names"])} if args.tank else {}
        np.savez_compressed(out_dir / f"trajectories_{stem}.npz", positions=trials["positions"].astype(np.float32),
                            steps=trials["steps"], outcome=trials["outcome"], start=np.asarray(start),
                            goal=np.asarray(goal), **extra)
        if args.figures > 0 and args.tank:
            tank_trials.plot_flown(out_dir / f"trajectory_{stem}", stack, cfg["tank_names"], trials,
                                   f"{row['method']}{tag}, {SHORT[row['direction']]}", args.figures)
        elif args.figures > 0:
            from docrl_jax.evaluate import plotting
            plotting.plot_trajectories(env.mj_model, trials["positions"], trials["steps"], trials["outcome"],
                                       start, goal, out_dir / f"trajectory_{stem}.png",
                                       title=f"{row['method']}{tag}, scenario {row['scenario']}, "
                                             f"{SHORT[row['direction']]}", max_trajectories=args.figures)

    for scenario in cfg["scenarios"]:
        for seed_index, (run, run_seed) in zip(seed_indices, sources):
            env_kw = rollout.flown_env(vehicles[seed_index], cfg["env"])
            env = rollout.make_eval_env(scenario, args.max_steps, **env_kw)
            if seed_index not in policies:
                try:
                    policy, method = load_policy_for(args, env, run_seed, run)
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
            if args.tank is not None:
                def tank_report(row, trials, per_tank, names, stack):
                    report(row, trials, env, trials["start_positions"], trials["goals"], stack)
                for row, trials, per_tank in tank_trials.evaluate_policy(
                        policy, method, args.tank, cfg["directions"], args.trials, args.max_steps, args.seed, env_kw,
                        seed_index, tank_report):
                    rows.append(row)
                    tank_rows += per_tank
                    trial_rows += [{**t, "seed_index": seed_index, "tank": cfg["tank_names"][i]} for t, i in
                                   zip(trial_table(method, 0, row["direction"], trials), trials["tank"])]
                continue
            for row, trials in rollout.evaluate_policy(policy, method, [scenario], cfg["directions"], args.trials,
                                                       args.max_steps, args.seed, env_kw, seed_index, report):
                rows.append(row)
                trial_rows += [{**t, "seed_index": seed_index}
                               for t in trial_table(method, scenario, row["direction"], trials)]
    meta["wall_time_s"] = round(time.time() - t_start, 2)
    aggs = aggregate_seeds(rows) if args.run is not None else []
    print(markdown_table(rows, paper=args.tank is None, seed_rows=aggs))
    if args.tank is not None:
        print(tank_trials.markdown(tank_rows, args.tank))
    if out_dir is None:
        print(f"nothing written: pass --out DIR to keep the tables, trials and figures ({meta['wall_time_s']} s)")
        return 0
    write_outputs(out_dir, rows, trial_rows, meta, aggs)
    tanks = ", " + ", ".join(p.name for p in tank_trials.write(out_dir, tank_rows, args.tank)) if args.tank else ""
    print(f"wrote {out_dir}/results.md, results.csv, results.json, trials.csv{tanks} ({meta['wall_time_s']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
