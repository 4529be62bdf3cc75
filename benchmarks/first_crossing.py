"""When each seed's policy first reads a target both ways, from evaluations at every chunk; and when an
evaluation schedule would have read it.

    python3 benchmarks/first_crossing.py gamma0.99=RUN/metrics.csv gamma0.995=SWEEP/c01/metrics.csv ... \
        [--target 0.9] [--slow 15] [--schedules 1x3,2x3,3x2,5x1] [--out FILE.md]

Each input is LABEL=PATH: the metrics.csv of a plain run (any train.num_seeds) or of one sweep
combination, trained with `train.eval_alongside=false` and `train.eval_every` equal to one chunk, so that
every chunk boundary has an evaluation (the same episodes as an alongside evaluation begun there: the keys
depend on the seed and the env steps only). Inputs with one label are pooled.

Per input and per label: the chunk at which each seed first reads >= target in both paper directions
(success_air_to_water and _water_to_air), its median over seeds (a seed that never reads it counts as
later than any), the seeds that read it at chunk `--slow` or later or never, and the seeds whose last
evaluation reads it.

`--schedules GxE` replays each label's curves under evaluations alongside
training with G lane groups, one begun every E chunks when a group is free: an evaluation that reads the
target lands 3 chunks after it begins (its episodes arrive within 300 steps), any other keeps its group 5
chunks (an episode times out at 500 steps), the one at step 0 included. 1x3 is the default's schedule
(train.eval_every 1.25 M env steps, one group of lanes). It gives the chunk at which each seed's target
row would land.
"""

from __future__ import annotations

import argparse
import csv
import statistics
from collections import defaultdict

NEVER = 10 ** 6


def curves(path: str) -> dict[str, dict[int, tuple[float, float]]]:
    """seed -> chunk -> (A-W, W-A) success; a chunk is the first row's env-step spacing."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    steps = sorted({int(r["env_steps"]) for r in rows})
    chunk = steps[1] - steps[0]
    out: dict = defaultdict(dict)
    for r in rows:
        out[r["seed"]][int(r["env_steps"]) // chunk] = (float(r["success_air_to_water"]),
                                                         float(r["success_water_to_air"]))
    return dict(out)


def first_at(curve: dict[int, tuple[float, float]], target: float) -> int:
    return next((c for c in sorted(curve) if min(curve[c]) >= target), NEVER)


def replay(curve: dict[int, tuple[float, float]], target: float, groups: int, every: int,
           land: int = 3, busy: int = 5) -> int:
    """The chunk at which the schedule's first target row lands (NEVER if none within the curve)."""
    free, due = [0] * groups, 0
    for c in sorted(curve):
        if c < due:
            continue
        g = min(range(groups), key=free.__getitem__)
        if free[g] > c:
            continue
        if min(curve[c]) >= target:
            return c + land
        free[g], due = c + busy, c + every
    return NEVER


def fmt(c: float) -> str:
    return "never" if c >= NEVER / 2 else f"{c:g}"


def summary(firsts: list[int], finals: list[bool], slow: int) -> str:
    return (f"{len(firsts)} | {fmt(statistics.median(firsts))} | {sum(c < NEVER for c in firsts)} | "
            f"{sum(c >= slow for c in firsts)} | {sum(finals)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("inputs", nargs="+", metavar="LABEL=PATH")
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--slow", type=int, default=15, help="chunks from which a seed counts as slow")
    ap.add_argument("--schedules", default="", help="comma-separated GxE: G lane groups, one begun every E chunks")
    ap.add_argument("--out")
    a = ap.parse_args()
    by_label: dict[str, list] = defaultdict(list)
    lines = [f"# First evaluation at >= {a.target:.0%} both ways, in chunks of evaluations at every chunk", "",
             "Command: `python3 benchmarks/first_crossing.py " + " ".join(a.inputs)
             + (f" --schedules {a.schedules}" if a.schedules else "") + "`", "",
             "| input | per seed (chunk of the first such evaluation) |", "|---|---|"]
    for spec in a.inputs:
        label, _, path = spec.partition("=")
        if not path:
            ap.error(f"{spec!r} is not LABEL=PATH")
        got = curves(path)
        by_label[label] += [got[s] for s in sorted(got)]
        lines.append(f"| {label}: `{path}` | {' '.join(fmt(first_at(got[s], a.target)) for s in sorted(got))} |")
    lines += ["", f"| label | seeds | median chunk | reached | from chunk {a.slow} or never | last evaluation at target |",
              "|---|---|---|---|---|---|"]
    for label, cs in by_label.items():
        firsts = [first_at(c, a.target) for c in cs]
        finals = [min(c[max(c)]) >= a.target for c in cs]
        lines.append(f"| {label} | {summary(firsts, finals, a.slow)} |")
    for label, cs in by_label.items() if a.schedules else ():
        lines += ["", f"Schedules replayed on {label} (chunk at which the target row lands):", "",
                  "| lane groups x chunks between evaluations | median chunk | per seed |", "|---|---|---|"]
        for sched in a.schedules.split(","):
            g, _, e = sched.partition("x")
            landed = [replay(c, a.target, int(g), int(e)) for c in cs]
            lines.append(f"| {sched} | {fmt(statistics.median(landed))} | {' '.join(fmt(x) for x in landed)} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
