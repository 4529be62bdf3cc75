"""A run directory, and reading a trained policy back from it.

    <run_dir>/config.yaml      the resolved config (every key, overrides applied)
    <run_dir>/metrics.csv      one row per seed per evaluation (see `METRIC_COLUMNS`)
    <run_dir>/tb/              TensorBoard event files (tensorboardX), training metrics every chunk
    <run_dir>/checkpoints/<env_steps>/{state,policy,best,meta}   Orbax (see `docrl_jax.checkpoint`)

The metrics.csv rows are made here too (`eval_rows`, `accumulate`, `append_rows`, `truncate_metrics`),
shared by the trainer (docrl_jax.cli) and sweeps (docrl_jax.sweep).

`load_policy(run_dir, seed_index, which)` returns the evaluation contract's `Policy` (docrl_jax.policy)
for a finished or interrupted run: the final policy of the latest checkpoint, or with which="best"
that checkpoint's best policy of the seed (docrl_jax.best_policy). `Policy.source` says which.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax import checkpoint
from docrl_jax.config import Config, ConfigError, load_config
from docrl_jax.policy import CHECKPOINT_POLICIES, Policy, RunDirError

CONFIG_FILE = "config.yaml"
METRICS_FILE = "metrics.csv"
TB_DIR = "tb"

# metrics.csv: the first five are the evaluator's contract; the rest may grow.
# Fractions of the paper-pair evaluation episodes (train.eval_paper_pairs) that ended in a collision
# or out of bounds; with the success fraction, the rest are time-outs. Added 2026-11-23: older runs'
# metrics.csv lack them, and a resume rewrites the header with them (empty in the old rows).
FAILURE_COLUMNS = ["collision_air_to_water", "out_of_bounds_air_to_water", "collision_water_to_air",
                   "out_of_bounds_water_to_air"]
METRIC_COLUMNS = ["env_steps", "wall_time_s", "seed", "success_rate", "episode_return",
                  "success_air_to_water", "success_water_to_air", "train_episode_return", "train_success_rate",
                  "train_episodes", "critic_loss", "actor_loss", "alpha", "q", "policy_freq", "grad_updates",
                  "trained_actor_success_rate", "trained_actor_success_air_to_water",
                  "trained_actor_success_water_to_air", *FAILURE_COLUMNS]
# The evaluation results also recorded for the trained (not averaged) actor (train.eval_trained_actor).
TRAINED_ACTOR_KEYS = ("success_rate", "success_air_to_water", "success_water_to_air")


def read_config(run_dir: str | Path) -> Config:
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunDirError(f"run directory {str(run_dir)!r} does not exist")
    path = run_dir / CONFIG_FILE
    if not path.is_file():
        raise RunDirError(f"{str(run_dir)!r} has no {CONFIG_FILE}; is it a docrl_jax run directory?")
    try:
        return load_config(path, check_memory=False)
    except ConfigError as e:
        raise RunDirError(f"{path}: incompatible config ({e})") from None


def policy_abstract(agent, config: Config):
    """Shapes of the actor params stacked over seeds, as stored in a checkpoint's `policy` item."""
    keys = jnp.stack([jax.random.PRNGKey(0)] * config.train.num_seeds)
    return jax.eval_shape(jax.vmap(agent.init), keys).actor


def load_policy(run_dir: str | Path, seed_index: int = 0, which: str = "final") -> Policy:
    """The deterministic policy of seed `seed_index` from the latest checkpoint of `run_dir`: the run's
    policy at that checkpoint (`which="final"`, what tables report) or the best evaluated one so far
    (`which="best"`). Raises RunDirError for a missing directory, config or checkpoint, a corrupt
    checkpoint, an incompatible config, a seed index out of range, or a run without best policies."""
    from docrl_jax import best_policy
    from docrl_jax.algorithms import make_agent

    if which not in CHECKPOINT_POLICIES:
        raise RunDirError(f"which={which!r}: valid choices are {', '.join(CHECKPOINT_POLICIES)}")
    config = read_config(run_dir)
    if not 0 <= seed_index < config.train.num_seeds:
        raise RunDirError(f"seed_index={seed_index}: the run has num_seeds={config.train.num_seeds} "
                          f"(valid indices 0..{config.train.num_seeds - 1})")
    step = checkpoint.latest_step(run_dir)
    if step is None:
        raise RunDirError(f"{str(run_dir)!r} has no checkpoint under {checkpoint.CHECKPOINT_DIR}/")
    agent = make_agent(config)
    mngr = checkpoint.manager(run_dir)
    if which == "best" and not checkpoint.has_best(mngr, step):
        raise RunDirError(f"checkpoint {step} in {str(run_dir)!r} holds no best policy (trained with "
                          f"train.track_best_policy false, or before best-policy tracking existed); "
                          f"which='final' loads its final policy")
    try:
        _, stacked, meta = checkpoint.restore(mngr, step, abstract_policy=policy_abstract(agent, config),
                                              item="best" if which == "best" else "policy")
    except Exception as e:  # orbax raises many types for unreadable data; all mean the same here
        raise RunDirError(f"checkpoint {step} in {str(run_dir)!r} is corrupt or does not match config.yaml: "
                          f"{type(e).__name__}: {e}") from None
    params = jax.tree.map(lambda x: x[seed_index], stacked)
    source = (best_policy.describe(meta["best"], seed_index) + f", kept in checkpoint {step}" if which == "best"
              else f"final policy of seed index {seed_index}: checkpoint {step}")
    memory = config.agent.actor == "lstm" and config.agent.memory

    def init_carry():
        return agent.actor.init_carry(())

    def act(params, carry, obs, info, key):
        """Deterministic action (TD3/DDPG: actor output; SAC: tanh(mean)); info and key unused."""
        if not memory:
            carry = init_carry()
        return agent.act(params, carry, obs)

    return Policy(name=config.name, params=params, init_carry=init_carry, act=act, source=source)


# ------------------------------------------------------------------ metrics.csv rows
def eval_rows(config: Config, seeds: list[int], steps: int, wall_s: float, pending: dict, ev: dict,
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


def append_rows(path: Path, rows: list[dict], columns: list[str] = METRIC_COLUMNS) -> None:
    """Appends rows to a metrics CSV (floats to 6 significant digits)."""
    with open(path, "a", newline="") as fh:
        w = csv.DictWriter(fh, columns)
        for row in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})


def empty_pending(num_seeds: int) -> dict:
    keys = ("episodes", "return_sum", "success_sum", "learn_iters", "critic_loss", "actor_loss", "alpha", "q",
            "policy_freq")
    return {k: [0.0] * num_seeds for k in keys}


def accumulate(pending: dict, m: dict) -> None:
    """Adds a chunk's per-seed metrics to the totals since the last evaluation (losses weighted by
    the chunk's learning iterations). Kept as plain floats so it fits the checkpoint's JSON."""
    learn = np.asarray(m["learn_iters"], np.float64)
    for k in pending:
        if k in ("episodes", "return_sum", "success_sum", "learn_iters"):
            add = np.asarray(m[k], np.float64)
        elif k in m:
            add = np.asarray(m[k], np.float64) * learn
        else:
            add = np.zeros_like(learn)
        pending[k] = [float(a + b) for a, b in zip(pending[k], add)]


def truncate_metrics(path: Path, env_steps: int) -> None:
    """Drops rows written after the checkpoint being resumed (they will be written again). A file
    written by an older version with fewer columns gets today's header, its rows re-aligned by
    column name (the new columns left empty), so the rows appended after the resume line up."""
    if not path.is_file():
        with open(path, "w", newline="") as fh:
            csv.writer(fh).writerow(METRIC_COLUMNS)
        return
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
