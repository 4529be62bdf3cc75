"""Wall-clock from launch until the paper's evaluation reaches a success target in both directions.

    python benchmarks/time_to_success.py --config td3_lstm --budget-s 570 --run-dir runs/ttt_td3 \
        --set env.num_envs=1024 --set train.eval_every=100000

Launches the real command line (`python -m docrl_jax.train`) as a subprocess, so the time includes
start-up and compilation, and watches its metrics.csv. The trainer's periodic evaluation runs the
paper's air-to-water and water-to-air pairs of its scenario (`train.eval_paper_pairs`,
`train.eval_episodes` episodes each, deterministic policy). The clock stops at the first evaluation
whose success rates in BOTH directions reach `--target` (every seed, if several), or at
`--budget-s`; then the trainer gets Ctrl-C, which makes it write its final checkpoint. Writes
time_to_success.json / .md into --out, and the metrics curve.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import run_meta  # noqa: E402


def read_rows(path: str) -> list[dict]:
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [r for r in csv.DictReader(f)]


def reached(rows: list[dict], target: float, num_seeds: int) -> dict | None:
    """The first env_steps at which every seed has both paper directions >= target."""
    by_step: dict[int, list[dict]] = {}
    for r in rows:
        by_step.setdefault(int(float(r["env_steps"])), []).append(r)
    for step in sorted(by_step):
        group = by_step[step]
        if len(group) < num_seeds:
            continue
        ok = all(float(r["success_air_to_water"]) >= target and float(r["success_water_to_air"]) >= target
                 for r in group)
        if ok:
            return {"env_steps": step, "rows": group}
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--budget-s", type=float, default=600.0)
    ap.add_argument("--num-seeds", type=int, default=1)
    ap.add_argument("--run-dir", required=True)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    ap.add_argument("--tag", default=None, help="suffix of the result files (default: the config name)")
    args = ap.parse_args(argv)
    launch = time.time()
    meta = run_meta()
    cmd = [sys.executable, "-m", "docrl_jax.train", "--config", args.config, "--run-dir", args.run_dir,
           "--set", f"train.num_seeds={args.num_seeds}", "--set", "train.eval_paper_pairs=true"]
    for s in args.set:
        cmd += ["--set", s]
    log_path = os.path.join(args.out, f"time_to_success_{args.tag or args.config}.log")
    os.makedirs(args.out, exist_ok=True)
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        hit, stop_reason = None, "budget"
        while True:
            time.sleep(0.5)
            hit = reached(read_rows(os.path.join(args.run_dir, "metrics.csv")), args.target, args.num_seeds)
            if hit:
                stop_reason, elapsed = "target", time.time() - launch
                break
            if proc.poll() is not None:
                stop_reason, elapsed = f"trainer exited ({proc.returncode})", time.time() - launch
                break
            if time.time() - launch > args.budget_s:
                elapsed = time.time() - launch
                break
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)  # the trainer checkpoints on Ctrl-C
            try:
                proc.wait(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
    rows = read_rows(os.path.join(args.run_dir, "metrics.csv"))
    best = {}
    for d in ("air_to_water", "water_to_air"):
        vals = [float(r[f"success_{d}"]) for r in rows] or [float("nan")]
        best[d] = max(vals)
    result = {**meta, "trainer_command": " ".join(cmd), "target": args.target, "budget_s": args.budget_s,
              "stop_reason": stop_reason, "reached": hit is not None,
              "time_to_target_s": round(elapsed, 1) if hit else None, "elapsed_s": round(elapsed, 1),
              "env_steps_at_target": hit["env_steps"] if hit else None, "best_success": best,
              "curve": [{k: r[k] for k in ("env_steps", "wall_time_s", "seed", "success_rate", "success_air_to_water",
                                           "success_water_to_air", "episode_return")} for r in rows]}
    tag = args.tag or args.config
    with open(os.path.join(args.out, f"time_to_success_{tag}.json"), "w") as f:
        json.dump(result, f, indent=1)
    summary = (f"{tag}: target {args.target:.0%} both directions: "
               + (f"reached in {elapsed:.0f} s at {hit['env_steps']:,} env steps" if hit
                  else f"NOT reached in {elapsed:.0f} s ({stop_reason}); best A-W {best['air_to_water']:.2f}, "
                       f"W-A {best['water_to_air']:.2f}"))
    with open(os.path.join(args.out, f"time_to_success_{tag}.md"), "w") as f:
        f.write(f"# Time to {args.target:.0%} success ({meta['gpu']}, {meta['date']})\n\nCommand: `{meta['command']}`\n\n"
                f"Trainer: `{' '.join(cmd)}`\n\n{summary}\n")
    print(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
