"""Throughput of the compiled training chunk: env steps/s, gradient updates/s, compile time, peak
device memory. One configuration per call (peak memory is per process):

    python benchmarks/bench_trainer.py --config td3_lstm --set env.num_envs=1024 --chunks 5 --out r.json

Times: `compile_s` = first chunk call (compile + one chunk) minus a steady chunk; steady numbers are
the median over the remaining chunk calls. Evaluation and checkpoints are not included (see
metrics.csv's wall_time_s for end-to-end time including them).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import jax
import jax.numpy as jnp

from docrl_jax import cli
from docrl_jax.config import load_config
from docrl_jax.train import make_trainer


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--config", default="td3_lstm")
    p.add_argument("--set", action="append", default=[])
    p.add_argument("--chunks", type=int, default=5, help="chunk calls (the first one compiles)")
    p.add_argument("--out", help="append the result as one JSON line to this file")
    args = p.parse_args()
    config = load_config(args.config, args.set)
    trainer = make_trainer(config)
    init, chunk, _ = cli.programs(config)
    seeds = config.train.num_seeds
    keys = jnp.stack([jax.random.PRNGKey(config.train.seed + i) for i in range(seeds)])
    t0 = time.time()
    state = jax.block_until_ready(init(keys, jnp.asarray(trainer.total_env_steps, jnp.int32)))
    init_s = time.time() - t0
    times, learn_iters, updates = [], [], []
    for _ in range(max(2, args.chunks)):
        t0 = time.time()
        state, m = chunk(state)
        m = jax.device_get(m)
        times.append(time.time() - t0)
        learn_iters.append(float(m["learn_iters"].mean()))
        updates.append(float(m["updates"].mean()))
    steady = statistics.median(times[1:])
    dev = jax.devices()[0]
    stats = dev.memory_stats() or {}
    result = {
        "config": args.config, "set": args.set, "device": dev.device_kind, "num_envs": config.env.num_envs,
        "num_seeds": seeds, "updates_per_step": config.train.updates_per_step,
        "batch_size": config.replay.batch_size, "seq_len": config.replay.seq_len,
        "steps_per_chunk_per_seed": trainer.steps_per_chunk, "init_s": round(init_s, 3),
        "compile_s": round(times[0] - steady, 3), "chunk_s": round(steady, 4),
        "env_steps_per_s": round(trainer.steps_per_chunk * seeds / steady, 1),
        "grad_updates_per_s": round(statistics.median(updates[1:]) * seeds / steady, 1),
        "learning_in_all_steady_chunks": all(li == trainer.iters_per_chunk for li in learn_iters[1:]),
        "peak_bytes": stats.get("peak_bytes_in_use"),
        "jax": jax.__version__,
    }
    print(json.dumps(result))
    if args.out:
        with open(args.out, "a") as fh:
            fh.write(json.dumps(result) + "\n")


if __name__ == "__main__":
    main()
