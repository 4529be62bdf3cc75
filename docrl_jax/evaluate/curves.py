"""Learning curves from the trainer's metrics.csv: success rate and return against environment steps
and wall-clock, mean +- std over seeds (Matplotlib, Agg, PNG).

    python -m docrl_jax.plotting curves runs/d runs/s --labels DoCRL-D,DoCRL-S --out results/curves
    plot_learning_curves(["runs/a/metrics.csv", "runs/b/metrics.csv"], "out_dir")
"""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

CURVE_METRICS = ("success_rate", "episode_return")
# The trainer's evaluation of the paper's start/goal pairs (`train.eval_paper_pairs`): drawn as extra
# rows when a metrics.csv has them, since they track what Table I measures.
PAPER_PAIR_METRICS = ("success_air_to_water", "success_water_to_air")
METRIC_LABELS = {"success_rate": "eval success (random goals)", "episode_return": "eval return (random goals)",
                 "success_air_to_water": "success, paper A-W pair", "success_water_to_air": "success, paper W-A pair"}
CURVE_X = (("env_steps", "environment steps"), ("wall_time_s", "wall-clock (s)"))
REQUIRED_COLUMNS = ("env_steps", "wall_time_s", "seed", "success_rate", "episode_return")


def read_metrics(path) -> dict[int, dict[str, np.ndarray]]:
    """metrics.csv -> {seed: {column: array}} (rows sorted by env_steps; non-numeric cells -> NaN)."""
    path = Path(path)
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        cols = reader.fieldnames or []
        missing = [c for c in REQUIRED_COLUMNS if c not in cols]
        if missing:
            raise ValueError(f"{path}: metrics.csv lacks column(s) {missing}; needs {list(REQUIRED_COLUMNS)}")
        rows = list(reader)

    def num(x):
        try:
            return float(x)
        except (TypeError, ValueError):
            return math.nan
    by_seed: dict[int, list] = defaultdict(list)
    for r in rows:
        s = num(r["seed"])
        by_seed[int(s) if math.isfinite(s) else 0].append(r)
    out = {}
    for seed, rs in by_seed.items():
        cols_arr = {c: np.array([num(r[c]) for r in rs]) for c in cols}
        order = np.argsort(cols_arr["env_steps"], kind="stable")
        out[seed] = {c: v[order] for c, v in cols_arr.items()}
    return out


def aggregate_curves(series: Sequence[tuple[np.ndarray, np.ndarray]], num: int = 200):
    """Mean and std over seeds of curves y(x) given at different x: interpolated on a common grid
    spanning the x range all seeds cover. Returns (grid, mean, std, n_seeds)."""
    clean = []
    for x, y in series:
        ok = np.isfinite(x) & np.isfinite(y)
        if ok.sum() >= 1:
            clean.append((x[ok], y[ok]))
    if not clean:
        return np.array([]), np.array([]), np.array([]), 0
    lo = max(x.min() for x, _ in clean)
    hi = min(x.max() for x, _ in clean)
    if hi <= lo:  # a single point or disjoint ranges: no common span, show the union
        lo, hi = min(x.min() for x, _ in clean), max(x.max() for x, _ in clean)
    grid = np.linspace(lo, hi, num) if hi > lo else np.array([lo])
    ys = np.stack([np.interp(grid, x, y) for x, y in clean])
    return grid, ys.mean(0), ys.std(0), len(clean)


def find_metrics_csv(path) -> Path:
    """A run directory's metrics.csv, or the file itself; RunDirError names what is missing."""
    from docrl_jax.errors import RunDirError
    from docrl_jax.runs import METRICS_FILE   # lazily: plotting alone needs no checkpoint code
    p = Path(path)
    if p.is_file():
        return p
    if (p / METRICS_FILE).is_file():
        return p / METRICS_FILE
    raise RunDirError(f"{str(p)!r}: no {METRICS_FILE} there (give a run directory or a {METRICS_FILE} file)")


def plot_learning_curves(csv_paths: Sequence, out_dir, labels: Sequence[str] | None = None,
                         filename: str = "learning_curves.png") -> list[Path]:
    """Success rate and return against env steps and wall-clock, mean +- std over seeds.

    Each metrics.csv may hold several seeds (its `seed` column); files with the same label (default:
    the name of the file's directory) are pooled, so one curve per method. Writes one PNG with one
    row per metric (plus the paper-pair success rows when any file has them) and two columns."""
    csv_paths = [Path(p) for p in csv_paths]
    if not csv_paths:
        raise ValueError("plot_learning_curves: no metrics.csv given")
    if labels is None:
        labels = [p.parent.name or str(p) for p in csv_paths]
    if len(labels) != len(csv_paths):
        raise ValueError(f"{len(labels)} labels for {len(csv_paths)} metrics files")
    groups: dict[str, list] = defaultdict(list)
    for p, lab in zip(csv_paths, labels):
        groups[lab].extend(read_metrics(p).values())
    metrics = list(CURVE_METRICS) + [
        m for m in PAPER_PAIR_METRICS
        if any(m in s and np.isfinite(s[m]).any() for seeds in groups.values() for s in seeds)]
    fig, axes = plt.subplots(len(metrics), 2, figsize=(11, 3.75 * len(metrics)), squeeze=False)
    for col, (xname, xlabel) in enumerate(CURVE_X):
        for row, metric in enumerate(metrics):
            ax = axes[row, col]
            for i, (lab, seeds) in enumerate(groups.items()):
                grid, mean, std, n = aggregate_curves([(s[xname], s[metric]) for s in seeds if metric in s])
                if n == 0:
                    continue
                c = f"C{i}"
                ax.plot(grid, mean, color=c, label=f"{lab} (n={n} seed{'s' if n != 1 else ''})")
                ax.fill_between(grid, mean - std, mean + std, color=c, alpha=0.2)
            ax.set(xlabel=xlabel, ylabel=METRIC_LABELS.get(metric, metric.replace("_", " ")))
            ax.grid(alpha=0.3)
            if metric.startswith("success"):
                ax.set_ylim(-0.03, 1.03)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Learning curves: mean ± std over seeds")
    fig.tight_layout()
    out = Path(out_dir) / filename
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return [out]


def add_command(sub) -> None:
    """The `curves` subcommand of `python -m docrl_jax.plotting` (argparse subparsers `sub`)."""
    cv = sub.add_parser("curves", help="learning curves from run dirs or metrics.csv files")
    cv.add_argument("runs", nargs="+")
    cv.add_argument("--labels", help="comma-separated labels, one per run (same label = pooled seeds)")
    cv.add_argument("--out", required=True, help="directory for learning_curves.png")


def run_command(args) -> None:
    labels = args.labels.split(",") if args.labels else None
    print(*plot_learning_curves([find_metrics_csv(r) for r in args.runs], args.out, labels))
