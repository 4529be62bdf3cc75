"""The HUAUV environment as a Brax environment, for Brax's own trainers (needs the `[brax]` extra).

    from docrl_jax.envs.brax_env import BraxHUAUV      # also applies the jax compatibility shim below
    from brax.training.agents.sac import train as sac
    env = BraxHUAUV(scenario=2)
    make_policy, params, metrics = sac.train(env, num_timesteps=..., episode_length=env.episode_length, ...)

or by name: `brax.envs.get_environment("docrl_huauv", scenario=2)` (registered on import).

Brax's trainers wrap the env themselves (`VmapWrapper` -> `EpisodeWrapper` -> `AutoResetWrapper`), so
this class is one un-batched, never-resetting env. How our episode semantics map onto Brax's:

* Truncation. Brax's `EpisodeWrapper(episode_length)` ends an episode after `episode_length` steps and
  sets `info["truncation"] = 1 - done` at that step; SAC and PPO use it to leave the cut transition
  out of their critic/value losses instead of treating it as a terminal state. That only works if the
  inner env does NOT also end the episode at the step limit (Brax would then see done=1 and report
  truncation 0, i.e. a terminal). So the wrapped env never truncates itself (its `max_episode_steps`
  is set out of reach) and `done` is 1 only for a true termination: collision, leaving the vertical
  bounds, diverged physics, or arrival when `terminate_on_arrival=True`.
* The paper's -10 time-out reward is still paid, on the step where our own step counter reaches
  `episode_length` (without a collision or arrival on that step), so Brax's reported episode
  returns equal ours. Pass `episode_length=env.episode_length` (default 500, the paper's) and
  `action_repeat=1` to the trainer so both counters agree (with action_repeat k, our counter counts
  the k inner steps: use an episode_length divisible by k); Brax's losses mask that transition anyway.
* Auto-reset. Brax's `AutoResetWrapper` restores the `pipeline_state` and `obs` an env slot had at
  its first reset: every episode of one slot starts from the same pose, yaw and goal (slots differ).
  Our full `EnvState` is the `pipeline_state`, so the step counter, goal and `goals_reached` restart
  correctly. The PRNG key for wind, sensor noise and goal resampling is kept in `info["rng"]`, which
  Brax does not restore, so repeated episodes of one slot still meet fresh wind and noise.
* `obs` (26,), `reward`, and `done` (float32, Brax's convention) are exactly our env's; our info dict
  is `state.pipeline_state.info`; `state.metrics` holds per-step `arrived`, `collision` and
  `out_of_bounds` (Brax sums them over an episode: `eval/episode_arrived`, ...).

Domain randomisation, the Brax / MuJoCo Playground way. Brax's trainers take
`randomization_fn(sys, rng) -> (sys_batched, in_axes)`; its `DomainRandomizationVmapWrapper` calls it
once on `env.sys` with `rng` of shape (num_envs, 2), then inside its `vmap` sets `env.unwrapped.sys` to
each env's slice around every reset and step. Here `sys` is the episode's `physics.Plant` (true
vehicle, water, wind, sensor corruption, latencies), and

    from docrl_jax.envs.brax_env import BraxHUAUV, make_randomization_fn
    env = BraxHUAUV(scenario=2, dr_thrust_air_scale=(0.5, 1.0), dr_hull_volume_scale=(0.8, 1.2))
    sac.train(env, ..., randomization_fn=make_randomization_fn(env))

draws one plant per env from the env's `dr_*` ranges (`randomization.sample_plant`). The contract:

* Reading `env.sys` gives the nominal plant of the env's parameters (what the controller assumes),
  unless a plant was assigned. Assigning a plant makes `reset` start every episode with it and `step`
  run it (as a Brax env's `sys` is its model in both). Assigning `None`, or the nominal plant that
  reading returned (what the wrapper puts back when it leaves), returns to the default.
* By default (no plant assigned, e.g. Brax's plain `VmapWrapper`) `reset` is our env's: the plant is
  drawn from the `dr_*` ranges (exactly the nominal plant when they are left at their defaults). So an
  env with `dr_*` ranges randomises with or without a `randomization_fn`; the two differ only in
  whose key draws: the reset key of the slot, or the `rng` Brax gives `randomization_fn`.
* Either way a slot keeps its plant for the whole run: the plant lives in the `pipeline_state`, which
  Brax's `AutoResetWrapper` restores from the slot's first reset (and under the randomisation wrapper
  `step` runs the slot's `sys` anyway). That is Playground's model too: one plant per env slot per
  run, redrawn only when the trainer builds its envs (Brax's evaluator uses its own `num_eval_envs`
  plants, drawn from its eval key).

Compatibility shim: brax 0.14.2's trainers call `jax.device_put_replicated`, which jax 0.10 removed
(the pinned jax here). Importing this module defines it, only where it is missing, as the
`jax.device_put` with a `NamedSharding` that jax's pmap migration guide gives as its replacement:
each leaf stacked `len(devices)` times along a new leading axis, one slice per device.
"""

from __future__ import annotations

from typing import Any, Sequence

import jax
import jax.numpy as jnp
import numpy as np

# Before Brax, which imports mujoco.mjx itself: imported here first, without the notice about MJX's
# optional Warp backend (docrl_jax.envs._quiet_import), so Brax finds it imported and nothing prints.
from docrl_jax.envs._quiet_import import mjx  # noqa: F401

try:
    import brax.envs
    from brax.envs.base import Env as _BraxEnv
    from brax.envs.base import State as BraxState
except ImportError as err:  # the core package works without brax; this module does not
    raise ImportError("docrl_jax.envs.brax_env needs brax: pip install -e '.[brax]' (brax==0.14.2)") from err

import docrl_jax.envs as envs
from docrl_jax.envs import randomization
from docrl_jax.envs.huauv import EnvState
from docrl_jax.envs.params import EnvParams
from docrl_jax.envs.physics import Plant

BRAX_ENV_NAME = "docrl_huauv"
_NEVER = 2**30  # a step limit no episode reaches: Brax's EpisodeWrapper truncates instead


def _device_put_replicated(x: Any, devices: Sequence[jax.Device]) -> Any:
    """`jax.device_put_replicated` as it was before jax 0.10: every leaf of `x` broadcast along a new
    leading axis of size len(devices), slice i on devices[i] (what `jax.pmap` expects as input)."""
    devices = list(devices)
    if not devices:
        raise ValueError("device_put_replicated: `devices` must be a non-empty sequence of devices")
    mesh = jax.sharding.Mesh(np.asarray(devices), ("replica",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("replica"))

    def put(leaf):
        leaf = jnp.asarray(leaf)
        return jax.device_put(jnp.broadcast_to(leaf[None], (len(devices),) + leaf.shape), sharding)

    return jax.tree.map(put, x)


def install_jax_compat() -> bool:
    """Defines `jax.device_put_replicated` if this jax lacks it; returns True if it did."""
    try:
        jax.device_put_replicated  # noqa: B018 (jax >= 0.10 raises AttributeError here)
        return False
    except AttributeError:
        jax.device_put_replicated = _device_put_replicated
        return True


install_jax_compat()


class BraxHUAUV(_BraxEnv):
    """`docrl_jax.envs.make(scenario, **overrides)` as a `brax.envs.base.Env` (see the module doc).

    `episode_length` is where the paper's time-out reward is paid (default: the scenario's
    `max_episode_steps`, 500); give the same number to the Brax trainer. Keyword overrides set any
    `EnvParams` field, as for `envs.make`."""

    def __init__(self, scenario: int = 2, episode_length: int | None = None, **overrides: Any):
        if "max_episode_steps" in overrides:
            raise ValueError("BraxHUAUV: pass episode_length=N (and the same episode_length to the Brax "
                             "trainer) instead of max_episode_steps; Brax's EpisodeWrapper truncates")
        if overrides.pop("auto_reset", False):
            raise ValueError("BraxHUAUV: auto_reset is Brax's AutoResetWrapper's job; leave it out")
        default_length = envs.make_params(scenario, **overrides).max_episode_steps
        self.episode_length = int(default_length if episode_length is None else episode_length)
        if self.episode_length < 1:
            raise ValueError(f"BraxHUAUV: episode_length={episode_length!r} must be >= 1")
        self.env = envs.make(scenario, auto_reset=False, max_episode_steps=_NEVER, **overrides)
        self.params = self.env.params
        self._nominal_plant = randomization.nominal_plant(self.params)
        self._plant: Plant | None = None   # assigned through `sys`; None: draw from the dr_* ranges

    @property
    def sys(self) -> Plant:
        """The plant `reset` and `step` run: the assigned one, else the nominal plant (module doc)."""
        return self._nominal_plant if self._plant is None else self._plant

    @sys.setter
    def sys(self, plant: Plant | None) -> None:
        if plant is not None and not isinstance(plant, Plant):
            raise TypeError(f"BraxHUAUV.sys: expected a physics.Plant (or None), got {type(plant).__name__}")
        # The nominal plant read from `sys` and put back (DomainRandomizationVmapWrapper does so on
        # leaving) restores the default, in which reset draws from the dr_* ranges.
        self._plant = None if plant is None or plant is self._nominal_plant else plant

    @property
    def observation_size(self) -> int:
        return self.env.observation_size

    @property
    def action_size(self) -> int:
        return self.env.action_size

    @property
    def backend(self) -> str:
        return "mjx"

    @property
    def dt(self) -> float:
        return self.env.control_dt

    def _wrap(self, inner: EnvState, reward: jax.Array, rng: jax.Array) -> BraxState:
        info = inner.info
        metrics = {k: info[k].astype(jnp.float32) for k in ("arrived", "collision", "out_of_bounds")}
        return BraxState(pipeline_state=inner, obs=inner.obs, reward=reward.astype(jnp.float32),
                         done=inner.done.astype(jnp.float32), metrics=metrics, info={"rng": rng})

    def reset(self, rng: jax.Array) -> BraxState:
        inner = self.env.reset(rng, plant=self._plant)
        return self._wrap(inner, inner.reward, inner.sim.key)

    def step(self, state: BraxState, action: jax.Array) -> BraxState:
        inner: EnvState = state.pipeline_state
        # The key Brax keeps across its auto-resets, not the one restored with the first state.
        inner = inner.replace(sim=inner.sim.replace(key=state.info["rng"]))
        if self._plant is not None:   # the env's current sys, as Brax envs step theirs
            inner = inner.replace(sim=inner.sim.replace(plant=self._plant))
        nxt = self.env.step(inner, action)
        info = nxt.info
        timeout = (info["step"] == self.episode_length) & ~nxt.done & ~info["arrived"]
        reward = nxt.reward + jnp.where(timeout, self.params.reward_timeout, 0.0)
        out = self._wrap(nxt, reward, nxt.sim.key)
        # Keep what wrappers outside put into info (Brax's steps, truncation, first_obs, ...).
        return out.replace(info={**state.info, "rng": nxt.sim.key}, metrics={**state.metrics, **out.metrics})


def randomization_fn(sys: Plant, rng: jax.Array, params: Any = None) -> tuple[Plant, Plant]:
    """One plant per env from the `dr_*` ranges of `params`, in Brax's `randomization_fn` form.

    `rng`: (num_envs, 2) keys (or (num_envs,) typed keys), as Brax's trainers pass them. `params`: an
    `EnvParams`, or anything with a `.params` (a `BraxHUAUV`, a `HUAUVEnv`); required, as a plant does
    not carry the ranges. The plants are those of `randomization.sample_plant(rng[i], params)`, i.e.
    drawn around the nominal values of `params`; `sys` (the env's nominal plant, which Brax passes)
    only has to have the same structure. Returns (plants with a leading num_envs axis, a Plant of 0s:
    the `in_axes` of every leaf). Bind `params` first: `make_randomization_fn(env)`, or
    `functools.partial(randomization_fn, params=env.params)`."""
    if params is None:
        raise TypeError("randomization_fn: pass params= (the env, or its EnvParams), e.g. through "
                        "make_randomization_fn(env)")
    p = getattr(params, "params", params)
    if not isinstance(p, EnvParams):
        raise TypeError(f"randomization_fn: params must be an EnvParams or an env with .params, "
                        f"got {type(params).__name__}")
    if not isinstance(sys, Plant):
        raise TypeError(f"randomization_fn: sys must be the env's physics.Plant, got {type(sys).__name__}")
    rng = jnp.asarray(rng) if not isinstance(rng, jax.Array) else rng
    batched = rng.ndim >= 2 or (rng.ndim == 1 and jnp.issubdtype(rng.dtype, jax.dtypes.prng_key))
    if not batched:
        raise ValueError(f"randomization_fn: rng must hold one key per env, shape (num_envs, 2); got "
                         f"shape {rng.shape} (split it: jax.random.split(key, num_envs))")
    plants = jax.vmap(lambda key: randomization.sample_plant(key, p))(rng)
    return plants, jax.tree.map(lambda _: 0, plants)


def make_randomization_fn(env_or_params: Any):
    """`fn(sys, rng) -> (plants, in_axes)` drawing from the `dr_*` ranges of a `BraxHUAUV` (or an
    `EnvParams`): pass it to Brax's trainers or `brax.envs.training.wrap` as `randomization_fn`."""
    p = getattr(env_or_params, "params", env_or_params)
    if not isinstance(p, EnvParams):
        raise TypeError(f"make_randomization_fn: expected a BraxHUAUV or an EnvParams, got "
                        f"{type(env_or_params).__name__}")

    def fn(sys: Plant, rng: jax.Array) -> tuple[Plant, Plant]:
        return randomization_fn(sys, rng, params=p)

    return fn


brax.envs.register_environment(BRAX_ENV_NAME, BraxHUAUV)

__all__ = ["BraxHUAUV", "BRAX_ENV_NAME", "install_jax_compat", "make_randomization_fn", "randomization_fn"]
