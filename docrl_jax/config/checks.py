"""The checks across keys that reject an impossible config before anything is compiled (each key's own
type and choices are checked as it is read: docrl_jax/config/values.py). Whether the run fits its
devices is `docrl_jax.memory.check_memory`, a separate step because it needs the devices."""

from __future__ import annotations

from docrl_jax.config.env import alongside_blocker, env_kwargs
from docrl_jax.config.sections import Config
from docrl_jax.config.values import bad
from docrl_jax.errors import ConfigError


def validate(c: Config) -> Config:
    """Rejects impossible combinations before anything is compiled."""
    from docrl_jax.envs import make_params
    e, a, r, t = c.env, c.agent, c.replay, c.train
    try:
        make_params(e.scenario, **env_kwargs(c))
    except ValueError as err:
        raise ConfigError(f"env: {err}") from None
    if not c.name or any(ch in c.name for ch in "/\\"):
        bad("name", c.name, "must be a non-empty name without path separators")
    for key, value, lo in [("env.num_envs", e.num_envs, 1), ("replay.buffer_size", r.buffer_size, 1),
                           ("replay.batch_size", r.batch_size, 1), ("replay.seq_len", r.seq_len, 1),
                           ("train.total_env_steps", t.total_env_steps, 1), ("train.num_seeds", t.num_seeds, 1),
                           ("train.updates_per_step", t.updates_per_step, 0), ("train.log_every", t.log_every, 1),
                           ("train.eval_every", t.eval_every, 1), ("train.eval_episodes", t.eval_episodes, 1),
                           ("train.checkpoint_every", t.checkpoint_every, 1), ("train.start_steps", t.start_steps, 0),
                           ("train.keep_checkpoints", t.keep_checkpoints, 1), ("agent.policy_freq", a.policy_freq, 0),
                           ("train.video_every", t.video_every, 0),
                           ("replay.burn_in", r.burn_in, 0), ("agent.n_step", a.n_step, 1),
                           ("agent.sequence_unroll", a.sequence_unroll, 0)]:
        if value < lo:
            bad(key, value, f"must be >= {lo}")
    if t.devices < 0:
        bad("train.devices", t.devices, "must be 'all' (or 0: every device) or a device count >= 1")
    if not 0 <= t.seed < 2**31 - t.num_seeds:
        bad("train.seed", t.seed, "must be in [0, 2**31 - num_seeds)")
    if r.burn_in >= r.seq_len:
        bad("replay.burn_in", r.burn_in, f"must be < replay.seq_len={r.seq_len} (at least one trained step)")
    if a.actor == "lstm" and len(a.actor_hidden) != 1:
        bad("agent.actor_hidden", list(a.actor_hidden), "an lstm actor takes one entry, the LSTM units, e.g. [32]")
    if a.frames < 1 or (a.frames > 1 and a.actor != "mlp"):
        bad("agent.frames", a.frames, "must be 1, or > 1 with agent.actor mlp (stacked observations)")
    if a.critic_carry and not (a.recurrent and a.algo == "sac"):
        bad("agent.critic_carry", True, "needs agent.algo sac and a recurrent actor (lstm with agent.memory true, "
                                        "or mlp with agent.frames > 1)")
    if not a.recurrent and r.burn_in != 0:
        why = "an mlp actor" if a.actor == "mlp" else "agent.memory false (the memoryless LSTM)"
        bad("replay.burn_in", r.burn_in, f"{why} has no carry to warm up: set burn_in 0 (seq_len > 1 only "
                                         f"serves agent.n_step)")
    capacity = r.buffer_size // e.num_envs
    if capacity < r.seq_len + 1:
        bad("replay.buffer_size", r.buffer_size,
            f"gives {capacity} steps per env (buffer_size // num_envs with num_envs={e.num_envs}); "
            f"needs at least seq_len + 1 = {r.seq_len + 1}, i.e. buffer_size >= {(r.seq_len + 1) * e.num_envs}")
    check_batch_size(c)
    if t.start_steps >= t.total_env_steps:
        bad("train.start_steps", t.start_steps,
            f"must be < train.total_env_steps={t.total_env_steps}: the first start_steps env steps act "
            f"randomly and make no gradient update, so this run would train nothing; lower train.start_steps "
            f"or raise train.total_env_steps")
    for key, value in [("agent.actor_lr", a.actor_lr), ("agent.critic_lr", a.critic_lr), ("agent.alpha_lr", a.alpha_lr),
                       ("agent.policy_noise", a.policy_noise), ("agent.noise_clip", a.noise_clip),
                       ("agent.ou_theta", a.ou_theta), ("agent.ou_sigma", a.ou_sigma),
                       ("agent.ou_sigma_final", a.ou_sigma_final)]:
        if value < 0:
            bad(key, value, "must be >= 0 (0 disables it; a learning rate of 0 freezes learning)")
    for key, value in [("train.eval_every_minutes", t.eval_every_minutes),
                       ("train.checkpoint_every_minutes", t.checkpoint_every_minutes)]:
        if value <= 0:
            bad(key, value, "must be > 0 (minutes of wall-clock time)")
    if not 0.0 < a.lr_end_scale <= 1.0:
        bad("agent.lr_end_scale", a.lr_end_scale, "must be in (0, 1] (1 = constant learning rates)")
    if a.n_step > r.seq_len - r.burn_in:
        bad("agent.n_step", a.n_step, f"must be <= the trained steps per sequence, replay.seq_len - burn_in = "
                                      f"{r.seq_len - r.burn_in}")
    if not 0.0 <= a.gamma < 1.0:
        bad("agent.gamma", a.gamma, "must be in [0, 1)")
    if not 0.0 < a.tau <= 1.0:
        bad("agent.tau", a.tau, "must be in (0, 1]")
    if not 0.0 < a.policy_average_tau <= 1.0:
        bad("agent.policy_average_tau", a.policy_average_tau, "must be in (0, 1] (1 = no averaging)")
    if a.policy_average_tau_start != 0.0 and not a.policy_average_tau <= a.policy_average_tau_start <= 1.0:
        bad("agent.policy_average_tau_start", a.policy_average_tau_start,
            f"must be 0 (a constant rate) or in [agent.policy_average_tau={a.policy_average_tau}, 1]")
    if a.ou_theta > 1.0:
        bad("agent.ou_theta", a.ou_theta, "must be in [0, 1] (mean reversion per step)")
    if a.init_alpha <= 0:
        bad("agent.init_alpha", a.init_alpha, "must be > 0")
    lv = c.levels
    if lv.sampler != "env":
        if e.scenario != 0 or "tank" in dict(e.overrides):
            bad("levels.sampler", lv.sampler, "a level pool needs procedural tanks: env.scenario 0 without env.tank")
        if not 1 <= lv.refresh <= lv.capacity:
            bad("levels.refresh", lv.refresh, f"must be in [1, levels.capacity={lv.capacity}]")
        if lv.route_reward < 0:
            bad("levels.route_reward", lv.route_reward, "must be >= 0 (0 = off)")
        if lv.temperature <= 0 or not 0.0 <= lv.uniform_mix <= 1.0:
            bad("levels.temperature/uniform_mix", (lv.temperature, lv.uniform_mix),
                "temperature must be > 0 and uniform_mix in [0, 1]")
    elif lv.route_reward:
        bad("levels.route_reward", lv.route_reward, "needs a level pool: levels.sampler uniform or learnability")
    if t.eval_alongside and (why := alongside_blocker(c)):
        bad("train.eval_alongside", True, f"not possible here: {why}; set it false (or auto)")
    if a.algo == "ddpg":
        if a.policy_noise != 0.0:
            bad("agent.policy_noise", a.policy_noise, "ddpg has no target-policy smoothing; set 0 or use algo td3")
        if a.policy_freq != 1:
            bad("agent.policy_freq", a.policy_freq, "ddpg updates the actor every step; set 1 or use algo td3")
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
        bad("replay.batch_size", r.batch_size,
            f"exceeds the {distinct:,} distinct sequences a full buffer holds (env.num_envs={e.num_envs} x "
            f"(replay.buffer_size={r.buffer_size} // num_envs - replay.seq_len={r.seq_len} + 1)); the largest "
            f"valid batch is {distinct}: lower replay.batch_size or raise replay.buffer_size")
