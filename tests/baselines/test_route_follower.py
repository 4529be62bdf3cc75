"""The privileged route-follower (docrl_jax/baselines/route.py) in a hand-made tank: a wall across the
straight line from start to goal, open beyond its end. Following the tank's route field it flies round the
wall's end and arrives; given a straight-line field instead (the tank as if empty) it flies into the wall. The
evaluator's rollout, planning each trial from its initial state, flies the very same flight. In an empty
tank file whose water goal lies 0.3 m above the floor (the paper's; below every free cell) it arrives too."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax.baselines import route
from docrl_jax.envs import flyability as fly
from docrl_jax.envs import guidance, tanks
from docrl_jax.evaluate import rollout

MAX_STEPS = 250
WALL_END_Y = -1.5   # the wall of tests/data/tanks/wall_and_opening.yaml covers y < -1.5 at x = 0

TANK = (Path(__file__).resolve().parents[1] / "data" / "tanks" / "wall_and_opening.yaml").read_text()

PAPER_GOAL_TANK = """
name: paper_goal
floor_top: -1.5
air: [-1.5, -3.0, 1.0]
water: [1.5, -3.0, -1.2]
"""


@pytest.fixture(scope="module")
def flights(tmp_path_factory):
    path = tmp_path_factory.mktemp("tank") / "wall.yaml"
    path.write_text(TANK)
    env = rollout.make_eval_env(0, MAX_STEPS, start_water_fraction=0.0, goal_water_fraction=1.0)
    layout = jax.tree.map(lambda x: x[None], tanks.load(path, env.params))
    state = rollout.reset_states(env, jax.random.PRNGKey(3)[None], layout)
    goal = state.info["goal"][0]
    one = jax.tree.map(lambda x: x[0], layout)
    out = {}
    for name, params in (("route", guidance.plan(one, env.params, goal)), ("straight", route.straight_plan(goal))):
        out[name] = rollout.run_from_states(env, route.route_follower(params), state, jax.random.PRNGKey(0)[None],
                                            MAX_STEPS)
    # Without params the rollout plans each trial itself from its initial state (Policy.trial_params:
    # guidance.trial_plans, the env's solids), as `evaluate --guide` and the robustness benchmark do.
    out["planned_by_rollout"] = rollout.run_from_states(env, route.route_follower(), state,
                                                        jax.random.PRNGKey(0)[None], MAX_STEPS)
    return state, out


def test_start_and_goal_are_the_tank_points(flights):
    state, _ = flights
    np.testing.assert_allclose(np.asarray(state.info["position"][0]), [-1.5, -3.0, 1.0], atol=1e-5)
    np.testing.assert_allclose(np.asarray(state.info["goal"][0]), [1.5, -3.0, -0.8], atol=1e-5)


def test_route_field_arrives_round_the_wall(flights):
    trials = flights[1]["route"]
    assert trials["success"][0], f"outcome {trials['outcome'][0]} after {trials['steps'][0]} steps"
    assert trials["positions"][0, :, 1].max() > WALL_END_Y + 0.5    # it went round the wall's end
    assert trials["path_length"][0] > 2 * np.hypot(1.5, WALL_END_Y + 3.0 + 0.5)   # not through it


def test_straight_line_field_hits_the_wall(flights):
    trials = flights[1]["straight"]
    assert not trials["success"][0]
    assert trials["collision"][0]
    assert abs(trials["positions"][0, trials["steps"][0], 0]) < 0.8    # it ended at the wall


def test_the_rollout_plans_each_trial_as_the_layout_plan(flights):
    """The plan from the env's solids (`flyability.tank_cells`) is the one from the tank's layout grids."""
    mine, reference = flights[1]["planned_by_rollout"], flights[1]["route"]
    assert mine["success"][0]
    np.testing.assert_array_equal(mine["positions"], reference["positions"])


def test_a_goal_near_the_floor_is_reached(tmp_path):
    """The tank file's own goal 0.3 m above the floor: the env draws it (its tank set's `draw_layout`, then
    `sample_goal`), the plan's goal cells lie above it within the arrival distance, the follower arrives."""
    path = tmp_path / "paper_goal.yaml"
    path.write_text(PAPER_GOAL_TANK)
    env = rollout.make_eval_env(0, MAX_STEPS, start_water_fraction=0.0, goal_water_fraction=1.0)
    start, goal = np.array([-1.5, -3.0, 1.0]), np.array([1.5, -3.0, -1.2])
    in_tank = envs.make(tank=path, wind=False, goal_water_fraction=1.0)
    drawn = jax.jit(lambda k: in_tank.sample_goal(k, jnp.asarray(start, jnp.float32), in_tank.draw_layout(k)))
    np.testing.assert_allclose(np.asarray(drawn(jax.random.PRNGKey(1))), goal, atol=1e-6)
    layout = jax.tree.map(lambda x: x[None], tanks.load(path, env.params))
    state = rollout.reset_states(env, jax.random.PRNGKey(3)[None], layout)
    np.testing.assert_allclose(np.asarray(state.info["goal"][0]), goal, atol=1e-6)
    plan = guidance.plan(jax.tree.map(lambda x: x[0], layout), env.params, state.info["goal"][0])
    seeds = np.asarray(plan["field"]) == 0.0
    lowest = fly.GRID_Z[np.nonzero(seeds.any((0, 1)))[0].min()]
    assert goal[2] + 0.25 <= lowest <= goal[2] + env.params.arrival_distance       # above it, within reach
    trials = rollout.run_from_states(env, route.route_follower(plan), state, jax.random.PRNGKey(0)[None],
                                     MAX_STEPS)
    assert trials["success"][0], f"outcome {trials['outcome'][0]} after {trials['steps'][0]} steps"
    assert not trials["collision"][0]
