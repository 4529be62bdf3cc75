"""The trainer's configuration: one YAML file with the sections `name`, `env`, `agent`, `replay`,
`train` and `levels` (see `configs/*.yaml`), loaded into a frozen, hashable `Config`:

    config = load_config("td3_lstm", ["agent.actor_lr=3e-4"])   # a packaged name or a YAML path

By concern, each a module of this package:

    sections.py   every key, declared with its default and documentation; what `auto` stands for
    files.py      finding a config by name or path, `extends` composition, writing one back (to_yaml)
    load.py       YAML -> `--set` overrides -> auto values -> typed values -> checks -> Config
    auto.py       `auto` values for this backend, with a note per value chosen
    values.py     one value against its key's declared type
    checks.py     the checks across keys, before anything compiles
    env.py        the env kwargs a run's training, evaluations and paper pairs run with

Every error is a one-line `ConfigError` (a ValueError) naming the key, the value and what is allowed;
an unknown name also gets the valid ones nearest it. The names imported below are the public ones:
import them from `docrl_jax.config`, not from its modules.
"""

# ruff: noqa: F401  (the imports are the package's public names)
from docrl_jax.config.auto import resolve_auto
from docrl_jax.config.checks import check_batch_size, max_batch_size, validate
from docrl_jax.config.env import (TRAINING_ONLY_ENV, alongside_blocker, env_kwargs, evaluation_env_kwargs,
                                  nominal_env_kwargs, observation_size, pair_scenario, pairs_own_env)
from docrl_jax.config.files import (differences, packaged_config_names, packaged_configs_dir, resolve_config_path,
                                    to_dict, to_yaml)
from docrl_jax.config.load import config_from_dict, load_config, parse_overrides
from docrl_jax.config.sections import (AUTO_CRITIC_DTYPE, AUTO_ITERS_PER_CHUNK, AUTO_NUM_ENVS, AUTO_STEPS_PER_ENV,
                                       SECTIONS, AgentConfig, Config, EnvConfig, LevelsConfig, ReplayConfig,
                                       TrainConfig, config_keys, field_docs)
from docrl_jax.errors import ConfigError

