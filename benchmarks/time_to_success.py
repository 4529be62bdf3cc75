"""Wall-clock from launch until the paper's evaluation reaches a success target in both directions,
for several seeds, each its own launch of the real command line.

    python benchmarks/time_to_success.py --config td3_lstm --seeds 0 1 2 --budget-s 300 --run-root runs/ttt
    python benchmarks/time_to_success.py --config td3_lstm --seeds 0 1 2 --to-end --tag td3_default  # the default command

Each seed launches `python -m docrl_jax.train --config C --set train.seed=S` as a subprocess, so the
time includes process start-up and compilation, and watches its metrics.csv. The trainer's periodic
evaluation runs the paper's air-to-water and water-to-air pairs of its scenario
(`train.eval_paper_pairs`, `train.eval_episodes` episodes each, deterministic policy), from the
evaluator's trial starts (`train.eval_pair_starts: paper`; results measured before that option existed used
`random_yaw`, a stricter test: pass `--set train.eval_pair_starts=random_yaw` to compare with them). The clock for
a seed stops at the first evaluation with both directions >= `--target`. Without `--to-end` the
trainer then gets Ctrl-C (it writes its final checkpoint); with `--to-end` it runs to its configured
end and the final evaluation is recorded too (what a user of the default command gets). A seed that
does not reach the target within `--budget-s` is stopped and reported as not reached, with its best.

`--compile-cache cold` gives every launch an empty persistent compilation cache (start-up as on a
fresh machine); `warm` shares one folder, so seeds after the first skip compilation; `default` uses
the trainer's own default. Writes time_to_success_<tag>.json / .md / per-seed logs into --out.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from docrl_jax.benchmarking import read_rows, reached, run_meta

from docrl_jax.train.metrics import FAILURE_COLUMNS  # noqa: E402


def run_seed(args, seed: int, cache_dir: str | None, out_dir: str, tag: str) -> dict:
    run_dir = os.path.join(args.run_root, f"{tag}_seed{seed}")
    shutil.rmtree(run_dir, ignore_errors=True)
    cmd = [sys.executable, "-m", "docrl_jax.train", "--config", args.config, "--run-dir", run_dir, "--no-progress",
           "--set", f"train.seed={seed}", "--set", "train.eval_paper_pairs=true"]
    if cache_dir is not None:
        cmd += ["--compile-cache", cache_dir]
    for s in args.set:
        cmd += ["--set", s]
    log_path = os.path.join(out_dir, f"time_to_success_{tag}_seed{seed}.log")
    metrics = os.path.join(run_dir, "metrics.csv")
    launch = time.time()
    hit_time, hit, first_eval_s = None, None, None
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        stop_reason = "budget"
        while True:
            time.sleep(0.25)
            rows = read_rows(metrics)
            if first_eval_s is None and len(rows) > 1:
                first_eval_s = time.time() - launch   # the first evaluation after training started
            if hit is None:
                hit = reached(rows, args.target)
                if hit is not None:
                    hit_time = time.time() - launch
                    if not args.to_end:
                        stop_reason = "target"
                        break
            if proc.poll() is not None:
                stop_reason = f"trainer exited ({proc.returncode})"
                break
            if time.time() - launch > args.budget_s:
                break
        elapsed = time.time() - launch
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)  # the trainer checkpoints on Ctrl-C
            try:
                proc.wait(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
    rows = read_rows(metrics)
    best = {d: max([float(r[f"success_{d}"]) for r in rows] or [float("nan")]) for d in ("air_to_water", "water_to_air")}
    last = rows[-1] if rows else {}
    final = {"env_steps": int(float(last["env_steps"])) if last else None,
             "air_to_water": float(last["success_air_to_water"]) if last else None,
             "water_to_air": float(last["success_water_to_air"]) if last else None}
    return {"seed": seed, "run_dir": run_dir, "trainer_command": " ".join(cmd), "stop_reason": stop_reason,
            "reached": hit is not None, "time_to_target_s": round(hit_time, 1) if hit_time else None,
            "env_steps_at_target": int(float(hit["env_steps"])) if hit else None,
            "updates_at_target": int(float(hit["grad_updates"])) if hit else None,
            "trainer_wall_at_target_s": float(hit["wall_time_s"]) if hit else None,
            "first_eval_s": round(first_eval_s, 1) if first_eval_s else None,
            "elapsed_s": round(elapsed, 1), "best_success": best, "final": final,
            "final_both_at_target": bool(final["air_to_water"] is not None and final["air_to_water"] >= args.target
                                         and final["water_to_air"] >= args.target),
            "curve": [{k: r.get(k) for k in ("env_steps", "wall_time_s", "success_rate", "success_air_to_water",
                                             "success_water_to_air", "grad_updates", *FAILURE_COLUMNS)} for r in rows]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--set", action="append", default=[], help="config override for every seed")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--budget-s", type=float, default=600.0, help="per seed, from its launch")
    ap.add_argument("--to-end", action="store_true", help="let each run finish and record its final evaluation")
    ap.add_argument("--compile-cache", choices=("cold", "warm", "default"), default="cold")
    ap.add_argument("--run-root", default="runs/time_to_success")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    ap.add_argument("--tag", default=None, help="name of the result files (default: the config name)")
    args = ap.parse_args(argv)
    tag = args.tag or os.path.basename(args.config).removesuffix(".yaml")
    meta = run_meta()
    os.makedirs(args.out, exist_ok=True)
    warm_dir = tempfile.mkdtemp(prefix="docrl_cache_") if args.compile_cache == "warm" else None
    results = []
    for seed in args.seeds:
        if args.compile_cache == "cold":
            cache = tempfile.mkdtemp(prefix="docrl_cache_")
        else:
            cache = warm_dir
        results.append(run_seed(args, seed, cache, args.out, tag))
        r = results[-1]
        print(f"{tag} seed {seed}: " + (f"{args.target:.0%} both ways at {r['time_to_target_s']} s "
                                         f"({r['env_steps_at_target']:,} env steps)" if r["reached"] else
                                         f"not reached in {r['elapsed_s']} s (best A-W {r['best_success']['air_to_water']:.2f}, "
                                         f"W-A {r['best_success']['water_to_air']:.2f})")
              + f"; final A-W {r['final']['air_to_water']}, W-A {r['final']['water_to_air']}; first eval {r['first_eval_s']} s",
              flush=True)
    times = [r["time_to_target_s"] for r in results]
    # A seed that never reached the target counts as +infinity for the median.
    med = statistics.median([t if t is not None else float("inf") for t in times])
    summary = {"median_time_to_target_s": med if med != float("inf") else None,
               "reached": sum(r["reached"] for r in results), "seeds": len(results),
               "final_both_at_target": sum(r["final_both_at_target"] for r in results)}
    out = {**meta, "config": args.config, "overrides": args.set, "target": args.target, "budget_s": args.budget_s,
           "to_end": args.to_end, "compile_cache": args.compile_cache, "summary": summary, "seeds": results}
    with open(os.path.join(args.out, f"time_to_success_{tag}.json"), "w") as f:
        json.dump(out, f, indent=1)
    lines = [f"# Time to {args.target:.0%} in both directions: {tag} ({meta['gpu']}, {meta['date']})", "",
             f"Command: `{meta['command']}`  ", f"Versions: {meta['versions']}  ",
             f"Compilation cache: {args.compile_cache}", "",
             "| seed | time to target (s) | env steps | gradient updates | first eval (s) | best A-W / W-A | "
             "final A-W / W-A | launch to stop (s) | stop |", "|---|---|---|---|---|---|---|---|---|"]
    dash = lambda v: "–" if v is None else v  # noqa: E731  (0 is a value: a target met at step 0)
    for r in results:
        lines.append(f"| {r['seed']} | {r['time_to_target_s'] if r['reached'] else '–'} | "
                     f"{dash(r['env_steps_at_target'])} | {dash(r['updates_at_target'])} | {r['first_eval_s']} | "
                     f"{r['best_success']['air_to_water']:.2f} / {r['best_success']['water_to_air']:.2f} | "
                     f"{r['final']['air_to_water']} / {r['final']['water_to_air']} | {r['elapsed_s']} | "
                     f"{r['stop_reason']} |")
    lines += ["", f"Median time to target: {summary['median_time_to_target_s']} s; reached {summary['reached']}/"
                  f"{summary['seeds']}; final policy at target {summary['final_both_at_target']}/{summary['seeds']}"]
    with open(os.path.join(args.out, f"time_to_success_{tag}.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines[-(len(results) + 3):]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
