"""The HUAUV air-water navigation environment (MuJoCo MJX).

    env = docrl_jax.envs.make(scenario=2, sensor_noise_std=0.0, wind=False)
    state = env.reset(key)                      # EnvState(obs (26,), reward, done, info, sim)
    state = env.step(state, action)             # action in [-1, 1]^3
    state = env.reset_to(key, position, yaw, goal)

    env = docrl_jax.envs.make(tank="wall_one_opening")   # a tank file, a folder, or a packaged tank

`make(..., auto_reset=True)` wraps the env so finished episodes restart inside `step`.
"""

from __future__ import annotations

from typing import Any

from docrl_jax.envs.params import EnvParams, make_params, param_docs
from docrl_jax.moved import lazy_members

# The env's names, imported on first use: a config, a run's vehicle or the trainer's command line
# reads `docrl_jax.envs.params` without importing MuJoCo and MJX (two seconds of a launch, which the
# trainer spends loading its stored programs meanwhile).
__getattr__ = lazy_members(__name__, {
    **{name: "docrl_jax.envs.huauv" for name in ("ACTION_SIZE", "DIST_SCALE", "OBS_LAYOUT", "OBS_SIZE", "EnvState",
                                                 "HUAUVEnv", "SimState")},
    "AutoResetWrapper": "docrl_jax.envs.wrappers"})

# The paper's evaluation pairs (start, goal), "Experimental Results". Water-to-air swaps them.
EVAL_AIR_START_GOAL = {
    1: ((0.0, 0.0, 2.5), (2.0, 3.0, -1.0)),
    2: ((0.0, 0.0, 2.5), (3.6, -2.4, -1.0)),
    3: ((0.0, 0.0, 2.5), (3.6, -2.4, -1.0)),
}


def eval_pair(scenario: int, direction: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(start, goal) of the paper's evaluation: direction "air_to_water" or "water_to_air"."""
    if scenario not in EVAL_AIR_START_GOAL:
        raise ValueError(f"scenario {scenario!r}: valid scenarios are 1, 2, 3")
    air, water = EVAL_AIR_START_GOAL[scenario]
    if direction == "air_to_water":
        return air, water
    if direction == "water_to_air":
        return water, air
    raise ValueError(f"direction {direction!r}: valid directions are 'air_to_water', 'water_to_air'")


def make(scenario: int = 2, auto_reset: bool = False, tank=None, **overrides: Any):
    """Builds the environment for scenario 1, 2 or 3, or 0 (procedural tanks); keyword overrides set any
    `EnvParams` field. `tank`: a tank file, a folder of them, or a packaged tank's name (docs/TANKS.md):
    episodes fly in those tanks (scenario 0)."""
    from docrl_jax.envs.huauv import HUAUVEnv
    from docrl_jax.envs.wrappers import AutoResetWrapper
    if tank is not None:
        scenario, overrides = 0, {**overrides, "tank": str(tank)}
    env = HUAUVEnv(make_params(scenario, **overrides))
    return AutoResetWrapper(env) if auto_reset else env


__all__ = ["make", "eval_pair", "EVAL_AIR_START_GOAL", "EnvParams", "EnvState", "SimState", "HUAUVEnv",
           "AutoResetWrapper", "param_docs", "OBS_SIZE", "ACTION_SIZE", "OBS_LAYOUT", "DIST_SCALE"]
