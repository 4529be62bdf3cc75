"""The trainer's configuration: schema, YAML loading, `--set` overrides and validation.

A run is configured by one YAML file with the sections `env`, `agent`, `replay` and `train`
(see `configs/*.yaml`); every field is declared and documented below, CleanRL style. Loading goes

    YAML file (bare name -> packaged `configs/`, else a path)  ->  `--set section.key=value` overrides
    ->  type coercion  ->  `validate` (before anything is compiled)  ->  frozen, hashable `Config`

Errors are `ConfigError` (a ValueError) and name the key, the bad value and what is allowed.
`Config` is hashable so that `make_trainer(config)` can be memoised and reuse compiled programs.

Why one long module: about half of it is the ~50 field declarations, each with its documentation
where it is declared (the one place a user reads what a key means); the loading and validation that
read those declarations stay beside them, so a new key is added, documented and checked in one file.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from docrl_jax import schema
from docrl_jax.errors import ConfigError  # noqa: F401  (re-exported: docrl_jax.config.ConfigError)
from docrl_jax.schema import documented


# What `auto` sizes resolve to, by JAX backend ("gpu" also stands for "tpu"): envs per seed, and
# replay steps kept per env (buffer_size = num_envs x that).
AUTO_NUM_ENVS = {"gpu": 4096, "cpu": 64}
AUTO_STEPS_PER_ENV = {"gpu": 256, "cpu": 1024}
# Vectorised steps per compiled chunk for `train.log_every: auto` (log_every = num_envs x that): on a
# GPU a chunk of 100 takes ~1.5 s; on a 2-core CPU 10 already take ~10-30 s, and the progress line,
# its ETA and Ctrl-C all wait for the chunk to end.
AUTO_ITERS_PER_CHUNK = {"gpu": 100, "cpu": 10}
# `agent.critic_dtype: auto`: bf16 activations where they are faster (an H100 update: -35 %); on a
# CPU XLA emulates bf16 matmuls and a td3_lstm iteration is ~10 % slower with them.
AUTO_CRITIC_DTYPE = {"gpu": "bfloat16", "cpu": "float32"}


@dataclass(frozen=True)
class EnvConfig:
    scenario: int = documented(2,
        "Tank layout: 1 empty, 2 four risers (the paper's training scenario), 3 fifteen obstacles; 0 = "
        "procedural tanks, a new layout every episode (docrl_jax/envs/layouts.py).", (0, 1, 2, 3))
    num_envs: int = documented(256, "Environments stepped in parallel (per seed). Each vectorised step adds num_envs "
                                    "transitions; see train.updates_per_step for the update-to-data ratio. 'auto' = "
                                    f"{AUTO_NUM_ENVS['gpu']} on a GPU/TPU (the simulator saturates there), "
                                    f"{AUTO_NUM_ENVS['cpu']} on a CPU; resolved when the config is loaded.")
    overrides: tuple = documented((), "Not a YAML key: every other key under `env:` is an `EnvParams` field "
                                      "(docrl_jax/envs/params.py), e.g. wind, max_goal_distance, progress_reward_scale.")

    def env_kwargs(self) -> dict[str, Any]:
        return dict(self.overrides)


@dataclass(frozen=True)
class AgentConfig:
    algo: str = documented("td3", "td3 = DoCRL-D (clipped double-Q, target smoothing, delayed policy); sac = DoCRL-S "
                                  "(tanh-Gaussian actor, learned temperature); ddpg = the paper's 'Det.' row "
                                  "(one critic, no smoothing, no delay).", ("td3", "sac", "ddpg"))
    actor: str = documented("lstm", "Actor network: lstm (the paper's) or mlp (the 'Det.'/'Sto.' baselines).", ("lstm", "mlp"))
    actor_hidden: tuple = documented((32,), "lstm: one entry, the LSTM units (orig 32), followed by Linear(3). "
                                            "mlp: the hidden widths (orig DDPG 512-512, SAC 256-256).")
    critic_hidden: tuple = documented((512, 512), "Hidden widths of each critic MLP on concat(obs, action) "
                                                  "(orig TD3 512-512, SAC 256-256).")
    memory: bool = documented(True, "true: the LSTM carry flows from step to step and resets at episode start. "
                                    "false: zero carry on every call, the original's memoryless LSTM "
                                    "(requires replay.burn_in 0).")
    actor_lr: float = documented(1e-3, "Adam learning rate of the actor (paper 1e-3).")
    critic_lr: float = documented(1e-3, "Adam learning rate of the critics (paper 1e-3).")
    alpha_lr: float = documented(1e-3, "SAC: Adam learning rate of log(alpha) (paper 1e-3 for all optimisers).")
    gamma: float = documented(0.99, "Discount (paper 0.99).")
    tau: float = documented(0.001, "Soft target update rate (paper silent; orig TD3/DDPG 0.001, SAC 0.01).")
    policy_freq: int = documented(0, "Critic updates per actor (and target) update. 0 = the paper's schedule "
                                     "int(1/(0.5 - t/(3*max_steps))) with t = max_steps * training progress "
                                     "(env steps done / total_env_steps): 2, then 3 from 50%, 4 from 75%, 5 from 90% (6 on the last step). "
                                     "k > 0 = fixed delay k (orig TD3 2, SAC 1).")
    policy_noise: float = documented(0.2, "TD3 target-policy smoothing: std of the Gaussian noise on a' (paper "
                                          "silent on the value; TD3 paper 0.2; the original code had it commented out).")
    noise_clip: float = documented(0.5,
        "TD3: the smoothing noise is clipped to [-noise_clip, noise_clip] (TD3 paper 0.5).")
    ou_theta: float = documented(0.15, "TD3/DDPG exploration: Ornstein-Uhlenbeck mean reversion per step (orig 0.15).")
    ou_sigma: float = documented(0.075, "TD3/DDPG: OU noise scale at the start, in action units [-1, 1] "
                                        "(orig TD3-LSTM 0.075; DDPG 0.71).")
    ou_sigma_final: float = documented(0.03, "TD3/DDPG: OU scale reached linearly at the end of training "
                                             "(orig floor 0.03 for TD3-LSTM, 0.2 for DDPG).")
    target_entropy: float = documented(-3.0, "SAC: target entropy of the temperature loss (orig -3 = -action size).")
    init_alpha: float = documented(1.0, "SAC: initial temperature (orig log alpha = 0, i.e. 1).")
    critic_layer_norm: bool = documented(False,
        "LayerNorm before every hidden ReLU of the critics (ours; the paper's "
        "critics have none). Keeps Q stable with large batches and high rates.")
    critic_dtype: str = documented("float32",
        "Dtype of the critics' activations: float32 (the paper's), bfloat16, or 'auto' = "
        "bfloat16 on a GPU/TPU and float32 on a CPU (ours). Parameters, optimiser state, "
        "targets and losses stay float32. bfloat16 halves the memory traffic of the "
        "critics' layers and LayerNorms, which is what an update spends its time on "
        "(docs/BENCHMARKS.md, 'What an update costs').", ("float32", "bfloat16"))
    n_step: int = documented(1, "TD target over n rewards inside each sampled sequence (1 = the paper's one-step "
                                "target); never crosses an episode end or the sequence end (common.nstep_targets).")
    lr_end_scale: float = documented(1.0,
        "All learning rates fall linearly with env-step progress from their value to "
        "lr_end_scale x their value at total_env_steps (1 = constant, the paper's).")
    policy_average_tau: float = documented(1.0,
        "The run's policy (evaluated, checkpointed, loaded) is a Polyak average "
        "of the trained actor: after every actor update, average <- (1 - tau) "
        "average + tau actor. 1 = the trained actor itself (the paper's). Ours: "
        "0.001 averages over ~1,000 actor updates, which damps the swings of "
        "the trained actor between evaluations.")

    @property
    def recurrent(self) -> bool:
        """True when the actor carries state from step to step (an LSTM with memory): the one rule
        for stored carries, burn-in and carry resets at episode starts."""
        return self.actor == "lstm" and self.memory


@dataclass(frozen=True)
class ReplayConfig:
    buffer_size: int = documented(50_000, "Transitions kept per seed, all envs together (paper silent; orig 50,000). "
                                          "Each env keeps buffer_size // num_envs steps of its own trajectory. 'auto' = "
                                          f"num_envs x {AUTO_STEPS_PER_ENV['gpu']} on a GPU/TPU, num_envs x "
                                          f"{AUTO_STEPS_PER_ENV['cpu']} on a CPU.")
    batch_size: int = documented(256, "Sequences per gradient update (paper minibatch 256). With seq_len 1 this is "
                                      "256 transitions, as in the paper.")
    seq_len: int = documented(16, "Steps per sampled sequence (burn-in included). 1 = single transitions.")
    burn_in: int = documented(8, "Leading steps of each sequence that only warm the LSTM up from the stored carry "
                                 "(no gradient, no loss); the loss uses the remaining seq_len - burn_in steps.")


@dataclass(frozen=True)
class TrainConfig:
    total_env_steps: int = documented(2_000_000, "Environment steps per seed, all envs together (paper: up to 1500 "
                                                 "episodes of 500 steps = 750k). Rounded up to whole chunks.")
    seed: int = documented(0, "Seed of the first run; seed index i uses seed + i.")
    num_seeds: int = documented(1, "Independent seeds trained in one program: vmapped on each device, and split over "
                                   "the devices of train.devices along a 'seed' mesh axis.")
    devices: int = documented(0,
        "Devices the seeds are split over (docrl_jax/sharding.py). 0 or 'all' = every device "
        "of every process (jax.devices()), or the largest count that divides num_seeds if "
        "they do not (a note says so); N = the first N devices, which must divide num_seeds. "
        "Each device trains num_seeds / devices seeds (vmapped; one seed per device runs the "
        "faster unbatched program). Multi-process runs (--distributed) use 0. May change on "
        "--resume: checkpoints are resharded onto the current devices.")
    start_steps: int = documented(10_000, "Env steps (all envs together) of uniform random actions before the actor "
                                          "acts and updates start (paper names start_steps without a value; orig "
                                          "waited for 1,024 transitions).")
    updates_per_step: int = documented(4, "Gradient updates after each vectorised env step (num_envs transitions). "
                                          "Update-to-data ratio = updates_per_step / num_envs updates per transition "
                                          "(orig: 1 env, 1 update per step). 0 = none: the policy stays as "
                                          "initialised (env-only throughput, or a fixed policy's evaluations).")
    log_every: int = documented(20_000, "Env steps per compiled chunk: Python logs, checks losses and may evaluate "
                                        "or checkpoint only between chunks (a Ctrl-C waits for the chunk to end). "
                                        f"'auto' = num_envs x {AUTO_ITERS_PER_CHUNK['gpu']} on a GPU/TPU, num_envs x "
                                        f"{AUTO_ITERS_PER_CHUNK['cpu']} on a CPU.")
    eval_every: int = documented(100_000, "Env steps between deterministic evaluations (at the first chunk boundary "
                                          "at or after each multiple, and at step 0 and at the end).")
    eval_every_minutes: float = documented(10.0,
        "Also evaluate when this many wall-clock minutes have passed since the "
        "last evaluation, so a slow device (a CPU) still writes learning curves; "
        "on a GPU the env-step cadence eval_every comes first.")
    eval_episodes: int = documented(64, "Evaluation episodes per seed, run in parallel, each until arrival, "
                                        "termination or the step limit, on the training distribution of starts/goals.")
    eval_paper_pairs: bool = documented(False, "Also evaluate the paper's air-to-water and water-to-air pairs "
                                               "(eval_episodes each, columns success_air_to_water/_water_to_air).")
    eval_pair_scenario: int = documented(2,
        "Scenario whose paper pairs eval_paper_pairs runs when env.scenario is 0 (procedural tanks); a run in "
        "scenario 1-3 evaluates its own scenario's pairs. The pair episodes run the nominal plant (no dr_* "
        "randomisation), as the paper's test does.", (1, 2, 3))
    eval_pair_starts: str = documented("paper", "Starts of the paper-pair episodes: 'paper' = the evaluator's trials "
                                                "(docrl_jax.evaluate.protocol: nominal yaw +-0.1 rad, start +-0.1 m), so the "
                                                "columns estimate what `evaluate` reports; 'random_yaw' = the exact "
                                                "start facing a uniformly random yaw, a stricter test (the trainer's "
                                                "first test; W-A 5-38 points lower on the same final policies, "
                                                "benchmarks/results/cpu/pair_starts.md).", choices=("paper", "random_yaw"))
    eval_trained_actor: bool = documented(False, "With agent.policy_average_tau < 1: also evaluate the trained (not "
                                                 "averaged) actor on the same episodes, columns trained_actor_* "
                                                 "(an ablation; doubles the evaluation time).")
    eval_alongside: bool = documented(False,
        "Run each periodic evaluation's episodes alongside training, as extra lanes of the chunk's "
        "vectorised env step driven by a frozen copy of the policy, instead of pausing training for them "
        "(on a GPU a pause per evaluation of latency-bound steps; alongside, the lanes cost 3.6 % of the "
        "chunks' pace and the default td3_lstm ends 11 % sooner on an H100, docs/BENCHMARKS.md). Same "
        "episodes, same starts, same rows "
        "(docrl_jax/train/evaluation.py); a row is written when its last episode has ended, up to "
        "env.max_episode_steps iterations later, and an evaluation that falls due meanwhile waits for it. "
        "The final evaluation, and one still running at a checkpoint or a stop, pause training as before. "
        "'auto' = on for a GPU/TPU where it is possible, off on a CPU (where every lane costs its full "
        "share of a step). Not possible with eval_trained_actor, nor when the paper pairs need an env of "
        "their own (a procedural or domain-randomised run).")
    track_best_policy: bool = documented(True,
        "Keep each seed's best evaluated policy so far (by the paper pairs' weaker "
        "direction with eval_paper_pairs, else random-goal success; ties to the "
        "later) in every checkpoint's best/ item, beside the final policy; "
        "load_policy(which='best') and evaluate --which best read it "
        "(docrl_jax/best_policy.py). Tables report the final policy.")
    checkpoint_every: int = documented(200_000,
        "Env steps between Orbax checkpoints (plus one at the end and on Ctrl-C).")
    checkpoint_every_minutes: float = documented(10.0,
        "Also checkpoint when this many wall-clock minutes have passed since "
        "the last checkpoint, so a crash loses at most that much, whatever "
        "the device's speed.")
    keep_checkpoints: int = documented(3, "Most recent checkpoints kept on disk.")
    video_every: int = documented(0,
        "0 = off. N: a GIF of one water-to-air trial of the run's policy (seed index 0) in the run's "
        "TensorBoard (image video/water_to_air) at every Nth evaluation of a launch, the first "
        "included, and at the last: trial 1 of `python -m docrl_jax.render --direction water_to_air` "
        "in env.scenario (the evaluator's env and seeds). Drawn by MuJoCo's renderer on process 0 "
        "between chunks (seconds on a CPU; docrl_jax/train/tb_video.py); a machine that cannot "
        "render warns once and trains on. Runs only: sweeps draw none.")


@dataclass(frozen=True)
class LevelsConfig:
    sampler: str = documented("env",
        "Where a training episode's procedural tank comes from (env.scenario 0 without env.tank). 'env': each "
        "reset draws its own layout (env.layout_structures mixes in structured ones). 'uniform' and "
        "'learnability': a pool of levels.capacity layouts from the same generator, each checked flyable "
        "(docrl_jax/envs/flyability.py) before it enters, levels.refresh of them replaced with fresh ones "
        "every chunk; 'uniform' samples and replaces uniformly, 'learnability' samples by each level's "
        "learnability p(1 - p) (p: its training episodes' success, Beta(1, 1) prior) and replaces the least "
        "learnable (docrl_jax/envs/curriculum.py).", ("env", "uniform", "learnability"))
    capacity: int = documented(4096, "Levels in the pool.")
    refresh: int = documented(256, "Pool levels replaced by fresh, flyable ones at the start of every chunk.")
    temperature: float = documented(0.5, "learnability: draws are proportional to learnability^(1 / "
                                         "temperature) (lower = greedier).")
    uniform_mix: float = documented(0.3, "learnability: share of the draws spread uniformly over the pool, so "
                                         "every level keeps being played and its score stays current.")
    route_reward: float = documented(0.0,
        "Ours, training only: reward per metre a step takes off the flyable route to the goal's region (air or "
        "water) of the level, read from the distance field its flyability check computed, beside env's "
        "straight-line progress_reward_scale. The route knows the way round a wall or through a ceiling's "
        "opening, where the straight line pulls into the wall. The policy never sees the field. 0 = off; "
        "needs a level pool (levels.sampler uniform or learnability).")


@dataclass(frozen=True)
class Config:
    name: str = documented("td3_lstm", "Run name: prefix of the default run directory and the policy's name.")
    env: EnvConfig = field(default_factory=EnvConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    replay: ReplayConfig = field(default_factory=ReplayConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    levels: LevelsConfig = field(default_factory=LevelsConfig)


SECTIONS = {"env": EnvConfig, "agent": AgentConfig, "replay": ReplayConfig, "train": TrainConfig,
            "levels": LevelsConfig}


def field_docs() -> dict[str, str]:
    """'section.key' -> documentation, for error messages and the README."""
    docs = {"name": schema.field_docs(Config)["name"]}
    for sec, cls in SECTIONS.items():
        docs.update(schema.field_docs(cls, sec))
    return docs


def config_keys() -> list[str]:
    """Every 'section.key' a config takes, the env parameters included."""
    from docrl_jax.envs import param_docs
    return [k for k in field_docs() if k != "env.overrides"] + [f"env.{k}" for k in param_docs() if k != "scenario"]


# ---------------------------------------------------------------------------------------- loading
def packaged_configs_dir() -> Path:
    """The repository's top-level `configs/` (a source checkout), else the installed `docrl_jax.configs`."""
    source = Path(__file__).resolve().parent.parent / "configs"
    if source.is_dir():
        return source
    return Path(str(resources.files("docrl_jax.configs")))


def packaged_config_names() -> list[str]:
    """The names `--config` takes without a path, sorted."""
    return sorted(p.stem for p in packaged_configs_dir().glob("*.yaml"))


def resolve_config_path(name_or_path: str | os.PathLike) -> Path:
    """A bare name ('td3_lstm' or 'td3_lstm.yaml') is looked up in the packaged configs; anything
    containing a path separator, or an existing file, is used as a path."""
    text = str(name_or_path)
    path = Path(text)
    if path.exists() and path.is_file():
        return path
    if os.sep in text or "/" in text:
        beside = sorted(p.name for p in path.parent.glob("*.yaml")) if path.parent.is_dir() else []
        raise ConfigError(f"config file {text!r} does not exist"
                          + schema.did_you_mean(path.name, beside, shown=lambda n: str(path.parent / n)))
    stem = text[:-5] if text.endswith(".yaml") else text
    packaged = packaged_configs_dir()
    candidate = packaged / f"{stem}.yaml"
    if candidate.is_file():
        return candidate
    names = packaged_config_names()
    raise ConfigError(f"config {text!r} is neither a file nor a packaged config; packaged configs: "
                      f"{', '.join(names)}{schema.did_you_mean(stem, names)}")


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """['agent.actor_lr=3e-4', 'env.wind=false'] -> {'agent.actor_lr': 0.0003, 'env.wind': False}.
    Values are YAML scalars (so lists work too: env.z_bounds=[-1.0,4.0])."""
    out: dict[str, Any] = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"override {item!r}: expected section.key=value")
        key, text = item.split("=", 1)
        try:
            out[key.strip()] = yaml.safe_load(text)
        except yaml.YAMLError as e:
            raise ConfigError(f"override {item!r}: value is not valid YAML ({e})") from None
    return out


def load_config(name_or_path: str | os.PathLike, overrides: list[str] | dict[str, Any] | None = None,
                backend: str | None = None, notes: list | None = None) -> Config:
    """Reads a YAML config, applies `--set` overrides, resolves `auto` sizes for the backend,
    validates; raises ConfigError. `notes` (a list) receives one line per `auto` value resolved.
    Whether the run fits its devices is `docrl_jax.memory.check_memory(config)`, a separate step
    because it needs the devices."""
    path = resolve_config_path(name_or_path)
    raw = _compose(path, ())
    if isinstance(overrides, list):
        overrides = parse_overrides(overrides)
    return config_from_dict(raw, overrides or {}, source=str(path), backend=backend, notes=notes)


def _compose(path: Path, chain: tuple[Path, ...]) -> dict:
    """The YAML of `path` with its references to other configs resolved, so that a recipe built on
    another one states only what differs:
      extends: NAME   -- start from config NAME; this file's keys replace its keys one by one
      SECTION: NAME   -- a section (env, agent, replay, train) is config NAME's section, whole
    NAME is a file relative to this one if there is one, else as `--config` takes it (a packaged name)."""
    path = path.resolve()
    if path in chain:
        raise ConfigError("configs extend each other in a cycle: " + " -> ".join(str(p) for p in (*chain, path)))
    try:
        raw = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: not valid YAML ({e})") from None
    if not isinstance(raw, dict):
        return raw  # config_from_dict names the problem

    def load(name: Any, key: str) -> dict:
        if not isinstance(name, str):
            raise ConfigError(f"{path}: {key!r} must name a config (a packaged name or a path), got {name!r}")
        beside = path.parent / name
        other = _compose(resolve_config_path(beside if beside.is_file() else name), (*chain, path))
        if not isinstance(other, dict):
            raise ConfigError(f"{path}: {key}: {name!r} is not a config (its top level is not a mapping)")
        return other

    # Every dict here is freshly parsed, so merging may build on them without copies.
    out = load(raw.pop("extends"), "extends") if "extends" in raw else {}
    for key, value in raw.items():
        if key in SECTIONS and isinstance(value, str):
            section = load(value, key).get(key)
            if not isinstance(section, dict):
                raise ConfigError(f"{path}: {key}: {value!r} names a config without a {key!r} section")
            value = section
        elif key in SECTIONS and isinstance(value, dict) and isinstance(out.get(key), dict):
            value = {**out[key], **value}
        out[key] = value
    return out


# The `auto` sizes that scale with env.num_envs: (section, key, value per env by backend, the note's
# explanation of the resolved value).
_AUTO_PER_ENV = (("replay", "buffer_size", AUTO_STEPS_PER_ENV, "{per} steps x {n:,} envs"),
                 ("train", "log_every", AUTO_ITERS_PER_CHUNK, "{per} vectorised steps per chunk"))


def resolve_auto(raw: dict, backend: str | None = None, notes: list | None = None) -> dict:
    """Replaces `env.num_envs: auto`, `replay.buffer_size: auto`, `train.log_every: auto` and
    `agent.critic_dtype: auto` by the values for `backend` (AUTO_NUM_ENVS, AUTO_STEPS_PER_ENV,
    AUTO_ITERS_PER_CHUNK, AUTO_CRITIC_DTYPE), and `train.eval_alongside: auto` by true on a GPU/TPU,
    false on a CPU; returns a new dict."""
    def is_auto(sec: str, key: str) -> bool:
        return isinstance(raw.get(sec), dict) and raw[sec].get(key) == "auto"

    if not any(is_auto(sec, key) for sec, key in [("env", "num_envs"), ("agent", "critic_dtype"),
                                                  ("train", "eval_alongside")] + [a[:2] for a in _AUTO_PER_ENV]):
        return raw
    if backend is None:
        import jax
        backend = jax.default_backend()
    kind = "cpu" if backend == "cpu" else "gpu"
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in raw.items()}
    if is_auto("env", "num_envs"):
        out["env"]["num_envs"] = AUTO_NUM_ENVS[kind]
        if notes is not None:
            notes.append(f"env.num_envs auto -> {AUTO_NUM_ENVS[kind]:,} ({backend})")
    if is_auto("agent", "critic_dtype"):
        out["agent"]["critic_dtype"] = AUTO_CRITIC_DTYPE[kind]
        if notes is not None:
            notes.append(f"agent.critic_dtype auto -> {AUTO_CRITIC_DTYPE[kind]} ({backend})")
    if is_auto("train", "eval_alongside"):  # whether the rest of the config allows it: config_from_dict
        out["train"]["eval_alongside"] = kind == "gpu"
    # The per-env sizes are multiples of num_envs, so a bad num_envs is reported here, by its own name,
    # rather than as an unresolvable 'auto' below.
    num_envs = _coerce("env.num_envs", out.get("env", {}).get("num_envs", EnvConfig.num_envs), int, None)
    if num_envs < 1:
        _bad("env.num_envs", num_envs, "must be >= 1")
    for sec, key, per_env, why in _AUTO_PER_ENV:
        if is_auto(sec, key):
            out[sec][key] = num_envs * per_env[kind]
            if notes is not None:
                notes.append(f"{sec}.{key} auto -> {out[sec][key]:,} ({why.format(per=per_env[kind], n=num_envs)})")
    return out


def config_from_dict(raw: dict, overrides: dict[str, Any] | None = None, source: str = "config", backend: str | None = None, notes: list | None = None) -> Config:
    """Builds and validates a Config from a YAML-like dict. `auto` sizes resolve for `backend`
    (default: JAX's default backend); a line per resolved value is appended to `notes`."""
    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: the top level must be a mapping with sections {['name', *SECTIONS]}")
    raw = {k: (dict(v) if isinstance(v, dict) else v) for k, v in raw.items()}
    for key, value in (overrides or {}).items():
        parts = key.split(".")
        if len(parts) == 1 and parts[0] == "name":
            raw["name"] = value
            continue
        if len(parts) == 2 and parts[0] not in SECTIONS:
            raise ConfigError(f"override {key!r}: unknown section {parts[0]!r}; sections: {', '.join(SECTIONS)}"
                              + schema.did_you_mean(parts[0], SECTIONS, shown=lambda sec: f"{sec}.{parts[1]}"))
        if len(parts) != 2:  # a bare key may be one of a section's: name it whole
            raise ConfigError(f"override {key!r}: expected section.key (sections: {', '.join(SECTIONS)})"
                              + schema.did_you_mean(parts[-1], config_keys(), key=lambda k: k.split(".")[-1]))
        section = raw.setdefault(parts[0], {})
        if not isinstance(section, dict):
            raise ConfigError(f"{source}: section {parts[0]!r} must be a mapping")
        section[parts[1]] = value
    unknown = sorted(set(raw) - {"name", *SECTIONS})
    if unknown:
        raise ConfigError(f"{source}: unknown top-level key {_first(unknown)}; valid keys: name, "
                          f"{', '.join(SECTIONS)}{schema.did_you_mean(unknown[0], ['name', *SECTIONS])}")
    alongside_auto = isinstance(raw.get("train"), dict) and raw["train"].get("eval_alongside") == "auto"
    raw = resolve_auto(raw, backend, notes)
    name = _coerce("name", raw.get("name", Config.name), str, None)
    built = {}
    for sec, cls in SECTIONS.items():
        values = raw.get(sec) or {}
        if not isinstance(values, dict):
            raise ConfigError(f"section {sec!r} must be a mapping, got {values!r}")
        built[sec] = _build_section(sec, cls, values)
    config = Config(name=name, **built)
    if alongside_auto:  # resolve_auto chose by backend; the rest of the config may rule it out
        why = alongside_blocker(config) if config.train.eval_alongside else "off on a CPU"
        if config.train.eval_alongside and why:
            config = dataclasses.replace(config, train=dataclasses.replace(config.train, eval_alongside=False))
        if notes is not None:
            notes.append(f"train.eval_alongside auto -> {str(config.train.eval_alongside).lower()}"
                         + (f" ({why})" if why else ""))
    validate(config)
    return config


def _build_section(sec: str, cls, values: dict) -> Any:
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "overrides"}
    hints = typing.get_type_hints(cls)
    kwargs, extra = {}, {}
    for key, value in values.items():
        if key in fields:
            kwargs[key] = _coerce(f"{sec}.{key}", value, hints[key], fields[key].metadata["choices"])
        else:
            extra[key] = value
    valid, listed = set(fields), f"the fields of {cls.__name__} in {schema.declared_in(cls)}"
    if sec == "env":  # every other key under env: is an EnvParams field
        from docrl_jax.envs import EnvParams, param_docs
        valid |= set(param_docs())
        listed = (f"{', '.join(f'env.{k}' for k in fields)} and the fields of EnvParams in "
                  f"{schema.declared_in(EnvParams)}")
        kwargs["overrides"] = tuple(sorted((k, _freeze(v)) for k, v in extra.items()))
    unknown = sorted(set(extra) - valid)
    if unknown:
        raise ConfigError(f"unknown key {_first([f'{sec}.{k}' for k in unknown])}; valid keys: {listed}"
                          + schema.did_you_mean(unknown[0], valid, shown=lambda k: f"{sec}.{k}"))
    return cls(**kwargs)


def _first(names: list[str]) -> str:
    """The first of the unknown names, quoted, and how many more there are: an error names one key."""
    return repr(names[0]) + (f" (and {len(names) - 1} more: {', '.join(map(repr, names[1:]))})" if names[1:] else "")


def _freeze(v: Any) -> Any:
    return tuple(_freeze(x) for x in v) if isinstance(v, (list, tuple)) else v


def _coerce(key: str, value: Any, typ: Any, choices: tuple | None) -> Any:
    """Checks one value against its declared type; ints are accepted for floats, and strings such as
    '3e-4' (which YAML 1.1 reads as text) are accepted for floats when they parse as numbers."""
    if typ is bool:
        if not isinstance(value, bool):
            also = " or 'auto'" if key == "train.eval_alongside" else ""
            raise ConfigError(f"{key}={value!r}: must be a bool (true or false){also}")
    elif typ is int:
        if key == "train.devices":
            if value == "all":
                value = 0
            elif isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"{key}={value!r}: must be 'all' (or 0: every device) or a device count >= 1")
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
                value = int(value)  # 1e6 written as 1.0e+6
            else:
                raise ConfigError(f"{key}={value!r}: must be an integer")
    elif typ is float:
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise ConfigError(f"{key}={value!r}: must be a number") from None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key}={value!r}: must be a number")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"{key}={value!r}: must be finite")
    elif typ is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}={value!r}: must be a string")
    elif typ is tuple:
        if isinstance(value, int) and not isinstance(value, bool):
            value = [value]
        if not isinstance(value, (list, tuple)) or not value or not all(
                isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value):
            raise ConfigError(f"{key}={value!r}: must be a non-empty list of positive integers, e.g. [256, 256]")
        value = tuple(value)
    if choices is not None and value not in choices:
        raise ConfigError(f"{key}={value!r}: valid choices are {list(choices)}")
    return value


# ---------------------------------------------------------------------------------------- validation
_bad = functools.partial(schema.fail, error=ConfigError)  # _bad(key, value, why) raises ConfigError


def validate(c: Config) -> Config:
    """Rejects impossible combinations before anything is compiled."""
    from docrl_jax.envs import make_params
    e, a, r, t = c.env, c.agent, c.replay, c.train
    try:
        make_params(e.scenario, **_env_kwargs_for_params(e))
    except ValueError as err:
        raise ConfigError(f"env: {err}") from None
    if not c.name or any(ch in c.name for ch in "/\\"):
        _bad("name", c.name, "must be a non-empty name without path separators")
    for key, value, lo in [("env.num_envs", e.num_envs, 1), ("replay.buffer_size", r.buffer_size, 1),
                           ("replay.batch_size", r.batch_size, 1), ("replay.seq_len", r.seq_len, 1),
                           ("train.total_env_steps", t.total_env_steps, 1), ("train.num_seeds", t.num_seeds, 1),
                           ("train.updates_per_step", t.updates_per_step, 0), ("train.log_every", t.log_every, 1),
                           ("train.eval_every", t.eval_every, 1), ("train.eval_episodes", t.eval_episodes, 1),
                           ("train.checkpoint_every", t.checkpoint_every, 1), ("train.start_steps", t.start_steps, 0),
                           ("train.keep_checkpoints", t.keep_checkpoints, 1), ("agent.policy_freq", a.policy_freq, 0),
                           ("train.video_every", t.video_every, 0),
                           ("replay.burn_in", r.burn_in, 0), ("agent.n_step", a.n_step, 1)]:
        if value < lo:
            _bad(key, value, f"must be >= {lo}")
    if t.devices < 0:
        _bad("train.devices", t.devices, "must be 'all' (or 0: every device) or a device count >= 1")
    if not 0 <= t.seed < 2**31 - t.num_seeds:
        _bad("train.seed", t.seed, "must be in [0, 2**31 - num_seeds)")
    if r.burn_in >= r.seq_len:
        _bad("replay.burn_in", r.burn_in, f"must be < replay.seq_len={r.seq_len} (at least one trained step)")
    if a.actor == "lstm" and len(a.actor_hidden) != 1:
        _bad("agent.actor_hidden", list(a.actor_hidden), "an lstm actor takes one entry, the LSTM units, e.g. [32]")
    if not a.recurrent and r.burn_in != 0:
        why = "an mlp actor" if a.actor == "mlp" else "agent.memory false (the memoryless LSTM)"
        _bad("replay.burn_in", r.burn_in, f"{why} has no carry to warm up: set burn_in 0 (seq_len > 1 only "
                                          f"serves agent.n_step)")
    capacity = r.buffer_size // e.num_envs
    if capacity < r.seq_len + 1:
        _bad("replay.buffer_size", r.buffer_size,
             f"gives {capacity} steps per env (buffer_size // num_envs with num_envs={e.num_envs}); "
             f"needs at least seq_len + 1 = {r.seq_len + 1}, i.e. buffer_size >= {(r.seq_len + 1) * e.num_envs}")
    check_batch_size(c)
    if t.start_steps >= t.total_env_steps:
        _bad("train.start_steps", t.start_steps,
             f"must be < train.total_env_steps={t.total_env_steps}: the first start_steps env steps act "
             f"randomly and make no gradient update, so this run would train nothing; lower train.start_steps "
             f"or raise train.total_env_steps")
    for key, value in [("agent.actor_lr", a.actor_lr), ("agent.critic_lr", a.critic_lr), ("agent.alpha_lr", a.alpha_lr),
                       ("agent.policy_noise", a.policy_noise), ("agent.noise_clip", a.noise_clip),
                       ("agent.ou_theta", a.ou_theta), ("agent.ou_sigma", a.ou_sigma),
                       ("agent.ou_sigma_final", a.ou_sigma_final)]:
        if value < 0:
            _bad(key, value, "must be >= 0 (0 disables it; a learning rate of 0 freezes learning)")
    for key, value in [("train.eval_every_minutes", t.eval_every_minutes),
                       ("train.checkpoint_every_minutes", t.checkpoint_every_minutes)]:
        if value <= 0:
            _bad(key, value, "must be > 0 (minutes of wall-clock time)")
    if not 0.0 < a.lr_end_scale <= 1.0:
        _bad("agent.lr_end_scale", a.lr_end_scale, "must be in (0, 1] (1 = constant learning rates)")
    if a.n_step > r.seq_len - r.burn_in:
        _bad("agent.n_step", a.n_step, f"must be <= the trained steps per sequence, replay.seq_len - burn_in = "
                                       f"{r.seq_len - r.burn_in}")
    if not 0.0 <= a.gamma < 1.0:
        _bad("agent.gamma", a.gamma, "must be in [0, 1)")
    if not 0.0 < a.tau <= 1.0:
        _bad("agent.tau", a.tau, "must be in (0, 1]")
    if not 0.0 < a.policy_average_tau <= 1.0:
        _bad("agent.policy_average_tau", a.policy_average_tau, "must be in (0, 1] (1 = no averaging)")
    if a.ou_theta > 1.0:
        _bad("agent.ou_theta", a.ou_theta, "must be in [0, 1] (mean reversion per step)")
    if a.init_alpha <= 0:
        _bad("agent.init_alpha", a.init_alpha, "must be > 0")
    lv = c.levels
    if lv.sampler != "env":
        if e.scenario != 0 or "tank" in dict(e.overrides):
            _bad("levels.sampler", lv.sampler, "a level pool needs procedural tanks: env.scenario 0 without env.tank")
        if not 1 <= lv.refresh <= lv.capacity:
            _bad("levels.refresh", lv.refresh, f"must be in [1, levels.capacity={lv.capacity}]")
        if lv.route_reward < 0:
            _bad("levels.route_reward", lv.route_reward, "must be >= 0 (0 = off)")
        if lv.temperature <= 0 or not 0.0 <= lv.uniform_mix <= 1.0:
            _bad("levels.temperature/uniform_mix", (lv.temperature, lv.uniform_mix),
                 "temperature must be > 0 and uniform_mix in [0, 1]")
    elif lv.route_reward:
        _bad("levels.route_reward", lv.route_reward, "needs a level pool: levels.sampler uniform or learnability")
    if t.eval_alongside and (why := alongside_blocker(c)):
        _bad("train.eval_alongside", True, f"not possible here: {why}; set it false (or auto)")
    if a.algo == "ddpg":
        if a.policy_noise != 0.0:
            _bad("agent.policy_noise", a.policy_noise, "ddpg has no target-policy smoothing; set 0 or use algo td3")
        if a.policy_freq != 1:
            _bad("agent.policy_freq", a.policy_freq, "ddpg updates the actor every step; set 1 or use algo td3")
    return c


def max_batch_size(c: Config) -> int:
    """The distinct sequences a full replay buffer holds, the largest sensible replay.batch_size: each
    of the num_envs rows keeps buffer_size // num_envs steps, i.e. that minus seq_len + 1 windows."""
    return c.env.num_envs * (c.replay.buffer_size // c.env.num_envs - c.replay.seq_len + 1)


def check_batch_size(c: Config) -> None:
    """A batch of more sequences than the buffer holds distinct ones only repeats them (and costs the
    memory of the repeats): ConfigError naming the largest valid batch. Pure: needs no device."""
    e, r = c.env, c.replay
    distinct = max_batch_size(c)
    if r.batch_size > distinct:
        _bad("replay.batch_size", r.batch_size,
             f"exceeds the {distinct:,} distinct sequences a full buffer holds (env.num_envs={e.num_envs} x "
             f"(replay.buffer_size={r.buffer_size} // num_envs - replay.seq_len={r.seq_len} + 1)); the largest "
             f"valid batch is {distinct}: lower replay.batch_size or raise replay.buffer_size")


def _env_kwargs_for_params(e: EnvConfig) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in e.overrides}


def env_kwargs(c: Config) -> dict[str, Any]:
    """Keyword overrides for `docrl_jax.envs.make(scenario, **kwargs)`."""
    return _env_kwargs_for_params(c.env)


def observation_size(c: Config) -> int:
    """Floats in one observation of the run's env (`EnvParams.observation_size`: env.vertical_beams
    adds two, env.slant_beams two rings)."""
    from docrl_jax.envs import make_params
    return make_params(c.env.scenario, **env_kwargs(c)).observation_size


def pair_scenario(c: Config) -> int:
    """The scenario of the run's paper-pair evaluations and videos: its own, or for a procedural run
    (env.scenario 0) train.eval_pair_scenario."""
    return c.env.scenario or c.train.eval_pair_scenario


# The env fields that shape training episodes only (they end them earlier than a test would).
TRAINING_ONLY_ENV = ("collision_margin", "hull_margin")


def evaluation_env_kwargs(c: Config) -> dict[str, Any]:
    """`env_kwargs` without the training-only fields (`TRAINING_ONLY_ENV`): what every evaluation episode runs with."""
    return {k: v for k, v in env_kwargs(c).items() if k not in TRAINING_ONLY_ENV}


def nominal_env_kwargs(c: Config) -> dict[str, Any]:
    """`evaluation_env_kwargs` without the domain randomisation (`dr_*`): the nominal plant of the paper's test."""
    return {k: v for k, v in evaluation_env_kwargs(c).items() if not k.startswith("dr_")}


def pairs_own_env(c: Config) -> bool:
    """Whether the paper-pair evaluation needs an env of its own: the pairs run and their scenario or
    plant differs from the training env's (a procedural or domain-randomised run)."""
    return c.train.eval_paper_pairs and (pair_scenario(c) != c.env.scenario or nominal_env_kwargs(c) != env_kwargs(c))


def alongside_blocker(c: Config) -> str | None:
    """Why this run's evaluations cannot run alongside training (train.eval_alongside), or None. The
    lanes are extra envs of the training step, so every evaluation episode must run in the training env
    and one policy must drive them."""
    if c.train.eval_trained_actor and c.agent.policy_average_tau < 1.0:
        return "train.eval_trained_actor evaluates a second policy on the same episodes"
    if c.levels.sampler != "env":
        return f"levels.sampler={c.levels.sampler} draws the training envs' tanks from a pool"
    for name in TRAINING_ONLY_ENV:
        if env_kwargs(c).get(name, 0.0) > 0.0:
            return f"env.{name} ends the training env's episodes earlier than an evaluation's"
    if pairs_own_env(c):
        return (f"the paper pairs run in scenario {pair_scenario(c)} with the nominal plant, not in the training "
                f"env (env.scenario={c.env.scenario}" + (", dr_* ranges)" if nominal_env_kwargs(c) != env_kwargs(c)
                                                         else ")"))
    return None


# ---------------------------------------------------------------------------------------- output
def to_dict(c: Config) -> dict[str, Any]:
    """Plain YAML-ready dict (env overrides flattened back into `env:`)."""
    def plain(v):
        return [plain(x) for x in v] if isinstance(v, tuple) else v
    out: dict[str, Any] = {"name": c.name}
    for sec in SECTIONS:
        obj = getattr(c, sec)
        d = {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.name != "overrides"}
        if sec == "env":
            d.update({k: plain(v) for k, v in c.env.overrides})
        out[sec] = d
    return out


def to_yaml(c: Config) -> str:
    return yaml.safe_dump(to_dict(c), sort_keys=False)
