"""The config's sections and every key in them: one frozen dataclass per section, each field declared
with its default and its documentation (CleanRL style: the one place a user reads what a key means),
and the values `auto` stands for.

`Config` is frozen and hashable, so `make_trainer(config)` can be memoised and reuse compiled programs.
Loading a YAML file into a Config is `docrl_jax.config.load`; the checks across keys are
`docrl_jax.config.checks`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from docrl_jax import schema
from docrl_jax.schema import documented

# What `auto` sizes resolve to, by JAX backend ("gpu" also stands for "tpu"): envs per seed, and
# replay steps kept per env (buffer_size = num_envs x that).
AUTO_NUM_ENVS = {"gpu": 4096, "cpu": 64}
AUTO_STEPS_PER_ENV = {"gpu": 256, "cpu": 1024}
# Vectorised steps per compiled chunk for `train.log_every: auto` (log_every = num_envs x that): on a
# GPU a chunk of 100 takes ~1.5 s; on a 2-core CPU 10 already take ~10-30 s, and the progress line,
# its ETA and Ctrl-C all wait for the chunk to end.
AUTO_ITERS_PER_CHUNK = {"gpu": 100, "cpu": 10}
# `agent.critic_dtype: auto`: bf16 activations where they are faster (a GPU: docs/BENCHMARKS.md, "Why the
# defaults are what they are"); on a CPU XLA emulates bf16 matmuls, which makes an iteration slower.
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
                                      "(docrl_jax/envs/param_fields.py), e.g. wind, max_goal_distance, progress_reward_scale.")

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
    frames: int = documented(1, "mlp: observations the actor reads, the current one after the frames - 1 before "
                                "it (stacked observations; zeros before an episode's first step). 1 = the "
                                "current one alone. Memory for an MLP, without a recurrent network.")
    critic_carry: bool = documented(False, "sac: the critics read the actor's carry after each observation (LSTM c "
                                           "and h, or an mlp's stacked frames) beside it, gradient stopped, so they "
                                           "judge actions with the memory the actor acts on. Needs a recurrent actor.")
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
    sequence_unroll: int = documented(0, "Replay-sequence steps the actor runs per loop iteration in the gradient "
                                         "updates: 0 = every step unrolled (the fastest learner); k > 0 = a loop of k "
                                         "steps at a time (less for XLA to compile, a slower learner: with 1 the "
                                         "learner made ~25 % fewer env steps/s on a GPU). The same computation either "
                                         "way. A cold start's quick build of the chunk uses 1 (docs/TRAINER.md).")
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
    policy_average_tau_start: float = documented(0.0,
        "With policy_average_tau < 1: the average's rate at the run's start, falling "
        "geometrically with env-step progress to policy_average_tau at total_env_steps. "
        "The run's policy then follows the trained actor closely while it learns and is "
        "averaged over ~1/policy_average_tau actor updates at the end. 0 = a constant "
        "policy_average_tau. Ours: 0.01 in td3_lstm (docs/BENCHMARKS.md, \"Why the defaults\").")

    @property
    def recurrent(self) -> bool:
        """True when the actor carries state from step to step (an LSTM with memory, or an MLP reading
        stacked frames): the one rule for stored carries, burn-in and carry resets at episode starts."""
        return self.memory and (self.actor == "lstm" or self.frames > 1)


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
        "(on a GPU a pause per evaluation of latency-bound steps; alongside, the lanes cost a few per cent of "
        "the chunks' pace and a run ends sooner: docs/BENCHMARKS.md, \"Why the defaults are what they are\"). Same "
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
        "later) in every checkpoint's best/ item, beside the final policy: "
        "what load_policy and every --run load by default (--which final "
        "for the final one; docrl_jax/train/best_policy.py).")
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
