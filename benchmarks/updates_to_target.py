"""Env steps and gradient updates each seed of a run needed to reach a success target in both paper
directions, read from the run's metrics.csv: a sample-efficiency figure that, unlike wall-clock time,
many seeds can share one GPU for (`train.num_seeds=8` trains eight seeds vmapped in one program).

    python benchmarks/updates_to_target.py RUN_DIR [RUN_DIR ...] [--target 0.9] [--late-from ENV_STEPS]

With --late-from, a second table: how steady each run's evaluated policy is from that env step on
(per seed: mean and standard deviation of the W-A success over those evaluations, its lowest value in
either direction, the final W-A; means over seeds, the per-seed lows and finals listed).

A seed that had not reached the target by the run's last evaluation is censored: it counts as
"above the last evaluated step" (the median is then a lower bound when half or more are censored).
Time to target on one GPU is about updates x (one iteration's wall time / updates per iteration),
plus start-up and evaluations; measure it directly with time_to_success.py.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from collections import defaultdict

from docrl_jax.benchmarking import reached, read_rows


def run_rows(run_dir: str) -> list[dict]:
    """The rows of a run's metrics.csv (an error line if it has none)."""
    rows = read_rows(os.path.join(run_dir, "metrics.csv"))
    if not rows:
        raise SystemExit(f"{run_dir}: no metrics.csv rows")
    return rows


def per_seed(rows: list[dict], target: float) -> tuple[dict, int, int]:
    """{seed: (env steps, gradient updates) at the first evaluation at target, or None}, and the
    last evaluated env steps and updates, from a run's metrics.csv rows."""
    by_seed = defaultdict(list)
    for r in rows:
        by_seed[r["seed"]].append(r)
    out = {}
    for seed, seed_rows in sorted(by_seed.items(), key=lambda kv: int(kv[0])):
        hit = reached(seed_rows, target)
        out[int(seed)] = None if hit is None else (int(float(hit["env_steps"])), int(float(hit["grad_updates"])))
    last = rows[-1]
    return out, int(float(last["env_steps"])), int(float(last["grad_updates"]))


def late(rows: list[dict], from_steps: float) -> dict:
    """{seed: (W-A successes, A-W successes)} of the evaluations at or after `from_steps` env steps."""
    out = defaultdict(lambda: ([], []))
    for r in rows:
        wa, aw = r.get("success_water_to_air", ""), r.get("success_air_to_water", "")
        if float(r["env_steps"]) >= from_steps and wa not in ("", "nan") and aw not in ("", "nan"):
            out[int(r["seed"])][0].append(float(wa))
            out[int(r["seed"])][1].append(float(aw))
    return dict(sorted(out.items()))


def late_table(runs: dict, from_steps: float) -> None:
    """The late-steadiness table of {run directory: its metrics.csv rows}."""
    print(f"\n| run | evaluations per seed from {from_steps / 1e6:.1f} M | W-A mean | W-A sd (mean over seeds) "
          "| lowest of either direction, per seed | final W-A, per seed |")
    print("|---|---|---|---|---|---|")
    for run_dir, rows in runs.items():
        seeds = late(rows, from_steps)
        wa = [v[0] for v in seeds.values()]
        print(f"| {os.path.basename(os.path.normpath(run_dir))} | {statistics.median(len(w) for w in wa):.0f} "
              f"| {statistics.mean(statistics.mean(w) for w in wa):.3f} "
              f"| {statistics.mean(statistics.pstdev(w) for w in wa):.3f} "
              f"| {', '.join(f'{min(v[0] + v[1]):.2f}' for v in seeds.values())} "
              f"| {', '.join(f'{w[-1]:.2f}' for w in wa)} |")


def median_text(values: list[int], censored: int, last: int) -> str:
    """The median of the seeds' values with the censored seeds counted above `last`."""
    ranked = sorted(values) + [None] * censored
    n = len(ranked)
    mid = ranked[(n - 1) // 2], ranked[n // 2]
    if None in mid:
        return f"> {last:,}" if mid[0] is None else f">= {mid[0]:,}"
    return f"{(mid[0] + mid[1]) / 2:,.0f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run_dirs", nargs="+")
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--late-from", type=float, default=None, metavar="ENV_STEPS",
                    help="also tabulate the evaluations from this env step on (steadiness late in the run)")
    args = ap.parse_args(argv)
    print(f"| run | seeds at {args.target:.0%} | env steps, per seed | median env steps | gradient updates, per seed "
          "| median updates |")
    print("|---|---|---|---|---|---|")
    runs = {run_dir: run_rows(run_dir) for run_dir in args.run_dirs}
    for run_dir, rows in runs.items():
        seeds, last_steps, last_updates = per_seed(rows, args.target)
        hits = [v for v in seeds.values() if v is not None]
        censored = len(seeds) - len(hits)
        steps = sorted(h[0] for h in hits)
        updates = sorted(h[1] for h in hits)
        more = f", {censored} > last" if censored else ""
        print(f"| {os.path.basename(os.path.normpath(run_dir))} | {len(hits)}/{len(seeds)} "
              f"| {', '.join(f'{s / 1e6:.1f} M' for s in steps)}{more} | {median_text(steps, censored, last_steps)} "
              f"| {', '.join(f'{u:,}' for u in updates)}{more} | {median_text(updates, censored, last_updates)} |")
    if args.late_from is not None:
        late_table(runs, args.late_from)
    return 0


if __name__ == "__main__":
    sys.exit(main())
