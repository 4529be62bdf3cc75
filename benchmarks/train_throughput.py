"""Trainer throughput: env steps/s, gradient updates/s and trained samples/s during training, compile
time, peak memory. Trained samples/s = updates/s x batch_size x (seq_len - burn_in): the sequence
steps that enter a loss per second (burn-in steps only warm the LSTM up).

    python benchmarks/train_throughput.py                                  # td3_lstm, sac_lstm x 256/1,024/4,096
    python benchmarks/train_throughput.py --configs td3_lstm --num-envs 1024 --set agent.critic_hidden=[256,256]
    python benchmarks/train_throughput.py --configs td3_lstm_paper td3_lstm --num-envs 4096   # old vs new recipe

For each config and num_envs: build the trainer (`docrl_jax.train.make_trainer`), compile one chunk
(timed separately), run one warm-up chunk (which also fills the buffer past `start_steps` and
seq_len, so every timed iteration learns), then time `--repeats` chunks and report the median.
A chunk is `--iters` iterations: every env steps once, then `train.updates_per_step` updates.
Writes train_throughput.json / .md into --out (default benchmarks/results/).
"""

from __future__ import annotations

import argparse
import json
import os
import sys



from docrl_jax.benchmarking import run_meta, train_throughput, write_results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--configs", nargs="+", default=["td3_lstm", "sac_lstm"])
    ap.add_argument("--num-envs", type=int, nargs="+", default=[256, 1024, 4096])
    ap.add_argument("--iters", type=int, default=50, help="iterations per timed chunk")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], help="extra config overrides section.key=value")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    ap.add_argument("--stem", default="train_throughput", help="result file name (without extension)")
    args = ap.parse_args(argv)
    meta = run_meta()
    print(json.dumps(meta), flush=True)
    columns = [("config", "config"), ("num_envs", "num_envs"), ("batch", "batch_size"),
               ("updates/iter", "updates_per_step"), ("compile (s)", "compile_s"), ("env steps/s", "env_steps_per_s"),
               ("grad updates/s", "grad_updates_per_s"), ("trained samples/s", "trained_samples_per_s"),
               ("peak GPU mem (GiB)", "peak_gpu_memory_gib")]
    rows, table = [], ""
    for name in args.configs:
        for n in args.num_envs:
            rows.append(train_throughput(name, n, args.iters, args.repeats, args.set))
            print(json.dumps(rows[-1]), flush=True)
            table = write_results(args.out, args.stem, "Trainer throughput", meta, rows, columns)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
