"""The evaluation's statistics and outputs: per-(scenario, direction) summaries, the paper-style
Markdown tables, statistics over seeds, and results.md / results.csv / results.json / trials.csv.

Per scenario and direction: successes out of the N trials run; t_air and t_water, mean +- std
(population std, ddof 0) over the successful trials, in simulated seconds; collisions (walls, floor,
obstacles), out-of-bounds, time-outs; path length, mean +- std over successful trials.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from docrl_jax.evaluate import paper_results
from docrl_jax.evaluate.protocol import OUTCOMES

SHORT = {"air_to_water": "A-W", "water_to_air": "W-A"}


def mean_std(x) -> tuple[float, float]:
    """Mean and population std (ddof 0) of the finite values of `x`; (nan, nan) when there are none."""
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan
    return float(x.mean()), float(x.std())


def plus_minus(mean: float | None, std: float | None, fmt: str = ".2f", missing: str = "–") -> str:
    """'mean ± std' with the format spec `fmt` (e.g. '.2f', '.1f'); `missing` when mean is None or not finite."""
    if mean is None or not math.isfinite(mean):
        return missing
    return f"{mean:{fmt}} ± {std:{fmt}}"


def summarize(trials: dict[str, np.ndarray]) -> dict[str, Any]:
    """Counts and mean/std over successful trials (the paper's statistics) of one `run_trials` result."""
    ok = trials["success"]
    s: dict[str, Any] = {"trials": int(ok.size), "successes": int(ok.sum()),
                         "success_rate": float(ok.mean()) if ok.size else float("nan"),
                         "collisions": int(trials["collision"].sum()),
                         "out_of_bounds": int(trials["out_of_bounds"].sum()),
                         "timeouts": int(trials["timeout"].sum()), "diverged": int(trials["diverged"].sum())}
    for name in ("t_air", "t_water", "time", "path_length"):
        s[f"{name}_mean"], s[f"{name}_std"] = mean_std(trials[name][ok])
    s["path_length_all_mean"], s["path_length_all_std"] = mean_std(trials["path_length"])
    s["final_distance_mean"], s["final_distance_std"] = mean_std(trials["final_distance"])
    return s


def heading(scenario: int, tank: str | None = None) -> str:
    """A table's heading: its scenario, or the tank set its trials flew in (`--tank`; scenario 0)."""
    return f"### Tanks: {tank}\n" if tank is not None else f"### Scenario {scenario}\n"


def markdown_table(rows: Sequence[dict[str, Any]], paper: bool = True, seed_rows: Sequence[dict] = (),
                   tank: str | None = None) -> str:
    """Markdown tables in the paper's format (Test | t_air (s) | t_water (s) | Success), one per
    scenario (or, for `tank`, the tank set's), with our extra columns, and the paper's published rows
    beside ours (scenario 2). `seed_rows` (from `aggregate_seeds`) adds a table of mean and spread over seeds."""
    out = [markdown_seed_table(list(seed_rows), tank)] if seed_rows else []
    if seed_rows:
        out.append("## Per seed\n")
    for scen in sorted({r["scenario"] for r in rows}):
        out.append(heading(scen, tank))
        out.append("| Test | t_air (s) | t_water (s) | Success | Collisions | Out of bounds | Time-outs | "
                   "Path (m) |")
        out.append("|---|---|---|---|---|---|---|---|")
        for r in rows:
            if r["scenario"] != scen:
                continue
            seed = "" if r.get("seed_index") is None else f" #{r['seed_index']}"
            out.append(f"| {SHORT[r['direction']]} {r['method']}{seed} | {plus_minus(r['t_air_mean'], r['t_air_std'])} | "
                       f"{plus_minus(r['t_water_mean'], r['t_water_std'])} | {r['successes']}/{r['trials']} | "
                       f"{r['collisions']} | {r['out_of_bounds']} | {r['timeouts']} | "
                       f"{plus_minus(r['path_length_mean'], r['path_length_std'])} |")
        if paper and scen == paper_results.TABLE_I_SCENARIO:
            for p in paper_results.TABLE_I:
                out.append(f"| {SHORT[p['direction']]} {p['method']} (paper) | {plus_minus(p['t_air'][0], p['t_air'][1])} | "
                           f"{plus_minus(p['t_water'][0], p['t_water'][1])} | {p['success']}/{p['trials']} | | | | |")
        out.append("")
    if paper:
        out.append(paper_results.NOTE)
    return "\n".join(out) + "\n"


CSV_FIELDS = ("method", "seed_index", "scenario", "direction", "trials", "successes", "success_rate", "collisions",
              "out_of_bounds", "timeouts", "diverged", "t_air_mean", "t_air_std", "t_water_mean", "t_water_std",
              "time_mean", "time_std", "path_length_mean", "path_length_std", "path_length_all_mean",
              "path_length_all_std", "final_distance_mean", "final_distance_std", "compile_s", "run_s")
TRIAL_FIELDS = ("method", "seed_index", "scenario", "direction", "trial", "outcome", "steps", "time", "t_air", "t_water",
                "path_length", "final_distance", "episode_return", "start_x", "start_y", "start_z", "start_yaw")


def write_outputs(out_dir: Path, rows: list[dict], trial_rows: list[dict], meta: dict,
                  seed_rows: Sequence[dict] = ()) -> None:
    """results.md (tables), results.csv (one row per scenario, direction and seed), trials.csv (one
    row per trial), results.json (all of it, plus the run's settings in "meta")."""
    out_dir.mkdir(parents=True, exist_ok=True)
    tank = meta.get("tank")
    (out_dir / "results.md").write_text(markdown_table(rows, paper=tank is None, seed_rows=seed_rows, tank=tank))
    r4 = lambda d: {k: round(v, 4) if isinstance(v, float) and math.isfinite(v) else v for k, v in d.items()}
    rows, seed_rows = [r4(r) for r in rows], [r4(r) for r in seed_rows]
    with open(out_dir / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    with open(out_dir / "trials.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=TRIAL_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(trial_rows)

    def clean(x):
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x
    (out_dir / "results.json").write_text(json.dumps(clean({"meta": meta, "results": rows, "over_seeds": list(seed_rows),
                                                            "trials": trial_rows}),
                                                     indent=1))


def trial_table(method: str, scenario: int, direction: str, trials: dict[str, np.ndarray]) -> list[dict]:
    rows = []
    for i in range(trials["success"].size):
        sp = trials["start_positions"][i]
        rows.append({"method": method, "scenario": scenario, "direction": direction, "trial": i,
                     "outcome": OUTCOMES[int(trials["outcome"][i])], "steps": int(trials["steps"][i]),
                     "time": round(float(trials["time"][i]), 4), "t_air": round(float(trials["t_air"][i]), 4),
                     "t_water": round(float(trials["t_water"][i]), 4),
                     "path_length": round(float(trials["path_length"][i]), 4),
                     "final_distance": round(float(trials["final_distance"][i]), 4),
                     "episode_return": round(float(trials["episode_return"][i]), 4),
                     "start_x": round(float(sp[0]), 4), "start_y": round(float(sp[1]), 4),
                     "start_z": round(float(sp[2]), 4), "start_yaw": round(float(trials["start_yaws"][i]), 4)})
    return rows


def aggregate_seeds(rows: list[dict]) -> list[dict]:
    """One row per (method, scenario, direction) over seeds: success mean/std over seeds (counts and
    rates), and t_air/t_water/path pooled over every seed's successful trials (weighted by successes)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["method"], r["scenario"], r["direction"]), []).append(r)
    out = []
    for (method, scen, direction), rs in groups.items():
        trials = {r["trials"] for r in rs}
        if len(trials) != 1:   # success counts out of different N do not pool
            raise ValueError(f"{method}, scenario {scen}, {direction}: the seeds ran different numbers of trials "
                             f"({sorted(trials)}); evaluate every seed with the same --trials")
        succ = np.array([r["successes"] for r in rs], float)
        rate = np.array([r["success_rate"] for r in rs], float)
        agg = {"method": method, "scenario": scen, "direction": direction, "seeds": [r["seed_index"] for r in rs],
               "trials": rs[0]["trials"], "successes_mean": float(succ.mean()), "successes_std": float(succ.std()),
               "successes_per_seed": [int(x) for x in succ], "success_rate_mean": float(rate.mean()),
               "success_rate_std": float(rate.std())}
        for key in ("collisions", "out_of_bounds", "timeouts"):
            agg[f"{key}_mean"] = float(np.mean([r[key] for r in rs]))
        for name in ("t_air", "t_water", "time", "path_length"):
            # pooled mean/std from per-seed (n, mean, std): exact for population statistics
            n = np.array([r["successes"] for r in rs], float)
            m = np.array([r[f"{name}_mean"] if r["successes"] else 0.0 for r in rs], float)
            sd = np.array([r[f"{name}_std"] if r["successes"] else 0.0 for r in rs], float)
            if n.sum() == 0:
                agg[f"{name}_mean"] = agg[f"{name}_std"] = float("nan")
            else:
                mu = float((n * m).sum() / n.sum())
                agg[f"{name}_mean"] = mu
                agg[f"{name}_std"] = float(np.sqrt((n * (sd ** 2 + (m - mu) ** 2)).sum() / n.sum()))
        out.append(agg)
    return out


def markdown_seed_table(aggs: list[dict], tank: str | None = None) -> str:
    out = ["## Over seeds\n", "Success: mean ± std over seeds (per seed in brackets); times and path: pooled over "
           "every seed's successful trials.\n"]
    for scen in sorted({a["scenario"] for a in aggs}):
        out.append(heading(scen, tank))
        out.append("| Test | t_air (s) | t_water (s) | Success | Seeds | Path (m) |")
        out.append("|---|---|---|---|---|---|")
        for a in aggs:
            if a["scenario"] != scen:
                continue
            out.append(f"| {SHORT[a['direction']]} {a['method']} | {plus_minus(a['t_air_mean'], a['t_air_std'])} | "
                       f"{plus_minus(a['t_water_mean'], a['t_water_std'])} | {plus_minus(a['successes_mean'], a['successes_std'], '.1f')}"
                       f"/{a['trials']} {a['successes_per_seed']} | {len(a['seeds'])} | "
                       f"{plus_minus(a['path_length_mean'], a['path_length_std'])} |")
        out.append("")
    return "\n".join(out) + "\n"
