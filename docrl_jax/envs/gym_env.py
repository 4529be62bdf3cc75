"""The HUAUV environment behind the Gymnasium 1.x API, NumPy in and out (needs the `[gym]` extra).

    import gymnasium as gym
    import docrl_jax.envs.gym_env                       # registers "docrl_jax/HUAUV-v0"
    env = gym.make("docrl_jax/HUAUV-v0", scenario=2)    # one env: HUAUVGymEnv
    envs = gym.make_vec("docrl_jax/HUAUV-v0", num_envs=64, vectorization_mode="vector_entry_point")

`HUAUVVectorEnv(num_envs)` steps all its envs with ONE jit-compiled `vmap` of our pure `step` (plus
the auto-reset, see below) and copies the results to NumPy; `HUAUVGymEnv` is the same program for
one env. The compiled programs are cached per (scenario, overrides), so several envs of the same
settings compile once per batch size.

Episode ends, as Gymnasium names them:
  terminated = collision, leaving the vertical bounds, diverged physics, or arrival when
               `terminate_on_arrival=True` (a true terminal state: do not bootstrap);
  truncated  = our step limit `max_episode_steps` (500, the paper's, with its -10 reward) without a
               termination on that step (bootstrap from the final observation). `gym.make` keeps
               its own `max_episode_steps` argument for Gymnasium's TimeLimit wrapper, which
               truncates without the -10 reward while ours still applies; ours is set by
               `HUAUVGymEnv(max_episode_steps=N)`.

Auto-reset mode: SAME_STEP (`metadata["autoreset_mode"] = AutoresetMode.SAME_STEP`), the mode our
own training wrapper uses, chosen because it wastes no step: when env i ends on a step, the
returned `obs[i]` and the top-level info of env i are already those of its new episode (reset with
`split(key)[1]` of the ended episode's PRNG key; an episode that goes on keeps our step's key, so
every episode is exactly our `reset(key)` followed by `step`s), while
`reward[i]`, `terminated[i]` and `truncated[i]` describe the transition that ended it. As
Gymnasium's SyncVectorEnv does in that mode, `infos["final_obs"]` is an object array holding that
transition's true next observation at i (None elsewhere) and `infos["final_info"]` its info dict,
each with a boolean mask `infos["_final_obs"]`, `infos["_final_info"]`. Every info key `k` comes
with its mask `_k` (all True at the top level: every env reports every key).

Seeding: `reset(seed=s)` seeds the env's NumPy generator, from which the JAX key of the reset is
drawn, so `reset(seed=s)` and the steps after it are reproducible; `reset()` continues the stream.

Rendering: `render_mode="rgb_array"` (`gym.make(ENV_ID, render_mode="rgb_array")`, so that
`gymnasium.wrappers.RecordVideo` works; it needs moviepy) makes `render()` return a frame
(H, W, 3) uint8 by MuJoCo's renderer (docrl_jax/envs/rendering.py): of the latest step (the
transition's own next state, with the path since the reset), or for `HUAUVVectorEnv` a tuple with one
frame per env of its current state. `render_camera` ("both", "follow", "overview"), `render_width` and
`render_height` choose the view; `metadata["render_fps"]` = 5 plays control steps in real time.
`close()` releases the renderer's OpenGL context.
"""

from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
    from gymnasium.vector import AutoresetMode, VectorEnv
except ImportError as err:  # the core package works without gymnasium; this module does not
    raise ImportError("docrl_jax.envs.gym_env needs gymnasium: pip install -e '.[gym]' (gymnasium==1.4.0)") from err

import docrl_jax.envs as envs
from docrl_jax.envs.huauv import ACTION_SIZE, OBS_SIZE, observation_bounds
from docrl_jax.envs.wrappers import reset_key

ENV_ID = "docrl_jax/HUAUV-v0"
RENDER_MODES = ["rgb_array"]
RENDER_FPS = 5   # one frame per control step (0.2 s) plays in real time


def observation_space(size: int = OBS_SIZE) -> spaces.Box:
    """Bounds of the observations (`huauv.observation_bounds`; `size` is the env's `observation_size`,
    more with vertical_beams or slant_beams)."""
    low, high = observation_bounds(size)
    return spaces.Box(low=low, high=high, dtype=np.float32)


def action_space() -> spaces.Box:
    return spaces.Box(low=-1.0, high=1.0, shape=(ACTION_SIZE,), dtype=np.float32)


# ------------------------------------------------------------------------------ compiled programs
_PROGRAMS: dict[tuple, tuple[Any, Callable, Callable]] = {}


def _programs(scenario: int, overrides: dict[str, Any], compiler_options: dict[str, Any] | None = None):
    """(env, reset, step) for these settings, built and jitted once per process (jit then compiles
    once per batch size): building an env and compiling its step take seconds, running it not."""
    cache_key = (int(scenario), tuple(sorted((k, tuple(v) if isinstance(v, list) else v)
                                             for k, v in overrides.items())),
                 tuple(sorted((compiler_options or {}).items())))
    if cache_key in _PROGRAMS:
        return _PROGRAMS[cache_key]
    env = envs.make(scenario, auto_reset=False, **overrides)
    on_arrival = bool(env.params.terminate_on_arrival)

    def reset(keys):
        states = jax.vmap(env.reset)(keys)
        return states, {"obs": states.obs, "info": states.info}

    def step_one(state, action):
        stepped = env.step(state, action)
        info = stepped.info
        terminated = info["terminated"] | (info["arrived"] & on_arrival)
        truncated = stepped.done & ~terminated          # only our step limit is left
        # SAME_STEP auto-reset, with our AutoResetWrapper's keys: an episode that goes on keeps our
        # step's own key, so every episode is exactly our env's reset(key) + step sequence; a new
        # episode's reset key is drawn from the ended episode's key (under vmap both branches run and
        # `where` picks one per env).
        fresh = env.reset(reset_key(stepped))
        nxt = jax.tree.map(lambda f, s: jnp.where(stepped.done, f, s), fresh, stepped)
        out = {"obs": nxt.obs, "reward": stepped.reward, "terminated": terminated, "truncated": truncated,
               "info": nxt.info}
        final = {"obs": stepped.obs, "info": info, "qpos": stepped.sim.data.qpos}   # qpos: for render()
        return nxt, out, final

    programs = (env, jax.jit(reset, compiler_options=compiler_options),
                jax.jit(jax.vmap(step_one), compiler_options=compiler_options))
    _PROGRAMS[cache_key] = programs
    return programs


def _masked(info: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
    """Gymnasium's vector info layout: each key's array plus a boolean mask `_key`."""
    out: dict[str, Any] = {}
    for k, v in info.items():
        out[k], out[f"_{k}"] = v, mask.copy()
    return out


def _keys(seed_source: np.random.Generator, num: int) -> jax.Array:
    return jax.random.split(jax.random.PRNGKey(int(seed_source.integers(0, 2**31 - 1))), num)


class _Rendering:
    """The adapters' `render_mode`: checks it, and holds MuJoCo's renderer once it is first used."""

    def __init__(self, env, render_mode: str | None, camera: str, width: int, height: int):
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode={render_mode!r}: valid render modes are {RENDER_MODES} (or None)")
        self.env, self.mode, self.args = env, render_mode, (camera, width, height)
        self._renderer = None

    def frame(self, qpos, infos: list[dict]) -> np.ndarray:
        from docrl_jax.envs import rendering
        if self._renderer is None:
            camera, width, height = self.args
            self._renderer = rendering.Renderer(self.env.mj_model, self.env.params, width, height, camera)
        return self._renderer.track_frame(rendering.track_from_infos(qpos, infos))

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


# ------------------------------------------------------------------------------ vector env
class HUAUVVectorEnv(VectorEnv):
    """`num_envs` HUAUV envs (`envs.make(scenario, **overrides)`) in one jitted vmapped step.

    `compiler_options` go to `jax.jit` (XLA options): e.g. {"xla_backend_optimization_level": 0}
    compiles about twice as fast on a CPU, for short runs where compiling dominates."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": RENDER_MODES, "render_fps": RENDER_FPS}

    def __init__(self, num_envs: int = 1, scenario: int = 2, compiler_options: dict[str, Any] | None = None,
                 render_mode: str | None = None, render_camera: str = "both", render_width: int = 640,
                 render_height: int = 240, **overrides: Any):
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs={num_envs!r}: must be an integer >= 1")
        if overrides.pop("auto_reset", False):
            raise ValueError("HUAUVVectorEnv always auto-resets (SAME_STEP); leave auto_reset out")
        self.num_envs = int(num_envs)
        self.env, self._reset, self._step = _programs(scenario, overrides, compiler_options)
        self.single_observation_space = observation_space(self.env.observation_size)
        self.single_action_space = action_space()
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self.metadata = dict(type(self).metadata)
        self._rendering = _Rendering(self.env, render_mode, render_camera, render_width, render_height)
        self.render_mode = render_mode
        self._state = None

    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        if options:
            raise ValueError(f"reset options {sorted(options)}: none are supported (every env is reset)")
        if isinstance(seed, (list, tuple)):
            if len(seed) != self.num_envs:
                raise ValueError(f"reset(seed=list of {len(seed)}): expected one seed per env ({self.num_envs})")
            super().reset(seed=seed[0])
            keys = jnp.stack([jax.random.PRNGKey(int(s)) for s in seed])
        else:
            super().reset(seed=seed)
            keys = _keys(self.np_random, self.num_envs)
        self._state, out = self._reset(keys)
        out = jax.device_get(out)
        all_envs = np.ones(self.num_envs, bool)
        return np.array(out["obs"]), _masked(out["info"], all_envs)

    def _step_device(self, actions):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        actions = np.asarray(actions, dtype=np.float32)
        if actions.shape != (self.num_envs, ACTION_SIZE):
            raise ValueError(f"actions of shape {actions.shape}: expected ({self.num_envs}, {ACTION_SIZE})")
        self._state, out, final = self._step(self._state, actions)
        return jax.device_get(out), final

    def step(self, actions):
        out, final = self._step_device(actions)
        done = out["terminated"] | out["truncated"]
        infos = _masked(out["info"], np.ones(self.num_envs, bool))
        if done.any():
            final = jax.device_get(final)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(done):
                final_obs[i] = np.array(final["obs"][i])
            infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
            infos["final_info"], infos["_final_info"] = _masked(final["info"], done), done.copy()
        return (np.array(out["obs"]), np.asarray(out["reward"], np.float32), np.array(out["terminated"]),
                np.array(out["truncated"]), infos)

    @property
    def state(self):
        """The batched JAX `EnvState` (after auto-reset), for inspection."""
        return self._state

    def render(self) -> tuple[np.ndarray, ...] | None:
        """With render_mode "rgb_array": one frame (H, W, 3) uint8 per env, of its current state."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() without a render_mode: make the env with render_mode='rgb_array'")
            return None
        if self._state is None:
            raise RuntimeError("call reset() before render()")
        qpos, info = jax.device_get((self._state.sim.data.qpos, self._state.info))
        return tuple(self._rendering.frame(qpos[i], [{k: v[i] for k, v in info.items()}]) for i in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        self._rendering.close()


# ------------------------------------------------------------------------------ single env
class HUAUVGymEnv(gymnasium.Env):
    """One HUAUV env (`envs.make(scenario, **overrides)`), no auto-reset: after `terminated` or
    `truncated`, call `reset()` (stepping on raises). `compiler_options` as for HUAUVVectorEnv."""

    metadata = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS}

    def __init__(self, scenario: int = 2, compiler_options: dict[str, Any] | None = None,
                 render_mode: str | None = None, render_camera: str = "both", render_width: int = 640,
                 render_height: int = 240, **overrides: Any):
        self._vec = HUAUVVectorEnv(1, scenario, compiler_options, **overrides)
        self.env = self._vec.env
        self.observation_space = self._vec.single_observation_space
        self.action_space = action_space()
        self._rendering = _Rendering(self.env, render_mode, render_camera, render_width, render_height)
        self.render_mode = render_mode
        self._ended = False
        self._seen: tuple[list, list] = ([], [])   # with a render_mode: poses and infos since the reset

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if options:
            raise ValueError(f"reset options {sorted(options)}: none are supported")
        self._vec._state, out = self._vec._reset(_keys(self.np_random, 1))
        out = jax.device_get(out)
        self._ended = False
        info = {k: np.array(v[0]) for k, v in out["info"].items()}
        if self.render_mode is not None:
            self._seen = ([np.asarray(self._vec._state.sim.data.qpos[0])], [info])
        return np.array(out["obs"][0]), info

    def step(self, action):
        if self._ended:
            raise RuntimeError("the episode has ended (terminated or truncated): call reset() before step()")
        action = np.asarray(action, dtype=np.float32)
        if action.shape != (ACTION_SIZE,):
            raise ValueError(f"action of shape {action.shape}: expected ({ACTION_SIZE},)")
        out, final = self._vec._step_device(action[None])
        final = jax.device_get(final)     # the transition's own next obs and info (not the auto-reset's)
        terminated, truncated = bool(out["terminated"][0]), bool(out["truncated"][0])
        self._ended = terminated or truncated
        info = {k: np.array(v[0]) for k, v in final["info"].items()}
        if self.render_mode is not None:
            self._seen[0].append(np.asarray(final["qpos"][0]))
            self._seen[1].append(info)
        return np.array(final["obs"][0]), float(out["reward"][0]), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """With render_mode "rgb_array": the frame (H, W, 3) uint8 of the latest state (the last
        step's next state, or the reset's), with the path since the reset."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() without a render_mode: make the env with render_mode='rgb_array'")
            return None
        if not self._seen[0]:
            raise RuntimeError("call reset() before render()")
        return self._rendering.frame(np.stack(self._seen[0]), self._seen[1])

    def close(self) -> None:
        self._rendering.close()
        super().close()


gymnasium.register(id=ENV_ID, entry_point=HUAUVGymEnv, vector_entry_point=HUAUVVectorEnv)

__all__ = ["HUAUVVectorEnv", "HUAUVGymEnv", "ENV_ID", "observation_space", "action_space"]
