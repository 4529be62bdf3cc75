"""The policies the commands fly: a shipped one by name, one seed of a run directory, or the BBA
baseline, optionally route-guided; policies of the same settings share their functions, so their
rollouts (cached per policy function in docrl_jax.evaluate.rollout) compile once."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

_SHARED: dict = {}   # settings -> the first policy loaded with them


def _shared(policy, settings) -> Any:
    """Policies of the same settings get the first one's functions, so a process that draws several
    (or draws again) compiles their rollout once (it is cached per policy function)."""
    first = _SHARED.setdefault(settings, policy)
    return policy if first is policy else replace(policy, init_carry=first.init_carry, act=first.act)


def steered(policy, label: str, guide: str | None, env):
    """(policy, label), steered down a route with `guide` (--guide's value) and labelled so (`guided_label`):
    "tank" plans every trial's route through its tank (docrl_jax.baselines.route.guided), "sensors" on the map its
    own beams draw as it flies in `env` (route.mapped); None leaves it mapless."""
    if not guide:
        return policy, label
    from docrl_jax.baselines import route
    steer = route.mapped(policy, env.params) if guide == "sensors" else route.guided(policy)
    return steer, guided_label(label, guide)


def guided_label(label: str, guide: str | None = "tank") -> str:
    """A method's label when --guide steers it."""
    return f"{label} {'own-map' if guide == 'sensors' else 'guided'}"


def policy_for(env, run: str | None = None, seed_index: int = 0, which: str | None = None,
               bba_depth_phase: str = "after", name: str | None = None, guide: str | None = None):
    """(policy, method label): the policy shipped as `name` (docrl_jax.pretrained), one seed of a run
    directory (`which` as runs.load_policy's: None = the run's policy; the label marks a best one), or the
    BBA baseline (neither); a learned one steered down a route with `guide` (`steered`)."""
    from docrl_jax import pretrained
    if name in pretrained.PRETRAINED:
        return steered(pretrained.load(name), name, guide, env)
    if run is None:
        from docrl_jax.baselines import bba
        return (_shared(bba.make_bba(env.params, depth_phase=bba_depth_phase), ("bba", id(env), bba_depth_phase)),
                bba.label(bba_depth_phase))
    from docrl_jax import runs
    policy = runs.load_policy(run, seed_index=seed_index, which=which)
    return steered(_shared(policy, ("run", runs.read_config(run).agent)),
                   runs.policy_label(Path(run).resolve().name, policy.which), guide, env)
