"""The run's environment, read from its config: the keyword overrides of `docrl_jax.envs.make` that its
training, its evaluations and its paper pairs run with, and what follows from them (the observation
size, whether the evaluations can run alongside training)."""

from __future__ import annotations

from typing import Any

from docrl_jax.config.sections import Config


def env_kwargs(c: Config) -> dict[str, Any]:
    """Keyword overrides for `docrl_jax.envs.make(scenario, **kwargs)` (lists where the YAML had them)."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in c.env.overrides}


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
    return c.train.eval_paper_pairs and (pair_scenario(c) != c.env.scenario
                                         or nominal_env_kwargs(c) != evaluation_env_kwargs(c))


def alongside_blocker(c: Config) -> str | None:
    """Why this run's evaluations cannot run alongside training (train.eval_alongside), or None. The
    lanes are extra envs of the training step, so every evaluation episode must run in the training env
    (its training-only margins switched off per lane) and one policy must drive them."""
    if c.train.eval_trained_actor and c.agent.policy_average_tau < 1.0:
        return "train.eval_trained_actor evaluates a second policy on the same episodes"
    if c.levels.sampler != "env":
        return f"levels.sampler={c.levels.sampler} draws the training envs' tanks from a pool"
    if pairs_own_env(c):
        return (f"the paper pairs run in scenario {pair_scenario(c)} with the nominal plant, not in the training "
                f"env (env.scenario={c.env.scenario}" + (", dr_* ranges)" if nominal_env_kwargs(c) != env_kwargs(c)
                                                         else ")"))
    return None
