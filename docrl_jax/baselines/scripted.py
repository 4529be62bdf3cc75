"""Scripted reference policies for checking the evaluator (not baselines of the paper).

`straight_line(dive=False)` steers straight at the goal using the pose in `info` (it ignores
obstacles, so it is an oracle only in the empty tank, scenario 1); `straight_line(dive=True)` commands
full descent and nothing else, so it ends on the floor. Both share one `act` function and differ only
in `params`, so the evaluator compiles one rollout for the two.
"""

from __future__ import annotations

import jax.numpy as jnp

from docrl_jax.policy import Policy


def _init_carry():
    return jnp.zeros((), jnp.int32)


def _act(params, carry, obs, info, key):
    del obs, key
    rel = info["goal"] - info["position"]
    err = jnp.arctan2(rel[1], rel[0]) - info["yaw"]
    err = jnp.arctan2(jnp.sin(err), jnp.cos(err))
    # dpsi is both the yaw rate and the heading offset of the velocity (env action mapping), so
    # a2 = err / 0.25 points the velocity straight at the goal once |err| < 0.25 rad.
    a2 = jnp.clip(err / 0.25, -1.0, 1.0)
    speed = jnp.where(jnp.abs(err) < 0.5, jnp.minimum(0.25, 0.5 * jnp.linalg.norm(rel[:2])), 0.0)
    a0 = 2.0 * speed / 0.25 - 1.0
    a1 = jnp.clip(rel[2] / 0.5, -1.0, 1.0)
    steer = jnp.stack([a0, a1, a2])
    dive = jnp.array([-1.0, -1.0, 0.0])
    return carry + 1, jnp.where(params["dive"], dive, steer).astype(jnp.float32)


def straight_line(dive: bool = False) -> Policy:
    return Policy(name="dive" if dive else "straight_line", params={"dive": jnp.asarray(dive)},
                  init_carry=_init_carry, act=_act)
