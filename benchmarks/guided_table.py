"""The table of benchmarks/rounds/guided.sh (the guided goals of docs/LEVELS.md, route-guided and mapless) from the job's
packed results.

    python3 benchmarks/guided_table.py round_guided.tar [--out summary.md]
    python3 benchmarks/guided_table.py DIR        (a folder holding pack/, or the pack folder itself)

Rows: each goal's test, success % A-W / W-A per seed of the guided policy, their median, the mapless
median of the same seeds on the same trials (where the job flew it) and the goal. The robustness
benchmark's rows (robustness.csv of each evaluation) are read with `robustness_report.cell_rates` (each
seed's rate averaged over the scenarios, then the median over seeds); the paper's pairs are the
evaluator's (results.csv: the lowest of scenarios 1-3 per direction); the goal perturbations are the lowest
of the goals' five settings, each averaged over scenarios 1-3.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import tarfile
import tempfile
from pathlib import Path

from docrl_jax.evaluate.robustness_report import cell_rates

DIRECTIONS = ("air_to_water", "water_to_air")
GUIDED, MAPLESS = "sac_mlp_tanks guided", "sac_mlp_tanks"
# (label, test, perturbation, magnitude) of the robustness benchmark's rows; goal in % both ways.
TESTS = (("the gallery (35 tanks, 350 trips each way)", "tanks", "none", "", 90),
         ("held-out structured tanks (1,000)", "structured", "none", "", 95),
         ("held-out procedural layouts (1,000)", "held_out_layouts", "none", "", 95),
         ("random trips, scenarios 1-3 (mean)", "random_trips", "none", "", 95))
GOAL_PERTURBATIONS = (("wind_gusts", "x2"), ("water_current", "0.25 m/s"), ("motor_lag", "x5"),
                      ("action_latency", "1 step"), ("beam_dropout", "p=0.1"))


def read_csv(path: Path) -> list[dict]:
    rows = list(csv.DictReader(open(path)))
    for r in rows:
        for k in ("success_rate",):
            r[k] = float(r[k])
        r["seed_index"] = int(r["seed_index"]) if r["seed_index"] not in ("", "None") else None
    return rows


def load(pack: Path) -> tuple[list[dict], list[dict]]:
    """(robustness rows, the evaluator's rows) of every evaluation in the pack (its eval_*.tgz)."""
    work = Path(tempfile.mkdtemp())
    for archive in sorted(pack.glob("eval_*.tgz")):
        with tarfile.open(archive) as t:
            t.extractall(work, filter="data")
    bench = [r for p in sorted(work.glob("eval/*/robustness.csv")) for r in read_csv(p)
             if not r["tank"] or r["tank"] == "all"]
    pairs = [dict(r, name=p.parent.name) for p in sorted(work.glob("eval/*/results.csv")) for r in read_csv(p)]
    return bench, pairs


def cell(a: float | None, w: float | None) -> str:
    return "" if a is None else f"{100 * a:.0f} / {100 * w:.0f}"


def table(bench: list[dict], pairs: list[dict]) -> str:
    seeds = sorted({r["seed_index"] for r in bench if r["method"] == GUIDED})
    lines = [f"| test | {' | '.join(f'guided, seed {s}' for s in seeds)} | guided, median | mapless, median | goal |",
             "|---|" + "---|" * (len(seeds) + 3)]

    def rate(method, test, perturbation, magnitude, seed=None) -> list[float] | None:
        rows = [r for r in bench if r["method"] == method and (seed is None or r["seed_index"] == seed)]
        rates = cell_rates(rows)
        got = [rates.get((method, test, perturbation, magnitude, d)) for d in DIRECTIONS]
        return None if None in got else got

    def goal_perturbations(method, seed=None):
        got = [rate(method, "perturbations", p, m, seed) for p, m in GOAL_PERTURBATIONS]
        return None if None in got else [min(g[i] for g in got) for i in range(2)]

    def pair_rates(method, seed=None):
        rows = [r for r in pairs if r["method"] == method and (seed is None or r["seed_index"] == seed)]
        if not rows:
            return None
        lowest = {d: min(float(r["successes"]) / float(r["trials"]) for r in rows if r["direction"] == d)
                  for d in DIRECTIONS}
        return [lowest[d] for d in DIRECTIONS]

    measures = [(label, lambda m, s, t=test, p=pert, g=mag: rate(m, t, p, g, s), goal)
                for label, test, pert, mag, goal in TESTS]
    measures += [("the paper's pairs, scenarios 1-3 (lowest)", pair_rates, 95),
                 ("goal perturbations, scenarios 1-3 (lowest of five)", goal_perturbations, 90)]
    for label, measure, goal in measures:
        per_seed = [measure(GUIDED, s) for s in seeds]
        median = (None, None) if None in per_seed else [statistics.median(x[i] for x in per_seed) for i in range(2)]
        mapless = [measure(MAPLESS, s) for s in seeds]
        mapless_median = ((None, None) if None in mapless else
                          [statistics.median(x[i] for x in mapless) for i in range(2)])
        lines.append(f"| {label} | {' | '.join(cell(*x) if x else '' for x in per_seed)} | {cell(*median)} | "
                     f"{cell(*mapless_median)} | >= {goal} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", help="the job's tar (round_guided.tar), or a folder holding pack/")
    ap.add_argument("--out", help="write the table here too")
    args = ap.parse_args()
    source = Path(args.source)
    if source.is_file():
        work = Path(tempfile.mkdtemp())
        with tarfile.open(source) as t:
            t.extractall(work, filter="data")
        source = work
    pack = source / "pack" if (source / "pack").is_dir() else source
    text = table(*load(pack))
    print(text)
    if args.out:
        Path(args.out).write_text(text)


if __name__ == "__main__":
    sys.exit(main())
