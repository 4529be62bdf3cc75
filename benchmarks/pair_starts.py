"""How much the start heading decides a paper-pair score: each run's final policy on the paper's
pairs, from the evaluator's trial starts (nominal yaw +-0.1 rad, +-0.1 m) and from the exact start
facing a uniformly random yaw (the trainer's first evaluation test, train.eval_pair_starts: random_yaw), with the
same trial keys, the evaluator's env (0.01 m range noise, wind; each run's own vehicle) and step limit. CPU
is enough.

    python benchmarks/pair_starts.py --runs R/td3_lstm_seed0 R/td3_lstm_seed1 R/td3_lstm_seed2 --out OUT
"""

from __future__ import annotations

import argparse
import math
import os

from docrl_jax.benchmarking import run_meta, write_results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", nargs="+", required=True, help="trainer run directories (seed index 0 of each)")
    ap.add_argument("--scenario", type=int, default=2)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--key", type=int, default=1, help="PRNG key of the trials (the same for both starts)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--tag", default="pair_starts")
    args = ap.parse_args(argv)

    import jax

    from docrl_jax import envs, evaluate
    from docrl_jax.evaluate import protocol
    from docrl_jax.evaluate.run_dirs import run_vehicle
    from docrl_jax.evaluate.rollout import flown_env
    from docrl_jax.train import load_policy
    meta, rows = run_meta(), []
    for run in args.runs:
        env = evaluate.make_eval_env(args.scenario, 500, **flown_env(run_vehicle(run), {}))   # the run's own vehicle
        policy = load_policy(run, which="final")
        row = {"run": os.path.basename(os.path.normpath(run))}
        for direction in protocol.DIRECTIONS:
            start, goal = envs.eval_pair(args.scenario, direction)
            # the evaluator's own trials, and the exact start with any yaw (nominal +- pi)
            for name, spec in (("paper", protocol.TrialSpec()),
                               ("random_yaw", protocol.TrialSpec(start_jitter_xy=0.0, yaw_jitter=math.pi))):
                t = evaluate.run_trials(env, policy, start, goal, jax.random.PRNGKey(args.key), args.trials, 500,
                                        protocol.NOMINAL_YAW[direction], spec)
                row[f"{evaluate.SHORT[direction]} {name}"] = int(t["success"].sum())
        rows.append(row)
        print(row, flush=True)
        write_results(args.out, args.tag, f"Paper-pair successes of {args.trials} by start heading, scenario "
                      f"{args.scenario}", meta, rows, [("run", "run")] + [(k, k) for k in row if k != "run"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
