"""The report of a sweep (docrl_jax.train.sweep): per combination, from its metrics.csv, time to 90 %
success in both paper directions and the final success, mean ± std over seeds (sweep.csv,
sweep.md), and one learning-curve figure per swept key (curves_<key>.png). Made from the files
alone, so it can be made again for an interrupted sweep."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from docrl_jax import runs
from docrl_jax.evaluate.tables import mean_std, plus_minus
from docrl_jax.train import metrics

TABLE_CSV, TABLE_MD = "sweep.csv", "sweep.md"
SUCCESS_LEVEL = 0.9


def columns(grid: dict) -> list[str]:
    """A combination's metrics.csv columns: a plain run's, its name and one per swept key."""
    return metrics.METRIC_COLUMNS + ["combination", *grid]


def time_to_success(rows: dict[str, np.ndarray], level: float = SUCCESS_LEVEL) -> float:
    """wall_time_s of the first evaluation with both paper directions >= level (NaN: not reached)."""
    ok = (rows["success_air_to_water"] >= level) & (rows["success_water_to_air"] >= level)
    return float(rows["wall_time_s"][np.argmax(ok)]) if ok.any() else math.nan


def summarise(run_dir, grid: dict) -> list[dict]:
    """One record per combination (sweep.json order) from its metrics.csv, seeds pooled."""
    from docrl_jax.evaluate.curves import read_metrics
    run_dir = Path(run_dir)
    meta = json.loads((run_dir / runs.SWEEP_FILE).read_text())
    out = []
    for c in meta["combinations"]:
        by_seed = read_metrics(run_dir / c["name"] / runs.METRICS_FILE)
        rec = {"combination": c["name"], **{k: c["values"][k] for k in grid}, "seeds": len(by_seed)}
        last = [{k: v[-1] for k, v in s.items()} for s in by_seed.values()]
        times = [time_to_success(s) for s in by_seed.values()]
        rec["seeds_reached_90"] = int(np.sum(np.isfinite(times)))
        rec["time_to_90_s_mean"], rec["time_to_90_s_std"] = mean_std(times)
        pairs = bool(last) and all(np.isfinite(r["success_air_to_water"]) for r in last)
        rec["paper_pairs"] = pairs
        for key, col in (("success", "success_rate"), ("success_a2w", "success_air_to_water"),
                         ("success_w2a", "success_water_to_air"), ("return", "episode_return")):
            rec[f"final_{key}_mean"], rec[f"final_{key}_std"] = mean_std([r[col] for r in last])
        rec["final_env_steps"] = int(max((r["env_steps"] for r in last), default=0))
        out.append(rec)
    return out


def write_summary(run_dir, grid: dict, diverged: dict | None = None) -> list[Path]:
    """sweep.csv, sweep.md and one learning-curve figure per swept key."""
    run_dir = Path(run_dir)
    recs = summarise(run_dir, grid)
    diverged = diverged or {}
    for r in recs:
        r["diverged_seeds"] = " ".join(map(str, diverged.get(r["combination"], [])))
    with open(run_dir / TABLE_CSV, "w", newline="") as fh:
        w = csv.DictWriter(fh, list(recs[0]) if recs else ["combination"])
        w.writeheader()
        for r in recs:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else json.dumps(v) if isinstance(v, list) else v)
                        for k, v in r.items()})
    head = ["combination", *grid, "seeds", "time to 90 % both ways (s)", "final success", "final A-W",
            "final W-A", "final eval return"]
    lines = [f"# Sweep: {', '.join(f'{k} in {v}' for k, v in grid.items())}", "",
             "Mean ± std over seeds. Time to 90 %: wall-clock seconds from the start of the combination's "
             "program (compile included, devices shared with the other rows of its group) to the first "
             "evaluation with success_air_to_water and success_water_to_air both >= 0.9, over the seeds that "
             "reached it. Final: the last evaluation.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in recs:
        if not r["paper_pairs"]:
            t90 = "n/a (train.eval_paper_pairs false)"
        elif r["seeds_reached_90"] == 0:
            t90 = "not reached"
        else:
            t90 = plus_minus(r["time_to_90_s_mean"], r["time_to_90_s_std"], ".0f", missing="n/a")
            if r["seeds_reached_90"] < r["seeds"]:
                t90 += f" ({r['seeds_reached_90']}/{r['seeds']} seeds; the others: not reached)"
        name = r["combination"] + (f" (diverged: seed {r['diverged_seeds']})" if r["diverged_seeds"] else "")
        cells = [name, *(str(r[k]) for k in grid), str(r["seeds"]), t90,
                 plus_minus(r["final_success_mean"], r["final_success_std"], ".2f", missing="n/a"),
                 plus_minus(r["final_success_a2w_mean"], r["final_success_a2w_std"], ".2f", missing="n/a"),
                 plus_minus(r["final_success_w2a_mean"], r["final_success_w2a_std"], ".2f", missing="n/a"),
                 plus_minus(r["final_return_mean"], r["final_return_std"], ".1f", missing="n/a")]
        lines.append("| " + " | ".join(cells) + " |")
    (run_dir / TABLE_MD).write_text("\n".join(lines) + "\n")
    return [run_dir / TABLE_CSV, run_dir / TABLE_MD, *plot_sweep_curves(run_dir, grid)]


def plot_sweep_curves(run_dir, grid: dict) -> list[Path]:
    """curves_<key>.png per swept key: success (and the paper pairs when evaluated) against env
    steps, one line per value, mean ± std over seeds and the other keys' values."""
    from docrl_jax.evaluate.curves import aggregate_curves, plt, read_metrics
    run_dir = Path(run_dir)
    meta = json.loads((run_dir / runs.SWEEP_FILE).read_text())
    series = {c["name"]: list(read_metrics(run_dir / c["name"] / runs.METRICS_FILE).values())
              for c in meta["combinations"]}
    metrics = ["success_rate"] + [m for m in ("success_air_to_water", "success_water_to_air")
                                  if any(np.isfinite(s[m]).any() for ss in series.values() for s in ss)]
    paths = []
    for key in grid:
        fig, axes = plt.subplots(1, len(metrics), figsize=(5.5 * len(metrics), 4), squeeze=False)
        for ax, metric in zip(axes[0], metrics):
            for i, value in enumerate(grid[key]):
                pooled = [(s["env_steps"], s[metric]) for c in meta["combinations"]
                          if json.dumps(c["values"][key]) == json.dumps(value) for s in series[c["name"]]]
                x, mean, std, n = aggregate_curves(pooled)
                if n == 0:
                    continue
                ax.plot(x, mean, color=f"C{i}", label=f"{key}={value} ({n} run{'s' * (n != 1)})")
                ax.fill_between(x, mean - std, mean + std, color=f"C{i}", alpha=0.2)
            ax.set(xlabel="env steps (per seed)", ylabel=metric.replace("_", " "), ylim=(-0.03, 1.03))
            ax.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=8)
        fig.suptitle(f"Sweep over {key}: mean ± std over seeds and the other keys")
        fig.tight_layout()
        path = run_dir / f"curves_{key}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths
