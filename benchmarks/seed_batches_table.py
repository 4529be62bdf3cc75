"""Per seed and per side, the final and best policies of benchmarks/rounds/seed_batches.sh,
from one or more jobs' packed results.

    python3 benchmarks/seed_batches_table.py round_seed_batches.tar [MORE.tar or DIR ...] [--out table.md]

A job's launches are batches: `train.num_seeds` seeds vmapped in one launch, named SIDE_sFIRSTSEED, and
the evaluator's results of their final and best policies (eval/SIDE_sFIRSTSEED_{final,best}, one row per
seed index). Per seed: env steps to 90 % both ways on the in-training paper pairs, the lowest W-A of the
in-training evaluations over the run's second half (the late slide the run goal guards against), which evaluation
today's best-policy rule picks from metrics.csv (the runs' own `best` was picked by the rule of their day),
and the evaluator's success per scenario and direction. Then per side how many final and best policies meet the run goal (docs/BENCHMARKS.md, "Targets").
Time to 90 % in seconds is not this table's figure: seeds sharing a GPU run slower than a launch of one.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np
import yaml

from docrl_jax.benchmarking import GOAL, SCENARIO_COLUMNS, TARGET, goal_counts, pair, pct, read_rows, reached, unpack

from docrl_jax.train import best_policy  # noqa: E402


def evaluator_by_seed(eval_dir: Path, first_seed: int) -> dict[int, dict]:
    """{seed: {(scenario, direction): success rate}} of the evaluator's results.csv in `eval_dir`."""
    path = eval_dir / "results.csv"
    out: dict[int, dict] = defaultdict(dict)
    for r in csv.DictReader(open(path)) if path.is_file() else []:
        out[first_seed + int(r["seed_index"])][(int(r["scenario"]), r["direction"])] = float(r["success_rate"])
    return out


def batch(work: Path, run_dir: Path) -> list[dict]:
    """One row per seed of the batch launch in `run_dir`."""
    side = run_dir.name.rsplit("_s", 1)[0]
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    first = int(config["train"]["seed"])
    total = int(config["train"]["total_env_steps"])
    by_seed = defaultdict(list)
    for row in read_rows(str(run_dir / "metrics.csv")):
        by_seed[int(float(row["seed"]))].append(row)
    final = evaluator_by_seed(work / "eval" / f"{run_dir.name}_final", first)
    best = evaluator_by_seed(work / "eval" / f"{run_dir.name}_best", first)
    out = []
    for seed, rows in sorted(by_seed.items()):
        hit = reached(rows, TARGET)
        late = [float(r["success_water_to_air"]) for r in rows if float(r["env_steps"]) >= total / 2]
        out.append({"side": side, "seed": seed, "env_steps_at_90": int(float(hit["env_steps"])) if hit else None,
                    "late_min_wa": min(late) if late else None, "pick": rule_pick(rows),
                    "last_env_steps": int(float(rows[-1]["env_steps"])),
                    "eval_final": final.get(seed), "eval_best": best.get(seed)})
    return out


def rule_pick(rows: list[dict]) -> int:
    """Env steps of the evaluation that today's best-policy rule (docrl_jax/train/best_policy.py) picks from
    one seed's metrics.csv rows: which policy `--run` would load had the run been tracked by it."""
    best = None
    for r in rows:
        ev = {k: np.asarray([float(r[k])]) for k in ("success_rate", *best_policy.PAIR_KEYS) if r.get(k) not in (None, "")}
        best, _ = best_policy.update(best, {"row": np.zeros(1)}, ev, int(float(r["env_steps"])))
    return int(best.env_steps[0])


def table(rows: list[dict]) -> str:
    head = ["side", "seed", "M env steps to 90 %", "lowest in-training W-A, 2nd half", "today's best-policy pick"]
    head += [f"evaluator {w} s{s} A-W / W-A" for w in ("final", "best") for s in SCENARIO_COLUMNS]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["side"], str(r["seed"]),
                 "not reached" if r["env_steps_at_90"] is None else f"{r['env_steps_at_90'] / 1e6:.1f}",
                 pct(r["late_min_wa"]), "final" if r["pick"] == r["last_env_steps"] else f"{r['pick'] / 1e6:.1f} M"]
        cells += [pair(r[f"eval_{w}"], s) for w in ("final", "best") for s in SCENARIO_COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    bar = dict(GOAL)
    summary = []
    for side in sorted({r["side"] for r in rows}):
        mine = [r for r in rows if r["side"] == side]
        steps = [r["env_steps_at_90"] if r["env_steps_at_90"] is not None else float("inf") for r in mine]
        med = statistics.median(steps)
        finals = sum(r["pick"] == r["last_env_steps"] for r in mine)
        text = (f"- **{side}** ({len(mine)} seeds): env steps to 90 % median "
                f"{'not reached' if med == float('inf') else f'{med / 1e6:.1f} M'}; today's best-policy rule "
                f"picks the final policy in {finals}/{len(mine)}")
        for w in ("final", "best"):
            done = [r[f"eval_{w}"] for r in mine if r[f"eval_{w}"]]
            if not done:
                continue
            s2, s13, both = goal_counts(done)
            text += (f"; {w}: {s2}/{len(done)} >= {bar[2]:.0%} in s2, {s13}/{len(done)} >= {bar[1]:.0%} in s1 and s3, "
                     f"**{both}/{len(done)} meet the goal**")
        summary.append(text)
    goal = "; ".join(f">= {b:.0%} both ways in scenario {s}" for s, b in GOAL)
    return "\n".join([*lines, "", *summary, "", f"Run goal, per policy by the evaluator: {goal}. "
                       "'–': not evaluated."]) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sources", nargs="+", help="jobs' tars (round_seed_batches.tar), folders holding pack/, or pack/")
    ap.add_argument("--out", help="write the table here too (Markdown)")
    args = ap.parse_args(argv)
    for source in args.sources:
        if not os.path.exists(source):
            ap.exit(2, f"seed_batches_table.py: error: {source}: no such file or folder (give a job's tar or a "
                       "folder holding pack/)\n")
    rows = []
    # All sources unpack into one folder: an evaluation packed apart from its job (e.g. one run on
    # another machine) finds its launch. Launch names differ between jobs (their sides' names).
    with tempfile.TemporaryDirectory(prefix="seed_batches_") as tmp:
        for i, source in enumerate(args.sources):
            work = unpack(source, Path(tmp) / "work", Path(tmp) / f"source{i}")
        for run_dir in sorted(p for p in (work / "runs").glob("*") if (p / "metrics.csv").is_file()):
            rows += batch(work, run_dir)
    if not rows:
        ap.exit(2, "seed_batches_table.py: error: no packed batch launches (pack/runs_SIDE_sSEED.tgz)\n")
    rows.sort(key=lambda r: (r["side"], r["seed"]))
    text = table(rows)
    print(text, end="")
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
