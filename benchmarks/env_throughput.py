"""Environment throughput: control steps per second and simulated seconds per wall second.

    python benchmarks/env_throughput.py                       # scenario 2, 1,024 ... 65,536 envs
    python benchmarks/env_throughput.py --num-envs 4096 --repeats 3 --out /tmp/res
    python benchmarks/env_throughput.py --scenarios 2 0 --env dr_wind_scale=0.5,3 --num-envs 4096   # procedural, randomised

Each timed call is one jitted `lax.scan` of `--steps` control steps over `vmap`ped envs (random
actions drawn inside the program, sensors on). Variants: `autoreset` (the training setting: every
step also computes a fresh reset for the envs that finish) and `plain` (env.step alone). Compile time
is measured separately (lower + compile), then the median of `--repeats` timed calls is reported.
Writes env_throughput.json and env_throughput.md into --out (default benchmarks/results/).
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import yaml


from docrl_jax.benchmarking import env_throughput, run_meta, write_results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenarios", type=int, nargs="+", default=[2], choices=(0, 1, 2, 3),
                    help="scenarios to measure, side by side (0 = procedural tanks: a layout per episode)")
    ap.add_argument("--env", action="append", default=[],
                    help="env parameter KEY=VALUE (a range as LOW,HIGH), applied to every scenario; repeatable")
    ap.add_argument("--num-envs", type=int, nargs="+", default=[1024, 4096, 16384, 65536])
    ap.add_argument("--steps", type=int, default=100, help="control steps per timed call")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--variants", nargs="+", default=["autoreset", "plain"], choices=["autoreset", "plain"])
    ap.add_argument("--unroll", type=int, nargs="+", default=[None],
                    help="substep_unroll values to compare (default: the env's backend default)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    args = ap.parse_args(argv)
    if any(n <= 0 for n in args.num_envs) or args.steps <= 0 or args.repeats <= 0:
        ap.error("--num-envs, --steps and --repeats must be positive")

    overrides = {}
    for item in args.env:
        key, sep, value = item.partition("=")
        if not sep:
            ap.error(f"--env {item!r}: expected KEY=VALUE")
        try:   # each part a YAML scalar, as a config's --set reads it: 0.1, 8, true
            parts = [yaml.safe_load(v) for v in value.split(",")]
        except yaml.YAMLError as e:
            ap.error(f"--env {item!r}: {e}")
        overrides[key] = tuple(parts) if len(parts) > 1 else parts[0]
    meta = run_meta()
    print(json.dumps(meta), flush=True)
    columns = [("scenario", "scenario"), ("variant", "variant"), ("unroll", "substep_unroll"), ("num_envs", "num_envs"),
               ("compile (s)", "compile_s"), ("control steps/s", "control_steps_per_s"),
               ("simulated s / s", "sim_seconds_per_s"), ("physics steps/s", "physics_steps_per_s")]
    rows, table = [], ""
    for variant in args.variants:
        for unroll in args.unroll:
            for n in args.num_envs:
                for scenario in args.scenarios:
                    rows.append(env_throughput(scenario, n, args.steps, args.repeats, variant, unroll, overrides))
                print(json.dumps(rows[-1]), flush=True)
                table = write_results(args.out, "env_throughput", "Environment throughput", meta, rows, columns)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
