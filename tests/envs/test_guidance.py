"""Route guidance (docrl_jax/envs/guidance.py): the observation's goal floats point at the route's aim.
Checked against the env's own observation (guiding at the real goal changes nothing) and in a hand-made
tank whose straight line from start to goal runs into a wall (tests/data/tanks/wall_and_opening.yaml, which
tests/baselines/test_route_follower.py flies): the aim is not the goal, lies down the route, is in sight, and
the guided observation's bearing turns towards it."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.envs import flyability, guidance, huauv, tanks
from docrl_jax.evaluate import rollout


@pytest.fixture(scope="module")
def trip():
    path = Path(__file__).resolve().parents[1] / "data" / "tanks" / "wall_and_opening.yaml"
    env = rollout.make_eval_env(0, 100, start_water_fraction=0.0, goal_water_fraction=1.0)
    layout = jax.tree.map(lambda x: x[None], tanks.load(path, env.params))
    state = jax.tree.map(lambda x: x[0], rollout.reset_states(env, jax.random.PRNGKey(3)[None], layout))
    plan = guidance.plan(jax.tree.map(lambda x: x[0], layout), env.params, state.info["goal"])
    return state, plan


def test_guiding_at_the_goal_is_the_envs_observation(trip):
    state, _ = trip
    info = state.info
    again = guidance.guide(state.obs, info["position"], info["yaw"], info["goal"])
    np.testing.assert_allclose(np.asarray(again), np.asarray(state.obs), atol=1e-6)
    assert huauv.GOAL_FEATURES.stop - huauv.GOAL_FEATURES.start == 3


def test_aim_leads_round_the_wall(trip):
    state, plan = trip
    position, goal = state.info["position"], state.info["goal"]
    assert not bool(guidance.in_sight(plan, position, goal))     # the wall is in the way
    target = guidance.aim(plan, position, goal)
    assert float(jnp.linalg.norm(target - goal)) > 1.0             # so the aim is not the goal ...
    assert float(flyability.field_at(plan["field"], target)) < float(flyability.field_at(plan["field"], position))
    assert bool(guidance.in_sight(plan, position, target))         # ... but a visible point down the route
    assert float(target[1]) > float(position[1])                   # towards the wall's open end (y > -1.5)
    guided = guidance.guide(state.obs, position, state.info["yaw"], target)
    want = huauv.goal_features(position, state.info["yaw"], target)
    np.testing.assert_allclose(np.asarray(guided[huauv.GOAL_FEATURES]), np.asarray(want), atol=1e-6)
    assert not np.allclose(np.asarray(guided[huauv.GOAL_FEATURES]), np.asarray(state.obs[huauv.GOAL_FEATURES]))
    np.testing.assert_array_equal(np.asarray(guided[:huauv.GOAL_FEATURES.start]),
                                  np.asarray(state.obs[:huauv.GOAL_FEATURES.start]))   # ranges, action untouched


def test_a_goal_near_the_floor_in_open_water_is_flown_at_straight():
    """Scenario 1's A-W goal lies 0.3 m above the floor, nearer than any line of sight may pass: its arrival
    sphere is what must be in sight, so in that open tank the guided policy flies as the mapless one (aim =
    goal from the start), not down the route to a point above the goal (where it hovered just outside the
    sphere in 44 of 100 trials). A wall between them still hides it (the test above)."""
    import docrl_jax.envs as envs
    env = rollout.make_eval_env(1, 100)
    start, goal = (jnp.asarray(p, jnp.float32) for p in envs.eval_pair(1, "air_to_water"))
    free, gap = flyability.tank_cells(*env.solids(), env.params)
    plan = guidance.plan_cells(free, gap, env.params, goal)
    assert float(flyability.field_at(gap, goal)) < guidance.GUIDED_SIGHT_GAP        # the goal itself is not in sight
    np.testing.assert_array_equal(guidance.aim(plan, start, goal, guidance.GUIDED_SIGHT_GAP), goal)
    # The evaluator's per-trial plans in a fixed scenario (its one tank gridded once): trial 1 is this plan.
    from types import SimpleNamespace
    states = SimpleNamespace(sim=SimpleNamespace(layout=None), info={"goal": jnp.stack([start, goal])})
    plans = guidance.trial_plans(env, states)
    for key in ("field", "gap", "arrival"):
        np.testing.assert_array_equal(plans[key][1], plan[key])


def test_a_steep_aim_under_water_comes_near_and_no_other():
    """With a steep reach (a guided policy's), an aim above steeper than STEEP_DEG from under water lies that
    far along its own direction; a shallow one, or one from the air, is the goal itself (an empty tank: the
    goal is always in sight)."""
    from docrl_jax.baselines import route
    reach = guidance.GUIDED_STEEP_REACH

    def aim(position, goal):
        position, goal = jnp.asarray(position, jnp.float32), jnp.asarray(goal, jnp.float32)
        return np.asarray(guidance.aim(route.straight_plan(goal), position, goal, 0.6, reach))

    steep = aim([0.0, 0.0, -1.0], [0.5, 0.0, 2.0])                      # 80 degrees above, 3 m away
    np.testing.assert_allclose(np.linalg.norm(steep - [0.0, 0.0, -1.0]), reach, atol=1e-5)
    np.testing.assert_allclose(steep - [0.0, 0.0, -1.0], reach * np.array([0.5, 0.0, 3.0]) / np.hypot(0.5, 3.0),
                               atol=1e-5)
    np.testing.assert_allclose(aim([0.0, 0.0, -1.0], [3.0, 0.0, 0.5]), [3.0, 0.0, 0.5], atol=1e-6)   # 27 degrees
    np.testing.assert_allclose(aim([0.0, 0.0, 1.0], [0.2, 0.0, 3.0]), [0.2, 0.0, 3.0], atol=1e-6)    # in air
