"""A privileged route-follower: the reference that tells whether a trial is flyable by the vehicle itself,
not only by the grid check (docrl_jax/envs/flyability.py). It knows the tank.

Each step it steers at `guidance.aim` of the trip's `guidance.plan` (docrl_jax/envs/guidance.py: the
farthest visible point a few cells down the route field, or the goal once in sight) with the scripted
`straight_line` policy's steering (docrl_jax/baselines/scripted.py). In the gallery's and the structured
set's trials (`python benchmarks/route_follower.py [--crowding 0]`, benchmarks/results/cpu/route_follower)
the default arrives in all 900, flyability's shortest routes (`--crowding 0`) collide in 37 (all in air,
where the LIDAR fan sees 270 degrees). It reads the pose and the goal from `info` and the grids from its
params, one plan per trial: run it with a rollout that maps params over trials (benchmarks/route_follower.py).
`guided` steers a learned policy at the same aim instead (its goal floats point there).

Without the tank's map, `own_map_follower` and `mapped` steer at the aim of the route planned on what the
vehicle's own beams have shown it (docrl_jax/envs/belief.py): their carry holds the belief, updated every step
from `info` (pose, attitude, ranges), and the last plan, made every `belief.REPLAN` steps of `info["step"]`;
nothing of the tank is known beforehand.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from docrl_jax.baselines.scripted import straight_line
from docrl_jax.envs import belief
from docrl_jax.envs import guidance
from docrl_jax.envs.guidance import aim
from docrl_jax.policy import Policy

_STRAIGHT = straight_line()


def straight_plan(goal: jax.Array) -> dict:
    """Params of the control case: the straight-line distance to `goal` from every cell and no solid
    anywhere, as if the tank were empty (the follower then flies straight at the goal)."""
    field = belief.initial_field(goal)
    return {"field": field, "gap": jnp.full(field.shape, jnp.inf, jnp.float32), "arrival": jnp.float32(0.0)}   # every line of sight is clear


def _init_carry():
    return jnp.zeros((), jnp.int32)


def _steer(carry, obs, info, key, target):
    """The scripted follower's action toward `target`."""
    position, goal = info["position"], info["goal"]
    # straight_line slows within 0.5 m (horizontally) of its goal; a route point is no place to stop, so
    # one nearer than that (and not straight above or below) is pushed out to 0.5 m along the same bearing.
    rel = target - position
    across = jnp.linalg.norm(rel[:2])
    stretch = jnp.where((across > 0.1) & jnp.any(target != goal), jnp.maximum(1.0, 0.5 / across), 1.0)
    target = position + rel * jnp.array([stretch, stretch, 1.0])
    _, action = _STRAIGHT.act(_STRAIGHT.params, carry, obs, {**info, "goal": target}, key)
    return carry + 1, action


def _act(params, carry, obs, info, key):
    return _steer(carry, obs, info, key, aim(params, info["position"], info["goal"]))


def _plans(params, env, states):
    return guidance.trial_plans(env, states)


def route_follower(params=None) -> Policy:
    """The route-follower with `params` (`guidance.plan` or `straight_plan` of one trip, or a stack of them with a
    leading trial axis for a rollout that maps params over trials); None: the evaluator's rollouts plan each
    trial from its initial state (`guidance.trial_plans`)."""
    return Policy(name="route_follower", params=params, init_carry=_init_carry, act=_act,
                  trial_params=None if params is not None else _plans, trial_axes=0)


def _guided_act(policy: Policy, params, plan: dict, carry, obs, info, key):
    """`policy`'s (carry, action) with its goal floats pointing at the aim of `plan` (lines of sight keeping
    GUIDED_SIGHT_GAP, a steep climb's aim brought GUIDED_STEEP_REACH near)."""
    position = info["position"]
    target = aim(plan, position, info["goal"], guidance.GUIDED_SIGHT_GAP, guidance.GUIDED_STEEP_REACH)
    return policy.act(params, carry, guidance.guide(obs, position, info["yaw"], target), info, key)


PLAN_AXES = {"plan": 0, "policy": None}   # vmap in_axes of a guided policy's params over trials


def _guided_plans(params, env, states):
    return {**params, "plan": guidance.trial_plans(env, states)}


_GUIDED: dict = {}   # id(policy.act) -> (guided act, policy): policies of one act share one guided act


def guided(policy: Policy) -> Policy:
    """`policy` steered by `aim` (lines of sight keeping GUIDED_SIGHT_GAP): each step its observation's goal
    floats point at the aim of the trip's plan (`plan`) from the pose in `info`. The returned Policy's params
    are {"plan": one plan per trial, "policy": `policy`'s own params}: a rollout maps "plan" over trials and
    shares "policy" (PLAN_AXES); the evaluator's rollouts plan each trial from its initial state. Policies of
    one act function (`policies.policy_for` shares them per architecture) get one guided act: one compile."""
    if id(policy.act) not in _GUIDED:
        def act(params, carry, obs, info, key):
            return _guided_act(policy, params["policy"], params["plan"], carry, obs, info, key)
        _GUIDED[id(policy.act)] = (act, policy)    # keeping the policy keeps its act's id unique
    return Policy(name=f"{policy.name} (route-guided)", params={"plan": None, "policy": policy.params},
                  init_carry=policy.init_carry, act=_GUIDED[id(policy.act)][0], source=policy.source,
                  which=policy.which, trial_params=_guided_plans, trial_axes=PLAN_AXES)


_OWN_MAP: dict = {}   # (kind, id(act), params) -> (act, init_carry, kept alive): one compile per policy and env


def own_map_follower(p) -> Policy:
    """The scripted follower (`route_follower`) on the route planned on its own beams (`belief.sense_and_plan`): it knows
    nothing of the tank beforehand. `p`: the env's params."""
    if ("follower", p) not in _OWN_MAP:
        def act(params, carry, obs, info, key):
            carry, plan = belief.sense_and_plan(p, carry, info)
            inner, action = _steer(carry["inner"], obs, info, key, aim(plan, info["position"], info["goal"]))
            return {**carry, "inner": inner}, action
        _OWN_MAP[("follower", p)] = (act, lambda: belief.own_map(_init_carry()), None)
    act, init, _ = _OWN_MAP[("follower", p)]
    return Policy(name="own-map follower", params=None, init_carry=init, act=act)


def mapped(policy: Policy, p) -> Policy:
    """`policy` steered as `guided` steers it, at the aim of the route planned on its own beams (`belief.sense_and_plan`)
    instead of the tank's: map-free. `p`: the params of the env it flies (its beams' geometry)."""
    cache_key = ("policy", id(policy.act), id(policy.init_carry), p)
    if cache_key not in _OWN_MAP:
        def act(params, carry, obs, info, key):
            carry, plan = belief.sense_and_plan(p, carry, info)
            inner, action = _guided_act(policy, params, plan, carry["inner"], obs, info, key)
            return {**carry, "inner": inner}, action
        _OWN_MAP[cache_key] = (act, lambda: belief.own_map(policy.init_carry()), policy)
    act, init, _ = _OWN_MAP[cache_key]
    return Policy(name=f"{policy.name} (own-map)", params=policy.params, init_carry=init, act=act,
                  source=policy.source, which=policy.which)
