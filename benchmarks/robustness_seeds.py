"""One table over several `python -m docrl_jax.robustness` outputs: per test, the median over seeds of
success % A-W / W-A, with each seed's figures beside it (what a results table must show).

    python3 benchmarks/robustness_seeds.py LABEL=DIR[,DIR...] [LABEL=DIR ...] [--tests structured,tanks]

DIR holds a robustness.csv; several DIRs under one label pool their seeds (one evaluation per seed index,
e.g. `--seed-index N` runs). A seed's figure pools every row of the test for that seed and direction
(all scenarios, all magnitudes of the `perturbations none` nominal rows); the tanks test counts only its
rows over the whole set (tank `all`), not the per-tank ones.
"""

from __future__ import annotations

import argparse
import csv
import statistics
from collections import defaultdict
from pathlib import Path

DIRECTIONS = ("air_to_water", "water_to_air")


def seed_rates(csv_paths: list[Path], test: str) -> dict[int, tuple[float, float]]:
    """{seed index: (A-W %, W-A %)} of one test over robustness.csv files."""
    counts = defaultdict(lambda: [0, 0])   # (seed, direction) -> [successes, trials]
    for csv_path in csv_paths:
        with open(csv_path, newline="") as fh:
            for row in csv.DictReader(fh):
                if row["test"] != test or (test == "tanks" and row["tank"] != "all"):
                    continue
                c = counts[int(row["seed_index"]), row["direction"]]
                c[0] += int(row["successes"])
                c[1] += int(row["trials"])
    seeds = sorted({s for s, _ in counts})
    return {s: tuple(100.0 * counts[s, d][0] / counts[s, d][1] for d in DIRECTIONS) for s in seeds}


def table(entries: list[tuple[str, list[Path]]], tests: list[str]) -> str:
    head = "| arm | " + " | ".join(f"{t}: median A-W / W-A | seeds" for t in tests) + " |"
    lines = [head, "|---|" + "---|---|" * len(tests)]
    for label, folders in entries:
        cells = []
        for test in tests:
            rates = dict(sorted(seed_rates([f / "robustness.csv" for f in folders], test).items()))
            if not rates:
                cells += ["–", "–"]
                continue
            aw, wa = (statistics.median(r[i] for r in rates.values()) for i in (0, 1))
            cells += [f"**{aw:.1f} / {wa:.1f}**", ", ".join(f"{a:.0f}/{w:.0f}" for a, w in rates.values())]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("entries", nargs="+", metavar="LABEL=DIR[,DIR...]")
    ap.add_argument("--tests", default="structured,tanks", help="comma-separated robustness tests")
    args = ap.parse_args()
    entries = []
    for item in args.entries:
        label, sep, folders = item.rpartition("=")
        folders = [Path(f) for f in folders.split(",")]
        if not sep or not all((f / "robustness.csv").is_file() for f in folders):
            ap.error(f"{item!r}: expected LABEL=DIR[,DIR...], each DIR with a robustness.csv")
        entries.append((label, folders))
    print(table(entries, args.tests.split(",")))


if __name__ == "__main__":
    main()
