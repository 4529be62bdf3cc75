"""What a training run reports: the metrics.csv rows of each evaluation, the TensorBoard scalars of
each chunk and the one-line summary of the progress display. Shared by runs and sweeps.

metrics.csv has one row per seed per evaluation (`METRIC_COLUMNS`; the first five are the
evaluator's contract, the rest may grow). Between evaluations the chunks' per-seed statistics are
summed in a `pending` dict of plain floats (`empty_pending`, `accumulate`), so it fits a
checkpoint's JSON and a resumed run writes the same rows as an uninterrupted one.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np


def import_tensorboard():
    """tensorboardX, imported without PyTorch where torch is installed but not yet imported:
    tensorboardX imports torch only to accept torch tensors (this package logs floats), and that
    import costs seconds of a launch that otherwise starts training in about ten."""
    block = "torch" not in sys.modules
    if block:
        sys.modules["torch"] = None  # `import torch` raises ImportError, which tensorboardX expects
    try:
        import tensorboardX
    finally:
        if block and sys.modules.get("torch", False) is None:
            del sys.modules["torch"]
    return tensorboardX

# Fractions of the paper-pair evaluation episodes (train.eval_paper_pairs) that ended in a collision
# or out of bounds; with the success fraction, the rest are time-outs. Older runs' metrics.csv lack
# them, and a resume rewrites the header with them (empty in the old rows).
FAILURE_COLUMNS = ["collision_air_to_water", "out_of_bounds_air_to_water", "collision_water_to_air",
                   "out_of_bounds_water_to_air"]
METRIC_COLUMNS = ["env_steps", "wall_time_s", "seed", "success_rate", "episode_return",
                  "success_air_to_water", "success_water_to_air", "train_episode_return", "train_success_rate",
                  "train_episodes", "critic_loss", "actor_loss", "alpha", "q", "policy_freq", "grad_updates",
                  "trained_actor_success_rate", "trained_actor_success_air_to_water",
                  "trained_actor_success_water_to_air", *FAILURE_COLUMNS]
# The evaluation results also recorded for the trained (not averaged) actor (train.eval_trained_actor).
TRAINED_ACTOR_KEYS = ("success_rate", "success_air_to_water", "success_water_to_air")
_SUMMED = ("episodes", "return_sum", "success_sum", "learn_iters")          # counts, added as they are
_PER_UPDATE = ("critic_loss", "actor_loss", "alpha", "q", "policy_freq")     # weighted by learning iterations


# ------------------------------------------------------------------ metrics.csv
def eval_rows(config, seeds: list[int], steps: int, wall_s: float, pending: dict, ev: dict,
              trained: dict, updates) -> list[dict]:
    """metrics.csv rows (METRIC_COLUMNS) of one evaluation, one per seed row: the evaluation `ev`
    (and `trained`, the trained actor's, or {}), the training statistics accumulated in `pending`
    since the last evaluation, and the gradient updates done."""
    rows = []
    for i, seed in enumerate(seeds):
        p = {k: v[i] for k, v in pending.items()}
        eps = p["episodes"]
        learn = p["learn_iters"]
        row = {"env_steps": steps, "wall_time_s": round(wall_s, 3), "seed": seed,
               "success_rate": float(ev["success_rate"][i]), "episode_return": float(ev["episode_return"][i]),
               "train_episode_return": p["return_sum"] / eps if eps else math.nan,
               "train_success_rate": p["success_sum"] / eps if eps else math.nan,
               "train_episodes": int(eps),
               "critic_loss": p["critic_loss"] / learn if learn else math.nan,
               "actor_loss": p["actor_loss"] / learn if learn else math.nan,
               "alpha": p["alpha"] / learn if learn and config.agent.algo == "sac" else math.nan,
               "q": p["q"] / learn if learn else math.nan,
               "policy_freq": p["policy_freq"] / learn if learn else math.nan,
               "grad_updates": int(updates[i])}
        for k in TRAINED_ACTOR_KEYS:
            row[f"trained_actor_{k}"] = float(trained[k][i]) if k in trained else math.nan
        for k in ("success_air_to_water", "success_water_to_air", *FAILURE_COLUMNS):  # train.eval_paper_pairs
            row[k] = float(ev[k][i]) if k in ev else math.nan
        rows.append(row)
    return rows


def write_header(path: Path, columns: list[str] = METRIC_COLUMNS) -> None:
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerow(columns)


def append_rows(path: Path, rows: list[dict], columns: list[str] = METRIC_COLUMNS) -> None:
    """Appends rows to a metrics CSV (floats to 6 significant digits)."""
    with open(path, "a", newline="") as fh:
        w = csv.DictWriter(fh, columns)
        for row in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})


def truncate_metrics(path: Path, env_steps: int) -> list[dict]:
    """Drops rows written after the checkpoint being resumed (they will be written again) and returns
    the rows of the last evaluation kept (as dicts of strings; [] if none). A file written by an
    older version with fewer columns gets today's header, its rows re-aligned by column name (the
    new columns left empty), so the rows appended after the resume line up."""
    if not path.is_file():
        write_header(path)
        return []
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    keep = [r for r in body if r and int(float(r[0])) <= env_steps]
    if header != METRIC_COLUMNS and set(header) <= set(METRIC_COLUMNS):
        keep = [[dict(zip(header, r)).get(c, "") for c in METRIC_COLUMNS] for r in keep]
        header = METRIC_COLUMNS
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(keep)
    last = [dict(zip(header, r)) for r in keep if r[0] == keep[-1][0]] if keep else []
    return last


# ------------------------------------------------------------------ between evaluations
def empty_pending(num_seeds: int) -> dict:
    return {k: [0.0] * num_seeds for k in _SUMMED + _PER_UPDATE}


def accumulate(pending: dict, m: dict) -> None:
    """Adds a chunk's per-seed metrics to the totals since the last evaluation (losses weighted by
    the chunk's learning iterations)."""
    learn = np.asarray(m["learn_iters"], np.float64)
    for k in pending:
        if k in _SUMMED:
            add = np.asarray(m[k], np.float64)
        elif k in m:
            add = np.asarray(m[k], np.float64) * learn
        else:
            add = np.zeros_like(learn)
        pending[k] = [float(a + b) for a, b in zip(pending[k], add)]


# ------------------------------------------------------------------ TensorBoard and the progress line
def log_chunk(writer, m: dict, env_steps: int, sps: float) -> None:
    """TensorBoard scalars of one chunk (all seeds pooled)."""
    eps = float(np.sum(m["episodes"]))
    if eps:
        writer.add_scalar("train/episode_return", float(np.sum(m["return_sum"])) / eps, env_steps)
        writer.add_scalar("train/success_rate", float(np.sum(m["success_sum"])) / eps, env_steps)
    for k in ("critic_loss", "actor_loss", "alpha", "alpha_loss", "q", "policy_freq"):
        if k in m and float(np.sum(m["learn_iters"])):
            writer.add_scalar(f"train/{k}", float(np.mean(m[k])), env_steps)
    writer.add_scalar("train/env_steps_per_s", sps, env_steps)
    for k in ("levels_learnability", "levels_success", "levels_route", "levels_flyable"):  # a level pool's
        if k in m:
            writer.add_scalar(f"levels/{k[len('levels_'):]}", float(np.mean(m[k])), env_steps)
    if "updates" in m:  # absent with train.updates_per_step 0
        writer.add_scalar("train/grad_updates_in_chunk", float(np.mean(m["updates"])), env_steps)


def eval_success(rows: list[dict]) -> float:
    """Mean success over the seed rows of one evaluation (rows as written or as read back)."""
    return float(np.mean([float(r["success_rate"]) for r in rows])) if rows else math.nan


def stats_line(m: dict, last_eval_success: float) -> str:
    eps = float(np.sum(m["episodes"]))
    ret = f"{float(np.sum(m['return_sum'])) / eps:.1f}" if eps else "n/a"
    succ = f"{float(np.sum(m['success_sum'])) / eps:.2f}" if eps else "n/a"
    parts = [f"train return {ret}", f"train success {succ}", f"eval success {last_eval_success:.2f}"]
    for name, k in (("critic", "critic_loss"), ("actor", "actor_loss"), ("alpha", "alpha")):
        if k in m:  # the losses are absent with train.updates_per_step 0
            parts.append(f"{name} {float(np.mean(m[k])):.3g}")
    return "  ".join(parts)


def duration(seconds: float) -> str:
    """'1 h 05 min', '4 min 10 s', '12 s'."""
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 60} min {s % 60:02d} s" if s >= 60 else f"{s} s"
