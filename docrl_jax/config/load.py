"""Loading a config: YAML file (a packaged name or a path, composed: docrl_jax/config/files.py)
->  `--set section.key=value` overrides  ->  `auto` values (docrl_jax/config/auto.py)  ->  each value
against its key's type (values.py)  ->  the checks across keys (checks.py)  ->  a frozen `Config`.
Every error is one ConfigError naming the key, the value and what is allowed, before anything compiles."""

from __future__ import annotations

import dataclasses
import os
import typing
from typing import Any

from docrl_jax import schema
from docrl_jax.config.auto import resolve_auto, settle_eval_alongside
from docrl_jax.config.checks import validate
from docrl_jax.config.files import compose, resolve_config_path
from docrl_jax.config.sections import SECTIONS, Config, config_keys
from docrl_jax.config.values import coerce, freeze
from docrl_jax.errors import ConfigError


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """['agent.actor_lr=3e-4', 'env.wind=false'] -> {'agent.actor_lr': 0.0003, 'env.wind': False}.
    Values are YAML scalars (so lists work too: env.z_bounds=[-1.0,4.0])."""
    import yaml  # (as in files.compose: only reading a config needs the parser)
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
    raw = compose(path, ())
    if isinstance(overrides, list):
        overrides = parse_overrides(overrides)
    return config_from_dict(raw, overrides or {}, source=str(path), backend=backend, notes=notes)


def config_from_dict(raw: dict, overrides: dict[str, Any] | None = None, source: str = "config",
                     backend: str | None = None, notes: list | None = None) -> Config:
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
        raise ConfigError(f"{source}: unknown top-level key {schema.first_and_count(unknown)}; valid keys: name, "
                          f"{', '.join(SECTIONS)}{schema.did_you_mean(unknown[0], ['name', *SECTIONS])}")
    alongside_auto = isinstance(raw.get("train"), dict) and raw["train"].get("eval_alongside") == "auto"
    raw = resolve_auto(raw, backend, notes)
    name = coerce("name", raw.get("name", Config.name), str, None)
    built = {}
    for sec, cls in SECTIONS.items():
        values = raw.get(sec) or {}
        if not isinstance(values, dict):
            raise ConfigError(f"section {sec!r} must be a mapping, got {values!r}")
        built[sec] = _build_section(sec, cls, values)
    config = Config(name=name, **built)
    if alongside_auto:
        config = settle_eval_alongside(config, notes)
    validate(config)
    return config


def _build_section(sec: str, cls, values: dict) -> Any:
    """One section's dataclass from its YAML dict: each key typed by its declaration; under `env:`, the
    keys that are EnvParams fields kept as the env's overrides."""
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "overrides"}
    hints = typing.get_type_hints(cls)
    kwargs, extra = {}, {}
    for key, value in values.items():
        if key in fields:
            kwargs[key] = coerce(f"{sec}.{key}", value, hints[key], fields[key].metadata["choices"])
        else:
            extra[key] = value
    valid, listed = set(fields), f"the fields of {cls.__name__} in {schema.declared_in(cls)}"
    if sec == "env":  # every other key under env: is an EnvParams field
        from docrl_jax.envs import EnvParams, param_docs
        valid |= set(param_docs())
        listed = (f"{', '.join(f'env.{k}' for k in fields)} and the fields of EnvParams in "
                  f"{schema.declared_in(EnvParams)}")
        kwargs["overrides"] = tuple(sorted((k, freeze(v)) for k, v in extra.items()))
    unknown = sorted(set(extra) - valid)
    if unknown:
        raise ConfigError(f"unknown key {schema.first_and_count([f'{sec}.{k}' for k in unknown])}; valid keys: "
                          f"{listed}{schema.did_you_mean(unknown[0], valid, shown=lambda k: f'{sec}.{k}')}")
    return cls(**kwargs)
