"""`auto` values: what `env.num_envs`, `replay.buffer_size`, `train.log_every`, `agent.critic_dtype` and
`train.eval_alongside` set to `auto` become on this backend (the AUTO_* tables of
docrl_jax/config/sections.py), each with a note that the trainer prints."""

from __future__ import annotations

import dataclasses

from docrl_jax.config.env import alongside_blocker
from docrl_jax.config.sections import (AUTO_CRITIC_DTYPE, AUTO_ITERS_PER_CHUNK, AUTO_NUM_ENVS, AUTO_STEPS_PER_ENV,
                                       Config, EnvConfig)
from docrl_jax.config.values import bad, coerce


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
    if is_auto("train", "eval_alongside"):  # whether the rest of the config allows it: settle_eval_alongside
        out["train"]["eval_alongside"] = kind == "gpu"
    # The per-env sizes are multiples of num_envs, so a bad num_envs is reported here, by its own name,
    # rather than as an unresolvable 'auto' below.
    num_envs = coerce("env.num_envs", out.get("env", {}).get("num_envs", EnvConfig.num_envs), int, None)
    if num_envs < 1:
        bad("env.num_envs", num_envs, "must be >= 1")
    for sec, key, per_env, why in _AUTO_PER_ENV:
        if is_auto(sec, key):
            out[sec][key] = num_envs * per_env[kind]
            if notes is not None:
                notes.append(f"{sec}.{key} auto -> {out[sec][key]:,} ({why.format(per=per_env[kind], n=num_envs)})")
    return out


def settle_eval_alongside(config: Config, notes: list | None = None) -> Config:
    """`train.eval_alongside: auto` once the config is built: `resolve_auto` chose by backend; the rest of
    the config may rule it out (`alongside_blocker`), and the note says which and why."""
    why = alongside_blocker(config) if config.train.eval_alongside else "off on a CPU"
    if config.train.eval_alongside and why:
        config = dataclasses.replace(config, train=dataclasses.replace(config.train, eval_alongside=False))
    if notes is not None:
        notes.append(f"train.eval_alongside auto -> {str(config.train.eval_alongside).lower()}"
                     + (f" ({why})" if why else ""))
    return config
