"""A run directory, and reading a trained policy back from it.

    <run_dir>/config.yaml      the resolved config (every key, overrides applied)
    <run_dir>/metrics.csv      one row per seed per evaluation (see `METRIC_COLUMNS`)
    <run_dir>/tb/              TensorBoard event files (tensorboardX), training metrics every chunk
    <run_dir>/checkpoints/<env_steps>/{state,policy,meta}   Orbax (see `docrl_jax.checkpoint`)

`load_policy(run_dir, seed_index, which)` returns the evaluation contract's `Policy` (docrl_jax.policy)
for a finished or interrupted run: the final policy of the latest checkpoint, or with which="best"
that checkpoint's best policy of the seed (docrl_jax.best_policy). `Policy.source` says which.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp

from docrl_jax import checkpoint
from docrl_jax.config import Config, ConfigError, load_config
from docrl_jax.policy import Policy, RunDirError

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


WHICH = ("final", "best")


def load_policy(run_dir: str | Path, seed_index: int = 0, which: str = "final") -> Policy:
    """The deterministic policy of seed `seed_index` from the latest checkpoint of `run_dir`: the run's
    policy at that checkpoint (`which="final"`, what tables report) or the best evaluated one so far
    (`which="best"`). Raises RunDirError for a missing directory, config or checkpoint, a corrupt
    checkpoint, an incompatible config, a seed index out of range, or a run without best policies."""
    from docrl_jax import best_policy
    from docrl_jax.algorithms import make_agent

    if which not in WHICH:
        raise RunDirError(f"which={which!r}: valid choices are {', '.join(WHICH)}")
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
