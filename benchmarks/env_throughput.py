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
import statistics
import sys
import time

import jax
import yaml

import docrl_jax.envs as envs

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import run_meta, write_results  # noqa: E402


def measure(scenario: int, num_envs: int, steps: int, repeats: int, variant: str, unroll: int | None = None,
            overrides: dict | None = None) -> dict:
    env = envs.make(scenario, auto_reset=(variant == "autoreset"), substep_unroll=unroll, **(overrides or {}))
    reset = jax.jit(jax.vmap(env.reset))

    def rollout(state, key):
        def body(s, k):
            a = jax.random.uniform(k, (num_envs, 3), minval=-1.0, maxval=1.0)
            s = jax.vmap(env.step)(s, a)
            return s, s.reward.sum()
        state, rewards = jax.lax.scan(body, state, jax.random.split(key, steps))
        return state, rewards.sum()

    state = reset(jax.random.split(jax.random.PRNGKey(0), num_envs))
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    compiled = jax.jit(rollout, donate_argnums=0).lower(state, jax.random.PRNGKey(1)).compile()
    compile_s = time.perf_counter() - t0
    state, _ = compiled(state, jax.random.PRNGKey(2))  # warm-up
    jax.block_until_ready(state)
    times = []
    for r in range(repeats):
        t0 = time.perf_counter()
        state, total = compiled(state, jax.random.PRNGKey(3 + r))
        jax.block_until_ready(total)
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    sps = num_envs * steps / med
    return {"scenario": scenario, "env": overrides or {}, "variant": variant, "substep_unroll": env._unroll, "num_envs": num_envs, "steps_per_call": steps,
            "repeats": repeats, "compile_s": round(compile_s, 2), "call_s_median": round(med, 5),
            "call_s_all": [round(t, 5) for t in times], "control_steps_per_s": round(sps),
            "sim_seconds_per_s": round(sps * env.control_dt),
            "physics_steps_per_s": round(sps * env.params.substeps)}


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
                    rows.append(measure(scenario, n, args.steps, args.repeats, variant, unroll, overrides))
                print(json.dumps(rows[-1]), flush=True)
                table = write_results(args.out, "env_throughput", "Environment throughput", meta, rows, columns)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
