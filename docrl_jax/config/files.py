"""Configs as YAML files: finding one by name (a packaged config) or path, composing one from the
configs it extends, and writing one back (what a run directory's config.yaml holds)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

from docrl_jax import schema
from docrl_jax.config.sections import SECTIONS, Config
from docrl_jax.errors import ConfigError
from docrl_jax.resources import resource_dir


def packaged_configs_dir() -> Path:
    """The folder of the packaged configs (`configs/` of the repository, installed as `docrl_jax.configs`)."""
    return resource_dir("configs")


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


def compose(path: Path, chain: tuple[Path, ...]) -> dict:
    """The YAML of `path` with its references to other configs resolved, so that a recipe built on
    another one states only what differs:
      extends: NAME   -- start from config NAME; this file's keys replace its keys one by one
      SECTION: NAME   -- a section (env, agent, replay, train) is config NAME's section, whole
    NAME is a file relative to this one if there is one, else as `--config` takes it (a packaged name)."""
    import yaml  # here: the many modules that import docrl_jax.config for `Config` need no parser (~14 ms)
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
        other = compose(resolve_config_path(beside if beside.is_file() else name), (*chain, path))
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


def differences(a: Config, b: Config) -> dict[str, tuple]:
    """{'section.key': (a's value, b's value)} where the two configs differ (what a resume may not change,
    what sets two runs apart)."""
    def flat(c):
        out = {}
        for key, value in to_dict(c).items():
            items = value.items() if isinstance(value, dict) else [(None, value)]
            out.update({(f"{key}.{k}" if k else key): v for k, v in items})
        return out
    fa, fb = flat(a), flat(b)
    return {k: (fa.get(k), fb.get(k)) for k in sorted(fa.keys() | fb.keys()) if fa.get(k) != fb.get(k)}


def to_yaml(c: Config) -> str:
    """The config as YAML (what a run directory's config.yaml holds); loads back to the same Config."""
    import yaml  # (as in compose)
    return yaml.safe_dump(to_dict(c), sort_keys=False)
