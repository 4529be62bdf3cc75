"""The paper's evaluation protocol: N trials per scenario and direction, Table I, CSV/JSON, figures.

    python -m docrl_jax.evaluate --policy td3_lstm --trials 20 --scenarios 2     # a shipped policy (CPU: ~1 min)
    python -m docrl_jax.evaluate --policy bba --trials 100 --scenarios 1,2,3 --out results/bba
    python -m docrl_jax.evaluate --run runs/docrl_d --seed-index 0 --out results/docrl_d
    python -m docrl_jax.evaluate --run runs/td3_seed0 runs/td3_seed1 runs/td3_seed2 --out results/td3  # 3 launches
    python -m docrl_jax.evaluate --curves runs/docrl_d runs/docrl_s --out results/curves
    python -m docrl_jax.evaluate --run runs/docrl_d --tank gallery --trials 20 --out results/tanks

The protocol itself: `docrl_jax.evaluate.protocol`; the rollout and per-trial metrics: `rollout`;
statistics, tables and output files: `tables`; trials in a tank set (`--tank`): `tank_trials`; the
shipped policies (`--policy`): `docrl_jax.pretrained`. This module is the command's arguments and
their checks (each bad input one line, no usage block, before anything compiles); what it then runs
is `cli_run`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Sequence

import yaml

from docrl_jax import flags, pretrained
from docrl_jax.arguments import OneLineParser, UsageError, check_out, prog
from docrl_jax.errors import RunDirError, os_error_line
from docrl_jax.evaluate.tank_sets import TankSetError
from docrl_jax.evaluate.protocol import DEFAULT_EVAL_ENV, SCENARIOS

# The built-in policies that need no run directory and fly in every command with --policy. The
# robustness benchmark (robustness_cli) reads this name and flies the baselines alone.
POLICIES = pretrained.BASELINES


def add_which_argument(p: argparse.ArgumentParser) -> None:
    """--which, as every command that loads a run's policy takes it (evaluate, robustness, render, export)."""
    from docrl_jax.policy import CHECKPOINT_POLICIES, RUN_POLICY_RULE
    p.add_argument("--which", default=None, choices=CHECKPOINT_POLICIES,
                   help=f"with --run, which policy of the latest checkpoint: final (the Polyak-averaged actor at "
                        f"it) or best (each seed's best evaluated one); default the run's policy: {RUN_POLICY_RULE}")


GUIDES = ("tank", "sensors")   # --guide's values: the route on the tank's own map, or on the vehicle's own beams


def add_guide_argument(p: argparse.ArgumentParser) -> None:
    """--guide, as every command that flies a policy takes it (evaluate, robustness, render)."""
    p.add_argument("--guide", nargs="?", const="tank", default=None, metavar="{tank,sensors}",
                   help="steer the policy down a route (docrl_jax/envs/guidance.py: its goal floats point at the "
                        "route's aim). 'tank' (alone: --guide) plans on each trial's tank, which the command knows: "
                        "map-aided, labels say 'guided'. 'sensors' plans on the map the vehicle builds from its own "
                        "beams as it flies (docrl_jax/envs/belief.py): no prior map, labels say 'own-map'. Not for "
                        "bba, which reads its goal from the env")


def check_guide(args: argparse.Namespace) -> None:
    """--guide names a known route source and steers a learned policy through its observation; the BBA baseline
    does not read one."""
    guide = getattr(args, "guide", None)
    if guide is None:
        return
    if guide not in GUIDES:
        from docrl_jax.schema import did_you_mean
        raise UsageError(f"--guide {guide!r}: valid routes are {', '.join(GUIDES)} (tank: the tank's own map; "
                         f"sensors: the map the vehicle builds from its beams){did_you_mean(guide, GUIDES)}")
    if (args.policy or "").lower() == "bba":
        raise UsageError("--guide steers a learned policy through its observation's goal floats; bba reads its goal "
                         "from the env: drop --guide, or give --run RUN_DIR or a shipped --policy")


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
            from docrl_jax.envs.params import EnvParams
            from docrl_jax.schema import declared_in, did_you_mean
            raise UsageError(f"--env {k!r}: unknown env parameter; valid names: the fields of EnvParams in "
                             f"{declared_in(EnvParams)}{did_you_mean(k, valid)}")
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
    p = OneLineParser(prog=prog("evaluate"), description=__doc__.split("\n\n")[0])
    src = p.add_mutually_exclusive_group()
    flags.add(src, "--run", "; several run directories of one config (separate launches, e.g. one per seed) are "
                            "evaluated as the seeds of one method", metavar="RUN_DIR", nargs="+")
    flags.add(src, "--policy", f": {', '.join(pretrained.POLICY_NAMES)} (the behaviour-based baseline, then the "
                               "trained policies shipped in the package, docrl_jax/pretrained/README.md)",
              metavar="NAME")
    p.add_argument("--seed-index", default="all",
                   help="seed(s) of --run to evaluate, comma-separated, e.g. 0 or 0,1,2; default 'all': every seed "
                        "the run trained (train.num_seeds in its config.yaml). Several seeds also give a table of "
                        "mean and spread over seeds. With several run directories each gives these seeds, "
                        "numbered 0, 1, ... in the order given (results.json maps them back)")
    add_which_argument(p)
    add_guide_argument(p)
    p.add_argument("--label", help="method name in the tables (default: the --policy name, 'BBA' for bba, or the run dir's name)")
    flags.add(p, "--trials", " per scenario and direction (default 100)", default=100)
    flags.add(p, "--scenarios", " (default 1,2,3)", default=None)
    flags.add(p, "--tank", ", in place of the scenarios' paper pairs: --trials per direction, trial i in tank i mod "
                           "the set's size, from a random start in the start medium's region to a random goal in the "
                           "other's, random yaw; a table per tank (printed, tanks.csv)", metavar="PATH|DIR|NAME")
    flags.add(p, "--directions", " (default both)", default="air_to_water,water_to_air")
    p.add_argument("--max-steps", type=int, default=500, help="step limit of a trial (default 500, the paper's)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of the trials (default 0)")
    p.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                   help="env parameter override (repeatable), e.g. hull_volume=4e-5, water_current=(0.1,0,0) or "
                        f"[0.1,0,0], wind=false; checked before anything runs; defaults here: {DEFAULT_EVAL_ENV}")
    p.add_argument("--bba-depth-phase", default="after", help="BBA only, order of the depth phase: after (default, the DoCRL script), first (the JINT copy), concurrent, in_air (climb first / descend last)")
    flags.add(p, "--out", ": a folder (results.md/.csv/.json, trials.csv, trajectories, figures). Default with "
                          "--run: <first RUN_DIR>/evaluation; with --policy: none, the tables are printed and nothing "
                          "is written; --curves needs --out (or --run)", metavar="DIR")
    p.add_argument("--figures", type=int, default=10, metavar="K",
                   help="trajectories drawn per figure (0 = no trajectory figures; default 10)")
    p.add_argument("--curves", nargs="+", metavar="RUN_DIR",
                   help="also plot learning curves from these run dirs' metrics.csv (or metrics.csv files)")
    return p


def validate_args(args: argparse.Namespace) -> dict[str, Any]:
    """Checks the command line before anything is compiled; raises UsageError naming valid choices."""
    from docrl_jax.baselines.bba import DEPTH_PHASES
    from docrl_jax.evaluate import rollout, tank_sets
    from docrl_jax.evaluate.run_dirs import check_run_dir, config_name, run_num_seeds
    if args.run is None and args.policy is None and not args.curves:
        raise UsageError("nothing to do: give --run RUN_DIR or --policy NAME "
                         f"(valid policies: {', '.join(pretrained.POLICY_NAMES)}), and/or --curves RUN_DIR ...")
    if args.policy is not None:
        args.policy = pretrained.check_name(args.policy.lower())
    check_guide(args)
    flags.check_positive("--trials", args.trials)
    flags.check_positive("--max-steps", args.max_steps)
    if args.bba_depth_phase not in DEPTH_PHASES:
        raise UsageError(f"--bba-depth-phase {args.bba_depth_phase!r}: valid choices are {', '.join(DEPTH_PHASES)}")
    flags.check_tank_or_scenarios(args.tank, args.scenarios)
    scenarios = [0] if args.tank is not None else flags.parse_scenarios(args.scenarios or "1,2,3")
    cfg = {"scenarios": scenarios, "directions": flags.parse_directions(args.directions),
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
    if cfg["out"] is not None:
        check_out(cfg["out"])
    check_memory(args, cfg)
    return cfg


def check_memory(args: argparse.Namespace, cfg: dict[str, Any]) -> None:
    """--trials against this machine's memory (trial_memory): a scenario's directions' trials held at once,
    every evaluated trial's row of trials.csv until it is written."""
    from docrl_jax.evaluate import trial_memory
    from docrl_jax.evaluate.run_dirs import run_num_seeds
    seeds = sum(len(cfg["seed_indices"]) if cfg["seed_indices"] is not None else run_num_seeds(run)
                for run in args.run) if args.run else 1
    pairs = len(cfg["scenarios"]) * len(cfg["directions"])
    need = trial_memory.Need(args.max_steps, held=len(cfg["directions"]), rows=pairs * seeds,
                             from_states=args.tank is not None or args.guide is not None)
    trial_memory.check("--trials", args.trials, need)


def output_dir(args: argparse.Namespace) -> Path | None:
    """--out; with --run and no --out, <first run dir>/evaluation; otherwise None (write nothing)."""
    if args.out is not None:
        return Path(args.out)
    if args.run:
        return Path(args.run[0]) / "evaluation"
    return None








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






def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        cfg = validate_args(args)
    except (UsageError, RunDirError, pretrained.UnknownPolicy, TankSetError) as e:
        parser.error(str(e))   # one line, exit status 2
    from docrl_jax.evaluate.cli_run import evaluate
    try:
        return evaluate(args, cfg, parser, argv)
    except OSError as e:  # an output folder that cannot be written: one line, as the other bad inputs
        print(f"error: {os_error_line(e)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
