"""Auto-reset for training: a finished episode restarts inside the same `step` call.

The returned state holds the new episode's first observation in `obs`, while `reward`, `done` and
`info` describe the transition that just ended, and `info["final_obs"]` keeps that transition's true
next observation, so a learner bootstraps truncated episodes from the right state. Under `vmap` the
reset branch is computed for every env and selected with `where` (no data-dependent control flow).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from docrl_jax.envs.huauv import EnvState, HUAUVEnv


class AutoResetWrapper:
    def __init__(self, env: HUAUVEnv):
        self.env = env

    def __getattr__(self, name):  # observation_size, action_size, control_dt, params, mj_model, ...
        return getattr(self.env, name)

    def reset(self, key: jax.Array) -> EnvState:
        state = self.env.reset(key)
        return state.replace(info={**state.info, "final_obs": state.obs})

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        inner = state.replace(info={k: v for k, v in state.info.items() if k != "final_obs"})
        stepped = self.env.step(inner, action)
        key, k_reset = jax.random.split(stepped.sim.key)
        fresh = self.env.reset(k_reset)
        done = stepped.done
        sim = jax.tree.map(lambda f, s: jnp.where(done, f, s), fresh.sim, stepped.sim.replace(key=key))
        obs = jnp.where(done, fresh.obs, stepped.obs)
        info = {**stepped.info, "final_obs": stepped.obs,
                "goals_reached": jnp.where(done, 0, stepped.info["goals_reached"])}
        return stepped.replace(sim=sim, obs=obs, info=info)
