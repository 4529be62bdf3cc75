"""The table of mapless / own-map / tank's-map flight from robustness benchmark outputs (robustness.csv of
`python -m docrl_jax.robustness --tests structured,tanks`, one file per way of flying, the same seeds and trials).

    python benchmarks/own_map_table.py mapless=DIR_A/robustness.csv "own map=DIR_B/robustness.csv" \
        "tank's map=DIR_C/robustness.csv" [--out table.md]

Rows: the held-out structured tanks, the gallery, then the gallery per family (the tank name's first word:
ceiling, dead_end, grove, ...; pier_*, pipe_*, ...); cells: success % A-W / W-A, the median over the file's
seeds, then each seed's in brackets. A family's rate pools its tanks' trials.
"""

from __future__ import annotations

import argparse
import csv
import statistics
from collections import defaultdict

DIRECTIONS = ("air_to_water", "water_to_air")
FAMILIES = ("ceiling", "dead_end", "grove", "mixed", "pier", "pipe", "room", "wall", "zigzag")


def family(tank: str) -> str:
    return next((f for f in FAMILIES if tank.startswith(f)), tank)


def rates(path: str) -> dict:
    """{(row name, direction): {seed: rate}} of one robustness.csv."""
    counts: dict = defaultdict(lambda: [0, 0])
    with open(path) as f:
        for r in csv.DictReader(f):
            if r["perturbation"] not in ("none", ""):
                continue
            seed, d = r["seed_index"], r["direction"]
            if r["test"] == "structured":
                names = ["held-out structured tanks"]
            elif r["test"] == "tanks":
                names = ["the gallery"] if r["tank"] in ("all", "") else [f"gallery: {family(r['tank'])}"]
            else:
                continue
            for name in names:
                c = counts[(name, d, seed)]
                c[0] += int(r["successes"])
                c[1] += int(r["trials"])
    out: dict = defaultdict(dict)
    for (name, d, seed), (ok, n) in counts.items():
        if n:
            out[(name, d)][seed] = 100.0 * ok / n
    return out


def cell(by_seed: dict | None) -> str:
    if not by_seed:
        return "–"
    seeds = [by_seed[s] for s in sorted(by_seed)]
    each = ", ".join(f"{v:.0f}" for v in seeds)
    return f"{statistics.median(seeds):.0f}" + (f" ({each})" if len(seeds) > 1 else "")


def table(modes: dict[str, dict]) -> str:
    rows = ["held-out structured tanks", "the gallery"] + [f"gallery: {f}" for f in FAMILIES]
    head = "| test | " + " | ".join(f"{m} A-W / W-A" for m in modes) + " |"
    lines = [head, "|---|" + "---|" * len(modes)]
    for row in rows:
        cells = [f"{cell(r.get((row, DIRECTIONS[0])))} / {cell(r.get((row, DIRECTIONS[1])))}" for r in modes.values()]
        if any(c != "– / –" for c in cells):
            lines.append(f"| {row} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("modes", nargs="+", metavar="NAME=CSV")
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    modes = {}
    for spec in args.modes:
        name, _, path = spec.partition("=")
        if not path:
            p.error(f"{spec!r}: give NAME=PATH of a robustness.csv")
        modes[name] = rates(path)
    text = table(modes)
    print(text, end="")
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
