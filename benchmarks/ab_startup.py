"""Start-up of two versions of the code, launch by launch: the train command's own `startup.json`
(launch -> compiled, -> training, -> first chunk), cold (an empty compile cache) then warm (the same
cache again, `--warm` times), versions interleaved within each round.

    # here: the old code beside the new (git-ignored .old/, as for benchmarks/ab_launches.sh)
    rm -rf .old && mkdir .old && git archive REV docrl_jax configs assets | tar -x -C .old
    # GPU machine (carry .old):
    python3 benchmarks/ab_startup.py --rounds 3 --out DIR

Each launch is `python -m docrl_jax.train --config td3_lstm --set train.total_env_steps=819200` (two
chunks, so it starts learning and ends) in its own fresh process and run directory. Besides the
trainer's own figures (whose clock starts where that version starts it), this script times every
launch itself: from spawning the process to the appearance of its `startup.json`, which the trainer
writes after the first chunk (`spawn_to_first_chunk_s`, imports included, the same clock for both),
and to its exit (`spawn_to_exit_s`: the final evaluation included); `first_eval_row_s` is the
wall_time_s of the run's first metrics.csv row (when the first evaluation's results were in, on the
trainer's clock).

`--new-env NAME=VALUE` (repeatable) sets an environment variable for the new side's launches only,
to compare one setting on the same code (`.old` a copy of this tree), e.g. an `XLA_FLAGS` value.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from docrl_jax.benchmarking import run_meta

KEYS = ("spawn_to_first_chunk_s", "launch_to_compiled_s", "launch_to_training_s", "launch_to_first_chunk_s",
        "compile_s", "first_eval_row_s", "spawn_to_exit_s")


def launch(root: str, cache: str, run_dir: str, config: str, extra_env: dict) -> dict:
    path = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
            if p and os.path.abspath(p) != os.path.abspath(os.getcwd())]
    env = {**os.environ, **extra_env, "PYTHONPATH": os.pathsep.join([root] + path)}
    startup = os.path.join(run_dir, "startup.json")
    # The trainer's output goes to a file, not a pipe: a pipe nobody reads while polling would fill
    # and stall the launch being timed.
    with tempfile.TemporaryFile("w+") as log:
        t0 = time.time()
        proc = subprocess.Popen([sys.executable, "-m", "docrl_jax.train", "--config", config, "--set",
                                 "train.total_env_steps=819200", "--run-dir", run_dir, "--compile-cache", cache,
                                 "--no-progress"], cwd=root, env=env, stdout=log, stderr=subprocess.STDOUT)
        seen = None
        while proc.poll() is None:
            if seen is None and os.path.exists(startup):
                seen = time.time() - t0
            time.sleep(0.01)
        ended = time.time() - t0
        if proc.returncode != 0:
            log.seek(0)
            raise SystemExit(f"launch failed ({proc.returncode}): {log.read()[-3000:]}")
    with open(os.path.join(run_dir, "metrics.csv")) as f:   # the first evaluation's row (launch clock)
        first_row = next(csv.DictReader(f))
    with open(startup) as f:
        return {"spawn_to_first_chunk_s": round(seen, 2), "first_eval_row_s": float(first_row["wall_time_s"]),
                "spawn_to_exit_s": round(ended, 2), **json.load(f)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", default=".old", help="the old version's checkout (docrl_jax, configs, assets)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--warm", type=int, default=1, help="warm launches per version and round (after its cold one)")
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--out", required=True)
    ap.add_argument("--new-env", action="append", default=[], metavar="NAME=VALUE",
                    help="an environment variable for the new side's launches only (repeatable)")
    args = ap.parse_args()
    if bad := [x for x in args.new_env if "=" not in x]:
        ap.error(f"--new-env takes NAME=VALUE, got {bad}")
    side_env = {"old": {}, "new": dict(x.split("=", 1) for x in args.new_env)}
    roots = {"old": os.path.abspath(args.old), "new": os.getcwd()}
    rows = []
    work = tempfile.mkdtemp(prefix="ab_startup_")
    for r in range(args.rounds):
        # cold old, cold new, then the warm launches alternating old and new
        for i, state in enumerate(["cold"] + ["warm"] * args.warm):
            for side, root in roots.items():
                cache = os.path.join(work, f"cache_{side}_{r}")
                run_dir = os.path.join(work, f"run_{side}_{r}_{state}{i}")
                got = launch(root, cache, run_dir, args.config, side_env[side])
                rows.append({"round": r, "version": side, "cache": state, **{k: got[k] for k in KEYS}})
                print(side, state, r, got["spawn_to_first_chunk_s"], flush=True)
    summary = {f"{side} {state}": {k: statistics.median(x[k] for x in rows if x["version"] == side and x["cache"] == state)
                                   for k in KEYS} for side in roots for state in ("cold", "warm")}
    meta = run_meta()
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "ab_startup.json"), "w") as f:
        json.dump({**meta, "rounds": rows, "medians": summary}, f, indent=1)
    lines = [f"# Start-up, old and new code, launch by launch ({meta['gpu']}, {meta['date']})", "",
             f"Command: `{meta['command']}`  ",
             f"New side's environment: {side_env['new'] or 'as the old'}  ", f"Versions: {meta['versions']}", "",
             f"Medians of {args.rounds} cold and {args.rounds * args.warm} warm launches per version (s):", "",
             "| version, cache | spawn -> first chunk | launch -> compiled | launch -> training | "
             "launch -> first chunk | compile or load | first evaluation row | spawn -> exit |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {name} | " + " | ".join(f"{v[k]:.2f}" for k in KEYS) + " |"
              for name, v in summary.items()]
    lines += ["", "Every launch (s, spawn -> first chunk): " + ", ".join(
        f"{x['version']} {x['cache']} r{x['round']} {x['spawn_to_first_chunk_s']:.2f}" for x in rows)]
    with open(os.path.join(args.out, "ab_startup.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
