"""Auto-reset for training: a finished episode restarts inside the same `step` call.

The returned state holds the new episode's first observation in `obs`, while `reward`, `done` and
`info` describe the transition that just ended, and `info["final_obs"]` keeps that transition's true
next observation, so a learner bootstraps truncated episodes from the right state. Under `vmap` the
reset branch is computed for every env and selected with `where` (no data-dependent control flow).

An episode that goes on keeps the key stream of the env's own `step`, so every episode under
auto-reset is exactly the unwrapped env's `reset` (or `reset_to`) followed by its `step`s until it
ends; the next episode's reset key is drawn from the ended episode's key (`reset_key`). That is what
lets the trainer run its evaluation episodes as lanes of the training envs (docrl_jax.train.evaluation).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from docrl_jax.envs.huauv import EnvState, HUAUVEnv


def reset_key(stepped: EnvState) -> jax.Array:
    """The reset key of the episode that follows `stepped` (an env's state after `step`), drawn from its
    key; used only where the episode has ended, so the stream of an episode that goes on is untouched."""
    return jax.random.split(stepped.sim.key)[1]


class AutoResetWrapper:
    """`env` with episodes that restart inside `step` (module docstring); every other attribute is the
    env's own."""

    def __init__(self, env: HUAUVEnv):
        self.env = env

    def __getattr__(self, name):  # observation_size, action_size, control_dt, params, mj_model, ...
        return getattr(self.env, name)

    @staticmethod
    def _first(state: EnvState) -> EnvState:
        return state.replace(info={**state.info, "final_obs": state.obs})

    def reset(self, key: jax.Array, **kwargs) -> EnvState:
        """The env's `reset` (with its `layout` and `plant` arguments), in this wrapper's state layout."""
        return self._first(self.env.reset(key, **kwargs))

    def reset_to(self, key: jax.Array, position, yaw, goal, **kwargs) -> EnvState:
        """The env's `reset_to`, in this wrapper's state layout (with `info["final_obs"]`)."""
        return self._first(self.env.reset_to(key, position, yaw, goal, **kwargs))

    def step(self, state: EnvState, action: jax.Array, layout=None) -> EnvState:
        """The env's step; an episode that ends restarts in `layout` when given (a procedural tank's level
        from a level sampler, e.g. the trainer's curriculum), else in the layout its reset draws."""
        inner = state.replace(info={k: v for k, v in state.info.items() if k != "final_obs"})
        stepped = self.env.step(inner, action)
        fresh = self.env.reset(reset_key(stepped), layout=layout)
        done = stepped.done
        sim = jax.tree.map(lambda f, s: jnp.where(done, f, s), fresh.sim, stepped.sim)
        obs = jnp.where(done, fresh.obs, stepped.obs)
        info = {**stepped.info, "final_obs": stepped.obs,
                "goals_reached": jnp.where(done, 0, stepped.info["goals_reached"])}
        return stepped.replace(sim=sim, obs=obs, info=info)
