"""What `python -m docrl_jax.evaluate` runs once its arguments are checked (docrl_jax.evaluate.cli):
learning curves, then for each scenario and evaluated policy the protocol's trials (or a tank set's),
the tables printed and the outputs written."""

from __future__ import annotations

import json
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from docrl_jax import pretrained, runs
from docrl_jax.errors import RunDirError
from docrl_jax.evaluate import policies, rollout, tank_trials
from docrl_jax.evaluate.run_dirs import config_name, run_config, run_num_seeds, run_vehicle
from docrl_jax.evaluate.protocol import DEFAULT_EVAL_ENV, NOMINAL_YAW, TrialSpec
from docrl_jax.evaluate.tables import SHORT, aggregate_seeds, markdown_table, trial_table, write_outputs


def policy_sources(args, seed_indices: list[int] | None) -> list[tuple[str, int]]:
    """(run dir, seed index within it) for each evaluated seed of --run, in the order given;
    seed_indices None = every seed each run trained."""
    return [(run, s) for run in args.run
            for s in (seed_indices if seed_indices is not None else range(run_num_seeds(run)))]


def load_policy_for(args, env, seed_index: int, run: str | None = None) -> tuple[Any, str]:
    """(policy, label) for --policy (a shipped policy or a baseline) or for one seed of the run directory
    `run`. Several run directories are labelled by their config's name, one by its folder's name."""
    if args.policy is not None:   # one BBA per env: the renderer's and benchmark's too
        policy, label = policies.policy_for(env, None, 0, None, args.bba_depth_phase, name=args.policy, guide=args.guide)
        if args.policy in pretrained.PRETRAINED:
            print(f"{args.policy}: {policy.source}", flush=True)
        return policy, args.label or label
    policy = runs.load_policy(run, seed_index=seed_index, which=args.which)
    print(f"{Path(run).name}: {policy.source}", flush=True)
    name = config_name(run) if len(args.run) > 1 else Path(run).resolve().name
    policy, label = policies.steered(policy, runs.policy_label(name, policy.which), args.guide, env)
    return policy, args.label or label


def evaluate(args, cfg: dict, parser, argv: Sequence[str] | None) -> int:
    """Runs what the checked arguments ask for: curves, then the protocol's trials; writes the outputs."""
    out_dir = cfg["out"]
    written: list[Path] = []   # every file written, named by the closing line
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
    if args.curves:
        from docrl_jax.evaluate import curves
        csvs = [curves.find_metrics_csv(d) for d in args.curves]
        paths = curves.plot_learning_curves(csvs, out_dir)
        print("learning curves:", ", ".join(str(p) for p in paths))
        written += paths
    if args.run is None and args.policy is None:
        print(wrote(out_dir, written))
        return 0

    import jax
    if args.run is None:
        sources, seed_indices = [(None, None)], [None]
    else:   # one run: its own seed indices; several: the evaluated seeds numbered 0, 1, ... in order
        sources = policy_sources(args, cfg["seed_indices"])
        seed_indices = [s for _, s in sources] if len(args.run) == 1 else list(range(len(sources)))
    # Each run's agent settings: runs with the same ones share their networks (and compiled rollout).
    agents = {run: json.dumps(run_config(run).get("agent"), sort_keys=True) for run in args.run or []}
    vehicles = {seed_index: run_vehicle(run, args.policy) for seed_index, (run, _) in zip(seed_indices, sources)}
    rows, trial_rows, tank_rows = [], [], []
    meta = {"command": " ".join(["python -m docrl_jax.evaluate", *(argv if argv is not None else sys.argv[1:])]),
            "run": args.run, "which": {} if args.run else None, "policy": args.policy, "guide": args.guide, "seed_indices": seed_indices,
            "policy_sources": {},
            "seed_runs": {str(i): {"run": run, "seed_index": s} for i, (run, s) in zip(seed_indices, sources)}
            if args.run is not None else {}, "trials": args.trials,
            "max_steps": args.max_steps, "seed": args.seed, "env_overrides": {**DEFAULT_EVAL_ENV, **cfg["env"]},
            "vehicles": {str(i): vehicle for i, vehicle in vehicles.items()},
            "trial_spec": asdict(TrialSpec()), "nominal_yaw": NOMINAL_YAW,
            "bba_depth_phase": args.bba_depth_phase if args.policy in pretrained.BASELINES else None,
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
        written.append(out_dir / f"trajectories_{stem}.npz")
        if args.figures > 0 and args.tank:
            written.extend(p for p in tank_trials.plot_flown(
                out_dir / f"trajectory_{stem}", stack, cfg["tank_names"], trials,
                f"{row['method']}{tag}, {SHORT[row['direction']]}", args.figures) if p is not None)
        elif args.figures > 0:
            from docrl_jax.evaluate import plotting
            written.append(plotting.plot_trajectories(
                env.mj_model, trials["positions"], trials["steps"], trials["outcome"], start, goal,
                out_dir / f"trajectory_{stem}.png", title=f"{row['method']}{tag}, scenario {row['scenario']}, "
                                                          f"{SHORT[row['direction']]}", max_trajectories=args.figures))

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
                    first = first_with_nets[nets]
                    policy = replace(policy, init_carry=first.init_carry, act=first.act)
                else:
                    first_with_nets[nets] = policy
                policies[seed_index] = (policy, method)
                if policy.source:
                    meta["policy_sources"][str(seed_index)] = policy.source
                if policy.which:   # what each run seed's checkpoint gave: "final" or "best"
                    meta["which"][str(seed_index)] = policy.which
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
    print(markdown_table(rows, paper=args.tank is None, seed_rows=aggs, tank=args.tank))
    if args.tank is not None:
        print(tank_trials.markdown(tank_rows, args.tank))
    if out_dir is None:
        print(f"nothing written: pass --out DIR to keep the tables, trials and figures ({meta['wall_time_s']} s)")
        return 0
    write_outputs(out_dir, rows, trial_rows, meta, aggs)
    written[:0] = [out_dir / name for name in ("results.md", "results.csv", "results.json", "trials.csv")]
    if args.tank:
        written[4:4] = tank_trials.write(out_dir, tank_rows, args.tank)
    print(f"{wrote(out_dir, written)} ({meta['wall_time_s']} s)")
    return 0


def wrote(out_dir: Path | None, paths: Sequence[Path]) -> str:
    """The closing line: every file the command wrote, named within its folder ('wrote DIR/: a, b, c')."""
    if not paths:
        return "nothing written"
    names = [str(p.relative_to(out_dir)) if out_dir is not None and p.is_relative_to(out_dir) else str(p)
             for p in paths]
    return f"wrote {out_dir}/: {', '.join(names)}"


