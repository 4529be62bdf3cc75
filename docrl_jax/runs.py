"""A run directory: what it holds, reading its config and its trained policy back.

    <run_dir>/config.yaml      the resolved config (every key, overrides applied)
    <run_dir>/metrics.csv      one row per seed per evaluation (docrl_jax.train.metrics.METRIC_COLUMNS)
    <run_dir>/tb/              TensorBoard event files, training metrics every chunk (and GIFs: train.video_every)
    <run_dir>/startup.json     compile time and launch-to-first-chunk seconds of the latest launch
    <run_dir>/checkpoints/<env_steps>/{state,policy,best,meta}   Orbax (docrl_jax.checkpoint)

A sweep directory (docrl_jax.train.sweep) holds `sweep.json` and one `cNN/` run-like folder per
combination, without checkpoints.

`load_policy(run_dir, seed_index, which)` returns the evaluation contract's `Policy`
(docrl_jax.policy) for a finished or interrupted run, from its latest checkpoint: by default the run's
policy, the seed's best evaluated one (docrl_jax.train.best_policy) where the checkpoint keeps best
policies, else the final one (`checkpoint_policy` is that rule); which="final" or "best" asks for one.
`Policy.which` and `Policy.source` say which was loaded, `policy_label` marks it in a table.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jnp

from docrl_jax import checkpoint
from docrl_jax.config import Config, ConfigError, load_config
from docrl_jax.errors import RunDirError, not_the_data, short_reason
from docrl_jax.policy import CHECKPOINT_POLICIES, RUN_POLICY_RULE, Policy

CONFIG_FILE = "config.yaml"
METRICS_FILE = "metrics.csv"
TB_DIR = "tb"
STARTUP_FILE = "startup.json"
SWEEP_FILE = "sweep.json"
# Files whose presence means a directory already holds a run (or a sweep) that a new one would overwrite.
RUN_FILES = (CONFIG_FILE, METRICS_FILE, checkpoint.CHECKPOINT_DIR, SWEEP_FILE)


def check_fresh(run_dir: str | Path) -> None:
    """Raises RunDirError when `run_dir` already holds a run or a sweep, even one that has not
    written a checkpoint yet: a new run there would overwrite its config and metrics."""
    run_dir = Path(run_dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise RunDirError(f"run directory {str(run_dir)!r} is a file, not a directory")
    held = [name for name in RUN_FILES if (run_dir / name).exists()]
    if held:
        resume = ("a sweep cannot be resumed" if SWEEP_FILE in held else
                  f"to continue it: --run-dir {run_dir} --resume")
        raise RunDirError(f"{str(run_dir)!r} already holds a run ({', '.join(held)}); {resume}; "
                          f"to start a new one, choose a fresh --run-dir")


def read_config(run_dir: str | Path) -> Config:
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunDirError(f"run directory {str(run_dir)!r} does not exist")
    path = run_dir / CONFIG_FILE
    if not path.is_file():
        raise RunDirError(f"{str(run_dir)!r} has no {CONFIG_FILE}; is it a docrl_jax run directory?")
    try:
        return load_config(path)
    except ConfigError as e:
        raise RunDirError(f"{path}: incompatible config ({e})") from None


def policy_abstract(agent, config: Config):
    """Shapes of the actor params stacked over seeds, as stored in a checkpoint's `policy` item."""
    keys = jnp.stack([jax.random.PRNGKey(0)] * config.train.num_seeds)
    return jax.eval_shape(jax.vmap(agent.init), keys).actor


def describe_best(meta: dict, seed_index: int) -> str:
    """One line saying which evaluation a seed's best policy (a checkpoint's meta["best"]) comes from."""
    ev = meta["evaluation"][seed_index]
    names = {"success_air_to_water": "A-W", "success_water_to_air": "W-A", "success_rate": "random goals"}
    parts = [f"{names[k]} {v:.2f}" for k, v in ev.items()]
    step = meta["env_steps"][seed_index]
    return f"best policy of seed index {seed_index}: the evaluation at env step {step:,} ({', '.join(parts)})"


def _check_which(which: str | None) -> None:
    if which is not None and which not in CHECKPOINT_POLICIES:
        raise RunDirError(f"which={which!r}: valid choices are {', '.join(CHECKPOINT_POLICIES)}, or None for "
                          f"the run's policy ({RUN_POLICY_RULE})")


def _latest_step(run_dir: str | Path) -> int:
    step = checkpoint.latest_step(run_dir)
    if step is None:
        raise RunDirError(f"{str(run_dir)!r} has no checkpoint under {checkpoint.CHECKPOINT_DIR}/")
    return step


def _kept_policy(mngr, step: int, which: str | None) -> str:
    # The run's policy is its best evaluated one where kept: a final policy is one sample of the swing of
    # the last evaluations, and some seeds end below their best (docs/BENCHMARKS.md, the 10-seed table).
    if which is not None:
        return which
    return "best" if checkpoint.has_best(mngr, step) else "final"


def checkpoint_policy(run_dir: str | Path, which: str | None = None) -> str:
    """Which policy of the latest checkpoint `load_policy(run_dir, which=which)` loads, "final" or "best":
    `which` itself when given; None = the run's policy, "best" where the checkpoint keeps best policies
    (train.track_best_policy), else "final". Raises RunDirError for an invalid `which` or a run directory
    without a checkpoint."""
    _check_which(which)
    return _kept_policy(checkpoint.manager(run_dir), _latest_step(run_dir), which)


def policy_label(name: str, which: str) -> str:
    """A method's name in a table for a run's policy: " (best)" marks a best policy (a final one is unmarked,
    as in every table made before best policies were the default)."""
    return name + " (best)" if which == "best" else name


def load_policy(run_dir: str | Path, seed_index: int = 0, which: str | None = None) -> Policy:
    """The deterministic policy of seed `seed_index` from the latest checkpoint of `run_dir`: which=None
    (default) the run's policy (`checkpoint_policy`: the best evaluated one where kept, else the final
    one), "final" the Polyak-averaged actor at that checkpoint, "best" the best evaluated one so far.
    `Policy.which` says which it loaded. Raises RunDirError for a missing directory, config or checkpoint,
    a corrupt checkpoint, an incompatible config, a seed index out of range, or which="best" on a run
    without best policies."""
    from docrl_jax.algorithms import make_agent

    _check_which(which)
    config = read_config(run_dir)
    if not 0 <= seed_index < config.train.num_seeds:
        raise RunDirError(f"seed_index={seed_index}: the run has num_seeds={config.train.num_seeds} "
                          f"(valid indices 0..{config.train.num_seeds - 1})")
    step = _latest_step(run_dir)
    agent = make_agent(config)
    mngr = checkpoint.manager(run_dir)
    which = _kept_policy(mngr, step, which)
    if which == "best" and not checkpoint.has_best(mngr, step):
        raise RunDirError(f"checkpoint {step} in {str(run_dir)!r} holds no best policy (trained with "
                          f"train.track_best_policy false, or before best-policy tracking existed); "
                          f"which='final' loads its final policy")
    try:
        _, stacked, meta = checkpoint.restore(mngr, step, abstract_policy=policy_abstract(agent, config),
                                              item="best" if which == "best" else "policy")
    except Exception as e:  # orbax raises many types for unreadable data; all mean the same here
        what = f"checkpoint {step} in {str(run_dir)!r}"
        raise not_the_data(e, what) or RunDirError(f"{what} is corrupt or does not match config.yaml: "
                                                   f"{short_reason(e)}") from None
    params = jax.tree.map(lambda x: x[seed_index], stacked)
    source = (describe_best(meta["best"], seed_index) + f", kept in checkpoint {step}" if which == "best"
              else f"final policy of seed index {seed_index}: checkpoint {step}")
    return replace(actor_policy(config, params, source, agent), which=which)


def actor_policy(config: Config, params, source: str = "", agent=None) -> Policy:
    """The deterministic `Policy` of one seed's actor `params` under `config` (what `load_policy`
    returns; the trainer's videos build it from the actor being trained). Its functions are new on
    every call: keep one and `dataclasses.replace` its params to reuse a compiled rollout."""
    if agent is None:
        from docrl_jax.algorithms import make_agent
        agent = make_agent(config)
    recurrent = config.agent.recurrent

    def init_carry():
        return agent.actor.init_carry(())

    def act(params, carry, obs, info, key):
        """Deterministic action (TD3/DDPG: actor output; SAC: tanh(mean)); info and key unused."""
        if not recurrent:
            carry = init_carry()
        return agent.act(params, carry, obs)

    return Policy(name=config.name, params=params, init_carry=init_carry, act=act, source=source)
