"""The map the vehicle builds from its own beams (docrl_jax/envs/belief.py) and the route planned on it,
checked against the tank's true solids (flyability's signed distances of the tank file, computed from the
geometry, not from the rays that built the belief)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax import pretrained
from docrl_jax.envs import belief, flyability


def _env(tank):
    """A gallery tank flown with the shipped tanks policy's sensors (its fan, the beams up and down and the two
    slanted rings), noise-free."""
    vehicle = {k: v for k, v in pretrained.vehicle("sac_mlp_tanks").items() if not k.startswith("dr_")}
    return envs.make(tank=tank, **{**vehicle, "sensor_noise_std": 0.0, "wind": False})


def _sweep(env, poses):
    """The belief after sensing once at each (position, yaw): the env's own sensing at that pose."""
    layout = jax.tree.map(lambda x: x[0], env.tanks)
    reset = jax.jit(lambda k, pos, yaw, goal: env.reset_to(k, pos, yaw, goal, layout=layout))
    seen = jax.jit(lambda b, info: belief.update(b, env.params, info["position"], info["rot"], info["underwater"],
                                                 jnp.concatenate([info["ranges"], info["vertical_ranges"]])))
    b = belief.empty()
    for position, yaw in poses:
        state = reset(jax.random.PRNGKey(0), jnp.asarray(position, jnp.float32), jnp.float32(yaw),
                      jnp.asarray([0.0, 0.0, -1.0], jnp.float32))
        b = seen(b, state.info)
    return np.asarray(b), layout


def _true_gaps(layout):
    return np.asarray(jax.jit(flyability.cell_gaps)(layout))


@pytest.fixture(scope="module")
def window_tank():
    """wall_opening_mid (a full-height wall across the tank, one window at 1.5-3.3 m, x 1.6-3.4) swept from
    the air side at five heights, facing the wall and along it."""
    env = _env("wall_opening_mid")
    poses = [((x, -3.0, z), yaw) for x in (-2.5, 0.0, 2.5) for z in (4.2, 3.3, 2.4, 1.0, -0.6)
             for yaw in (np.pi / 2, 0.0, np.pi)]
    b, layout = _sweep(env, poses)
    return env, b, layout


def test_the_belief_agrees_with_the_tank_where_the_beams_passed_and_is_unknown_elsewhere(window_tank):
    env, b, layout = window_tank
    gap = _true_gaps(layout)
    occupied, free = b == belief.OCCUPIED, b == belief.FREE
    assert occupied.sum() > 200 and free.sum() > 2000
    # A seen solid lies in its cell: the cell's centre is within half a cell's diagonal of a surface
    # (its true signed distance), and a cell a beam crossed is not inside a solid.
    half_diagonal = flyability.GRID_STEP * np.sqrt(3) / 2
    assert np.all(np.abs(gap[occupied]) <= half_diagonal + 0.02), np.abs(gap[occupied]).max()
    assert np.all(gap[free] > -0.05), gap[free].min()
    # Behind the wall (y > 0.5) no beam passed but through the window: the water side's cells the window
    # cannot show stay unknown, and no cell there is marked occupied but the far wall and the window's frame.
    centres = np.asarray(flyability.cell_centres())
    hidden = (centres[..., 1] > 1.0) & (centres[..., 0] < 0.0) & (centres[..., 2] < 0.5) & (gap > 0.3)
    assert hidden.sum() > 1000 and np.all(b[hidden] == belief.UNKNOWN)


def test_a_wall_behind_the_sonar_is_in_the_belief_once_the_vehicle_has_faced_it():
    """Under water the sonar fans 90 degrees: dead_end_u's U base (x = 1.2, y -2.5..2.5) behind the vehicle
    is unseen, then seen once it turns to face it."""
    env = _env("dead_end_u")
    position = (3.0, 0.0, -0.8)
    centres = np.asarray(flyability.cell_centres())
    base = (np.abs(centres[..., 0] - 1.2) < 0.3) & (np.abs(centres[..., 1]) < 1.5) & (np.abs(centres[..., 2] + 0.8) < 0.2)
    away, _ = _sweep(env, [(position, 0.0)])
    assert not np.any(away[base] == belief.OCCUPIED)
    facing, _ = _sweep(env, [(position, 0.0), (position, np.pi)])
    assert np.sum(facing[base] == belief.OCCUPIED) >= 8


def test_the_route_on_the_belief_goes_round_the_discovered_wall_and_through_its_window(window_tank):
    env, b, layout = window_tank
    start, goal = jnp.asarray([-2.0, -3.0, 2.4]), jnp.asarray([-2.0, 3.0, -0.8])
    field = belief.initial_field(goal)
    plan = jax.jit(lambda f: belief.plan(jnp.asarray(b), f, goal, env.params, sweeps=200))(field)
    path = np.asarray(flyability.route_path(plan["field"], start))
    assert np.isfinite(np.asarray(plan["field"])[tuple(np.asarray(flyability.nearest_cell(start)[0]))])
    crossing = path[np.argmax(path[:, 1] > 0.0)]
    # The wall is crossed through its window (x 1.6-3.4, z 1.5-3.3), not straight across where it was seen.
    assert 1.6 < crossing[0] < 3.4 and 1.5 < crossing[2] < 3.3, crossing
    gap = _true_gaps(layout)
    idx = np.asarray(flyability.nearest_cell(jnp.asarray(path))[0])
    assert gap[idx[:, 0], idx[:, 1], idx[:, 2]].min() > 0.3


def test_in_a_u_trap_the_policy_on_its_own_map_arrives_where_the_mapless_one_times_out():
    """dead_end_u's pocket faces the air start: the shipped tanks policy flown straight at the goal stalls
    in it; steered down the route on the map its beams draw, it arrives (the same two trials)."""
    from docrl_jax.evaluate import policies, rollout, tank_sets, tank_trials
    env_kw = rollout.flown_env(pretrained.vehicle("sac_mlp_tanks"), {})
    host = rollout.make_eval_env(0, 500, **env_kw)
    _, stack = tank_sets.load("dead_end_u", host.params)
    outcome = {}
    for guide in (None, "sensors"):
        policy, _ = policies.policy_for(host, name="sac_mlp_tanks", guide=guide)
        trials = tank_trials.run(policy, stack, "air_to_water", 2, 500, 0, env_kw)
        outcome[guide] = (trials["success"].tolist(), trials["timeout"].tolist())
    assert outcome[None] == ([False, False], [True, True]), outcome
    assert outcome["sensors"][0] == [True, True], outcome


def test_the_field_rises_where_a_newly_seen_solid_closes_the_route():
    """Warm-started relaxation: a field that was too low (the straight line through a wall) rises to the route
    cost round the wall, and matches flyability's full wavefront on the same cells once converged."""
    free = np.ones(flyability.GRID_SHAPE, bool)
    free[:, 19, :] = False
    free[30:33, 19, :] = True                    # a slot in a wall across the tank
    goal = jnp.asarray([0.0, 3.0, 0.0])
    seeds = flyability.goal_seeds(jnp.asarray(free), goal, 0.5)
    want = np.asarray(flyability.distance_field(jnp.asarray(free), seeds))
    got = np.asarray(belief.relax(belief.initial_field(goal), jnp.asarray(free), seeds, jnp.float32(1.0), 150))
    reach = np.isfinite(want)
    np.testing.assert_allclose(got[reach], want[reach], rtol=1e-5, atol=1e-4)
    start = (19, 5, 17)
    assert want[start] > float(np.linalg.norm(np.asarray(flyability.cell_centres())[start] - np.asarray(goal))) + 1.0


def test_the_own_map_is_the_same_under_vmap_and_alone():
    env = _env("dead_end_u")
    p = env.params
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    states = jax.vmap(lambda k: env.reset(k))(keys)
    carries = jax.vmap(lambda _: belief.own_map())(keys)
    batched, plans = jax.jit(jax.vmap(lambda c, i: belief.sense_and_plan(p, c, i)))(carries, states.info)
    one, plan = jax.jit(lambda c, i: belief.sense_and_plan(p, c, i))(belief.own_map(),
                                                                  jax.tree.map(lambda x: x[1], states.info))
    np.testing.assert_array_equal(np.asarray(batched["belief"][1]), np.asarray(one["belief"]))
    np.testing.assert_allclose(np.asarray(plans["field"][1]), np.asarray(plan["field"]), rtol=1e-6)


def test_the_map_takes_every_step_and_the_route_is_planned_every_replan_steps(monkeypatch):
    """With the episode's step in `info`, the belief takes every step's beams (a chain of `update`) while the
    plan (field and gaps) changes only at steps 0, REPLAN, 2 REPLAN, ..., where it is `plan` of that step's belief
    from the last plan's field; without a step, every step plans. Under vmap a step shared by the batch keeps
    the cond (one branch runs), a per-trial one does not."""
    monkeypatch.setattr(belief, "REPLAN", 3)
    env = _env("dead_end_u")
    p = env.params
    state = jax.jit(env.reset)(jax.random.PRNGKey(1))
    _, infos = jax.jit(lambda s: jax.lax.scan(lambda s, _: (env.step(s, jnp.asarray([0.6, 0.8, 0.0])), s.info),
                                              s, None, length=8))(state)
    np.testing.assert_array_equal(np.asarray(infos["step"]), np.arange(8))   # the env's own count

    def fly(given):
        def one(carry, info):
            carry, plan = belief.sense_and_plan(p, carry, info if given else {k: v for k, v in info.items() if k != "step"})
            return carry, (carry["belief"], plan["field"], plan["gap"])
        return [np.asarray(a) for a in jax.jit(lambda xs: jax.lax.scan(one, belief.own_map(), xs)[1])(infos)]

    beliefs, fields, gaps = fly(True)
    ranges = jnp.concatenate([infos["ranges"], infos["vertical_ranges"]], -1)
    b = belief.empty()
    goal = infos["goal"][0]
    planned = jax.jit(lambda b, f: belief.plan(b, f, goal, p))
    last = belief.initial_field(goal)
    for t in range(8):
        b = belief.update(b, p, infos["position"][t], infos["rot"][t], infos["underwater"][t], ranges[t])
        np.testing.assert_array_equal(beliefs[t], np.asarray(b))
        if t % 3 == 0:
            want = planned(b, last)
            np.testing.assert_allclose(fields[t], np.asarray(want["field"]), rtol=1e-6)
            np.testing.assert_array_equal(gaps[t], np.asarray(want["gap"]))
            last = want["field"]
        else:
            np.testing.assert_array_equal(fields[t], fields[t - 1])
            np.testing.assert_array_equal(gaps[t], gaps[t - 1])
    # The beams showed something new between plans, and each plan moved the field: the cadence is visible.
    assert any(np.any(beliefs[t] != beliefs[t - 1]) for t in (1, 2, 4, 5, 7))
    assert all(np.any(fields[t] != fields[t - 1]) for t in (3, 6))
    every = fly(False)[1]
    assert np.any(every[1] != every[0]) and np.any(every[1] != fields[1])

    carries = jax.vmap(lambda _: belief.own_map())(jnp.arange(2))
    info2 = jax.tree.map(lambda x: jnp.stack([x[0], x[0]]), infos)

    def traced(step_axis):
        axes = {k: (step_axis if k == "step" else 0) for k in info2}
        info = {**info2, "step": info2["step"][0]} if step_axis is None else info2
        return str(jax.make_jaxpr(jax.vmap(lambda c, i: belief.sense_and_plan(p, c, i), in_axes=(0, axes)))(carries, info))
    assert "cond[" in traced(None) and "cond[" not in traced(0)
