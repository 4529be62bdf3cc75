"""Table I side by side: several `python -m docrl_jax.evaluate` outputs in one table, beside the
paper's published numbers.

    python -m docrl_jax.compare docs/results/defaults_2026_11_24/{td3,sac,sto,det} docs/results/bba \
        --out docs/results/defaults_2026_11_24/table_i.md

Each argument is an evaluation output directory (its results.json). A multi-seed evaluation
contributes its mean and spread over seeds; a single-seed one (or BBA) one value. Rows are ordered
as in the paper (DoCRL-D, DoCRL-S, Sto., Det., BBA, then any other method).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Sequence

from docrl_jax import flags
from docrl_jax.arguments import OneLineParser, check_out, prog
from docrl_jax.evaluate import paper_results
from docrl_jax.evaluate.protocol import DIRECTIONS
from docrl_jax.evaluate.tables import SHORT, aggregate_seeds, plus_minus


def load_eval(path: str | Path) -> list[dict]:
    """The over-seeds rows of one evaluation output dir (computed from its per-seed rows if the file
    has none). Raises FileNotFoundError / ValueError naming the file and what is wrong."""
    path = Path(path)
    f = path / "results.json" if path.is_dir() else path
    if not f.exists():
        raise FileNotFoundError(f"{str(f)!r} does not exist; pass directories written by "
                                "`python -m docrl_jax.evaluate --out DIR`")
    try:
        data = json.loads(f.read_text())
        rows = data["results"]
    except (json.JSONDecodeError, KeyError, TypeError) as e:
        raise ValueError(f"{str(f)!r} is not an evaluation results.json ({type(e).__name__}: {e})") from None
    if not rows:
        raise ValueError(f"{str(f)!r} holds no results")
    aggs = data.get("over_seeds") or aggregate_seeds(rows)
    for a in aggs:  # JSON wrote NaN as null
        for k, v in a.items():
            if v is None and k.endswith(("_mean", "_std")):
                a[k] = math.nan
    return aggs


def _order(aggs: list[dict]) -> list[dict]:
    rank = {m: i for i, m in enumerate(paper_results.METHODS)}
    return sorted(aggs, key=lambda a: (DIRECTIONS.index(a["direction"]), rank.get(a["method"], len(rank)),
                                       a["method"]))


def _success(a: dict, show_seeds: bool = True) -> str:
    """Successes out of the trials the evaluation ran: the count of a single evaluation, else mean ± std
    over seeds [and each seed's]. The 'of N' keeps a 10-trial evaluation from reading as out of 100."""
    per_seed = a["successes_per_seed"]
    if len(per_seed) == 1:
        return f"{per_seed[0]} of {a['trials']}"
    return (f"{a['successes_mean']:.1f} ± {a['successes_std']:.1f} of {a['trials']}"
            + (f" {per_seed}" if show_seeds else ""))


def side_by_side_markdown(aggs: list[dict]) -> str:
    """Markdown: the paper's scenario (Table I) with the published rows beside ours, then every
    scenario evaluated, ours only."""
    aggs = _order(aggs)
    scen = paper_results.TABLE_I_SCENARIO
    out = [f"### Scenario {scen}: ours beside the paper's Table I\n",
           "Ours: successes out of the trials run per seed, mean ± std over seeds [each seed]; t_air, t_water: "
           "simulated seconds, mean ± std pooled over all seeds' successful trials; collisions, time-outs: mean "
           "per seed. Paper: one training run, 100 trials.\n",
           "| Test | ours: success | ours: t_air (s) | ours: t_water (s) | ours: collisions | ours: time-outs | "
           "paper: success | paper: t_air (s) | paper: t_water (s) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for a in (a for a in aggs if a["scenario"] == scen):
        try:
            p = paper_results.lookup(a["method"], a["direction"])
            paper = f"{p['success']} of {p['trials']} | {plus_minus(*p['t_air'])} | {plus_minus(*p['t_water'])}"
        except KeyError:
            paper = "– | – | –"
        out.append(f"| {SHORT[a['direction']]} {a['method']} | {_success(a)} | {plus_minus(a['t_air_mean'], a['t_air_std'])} "
                   f"| {plus_minus(a['t_water_mean'], a['t_water_std'])} | {a['collisions_mean']:.1f} | "
                   f"{a['timeouts_mean']:.1f} | {paper} |")
    scenarios = sorted({a["scenario"] for a in aggs})
    out += ["", "### Every scenario (ours)\n",
            "Each cell: successes out of the trials run, mean ± std over seeds; then t_air / t_water (s), "
            "pooled means.\n",
            "| Test | " + " | ".join(f"Scenario {s}" for s in scenarios) + " |",
            "|---|" + "---|" * len(scenarios)]
    by_key = {(a["direction"], a["method"], a["scenario"]): a for a in aggs}
    for direction, method in dict.fromkeys((d, m) for d, m, _ in by_key):
        cells = []
        for s in scenarios:
            a = by_key.get((direction, method, s))
            if a is None:
                cells.append("–")
                continue
            times = (f"{a['t_air_mean']:.1f} / {a['t_water_mean']:.1f}" if math.isfinite(a["t_air_mean"]) else "–")
            cells.append(f"{_success(a, show_seeds=False)} ({times})")
        out.append(f"| {SHORT[direction]} {method} | " + " | ".join(cells) + " |")
    out += ["", paper_results.NOTE, ""]
    return "\n".join(out)


def build_parser() -> OneLineParser:
    ap = OneLineParser(prog=prog("compare"), description=__doc__.split("\n\n")[0])
    ap.add_argument("evals", nargs="+", help="evaluation output directories (or their results.json)")
    flags.add(ap, "--out", ": a file, the Markdown (default: print only)", metavar="FILE")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        if args.out:
            check_out(args.out, folder=False)
        aggs = [a for e in args.evals for a in load_eval(e)]
    except (FileNotFoundError, ValueError) as e:   # (a UsageError is a ValueError)
        ap.error(str(e))
    dupes = {(a["method"], a["scenario"], a["direction"]) for a in aggs}
    if len(dupes) != len(aggs):
        ap.error("two evaluations share a method name; give each a distinct --label when evaluating")
    text = side_by_side_markdown(aggs)
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
