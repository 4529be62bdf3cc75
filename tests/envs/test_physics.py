"""Vehicle dynamics against physics limits and the controller's specification: hover, steady-state
velocity tracking in both media, surface crossings, buoyancy, wind, drag, collisions, rewards."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from docrl_jax.envs import physics
from docrl_jax.envs.params import make_params
from docrl_jax.envs.randomization import nominal_plant
from docrl_jax.resources import resource_dir

HOVER = (-1.0, 0.0, 0.0)
# Parameter sets shared by several tests (each distinct set costs one compile).
EVAL_LIKE = dict(wind=False, z_bounds=(-1.6, 4.8), terminate_on_arrival=True)
SHORT_SHAPED = dict(wind=False, max_episode_steps=10, progress_reward_scale=2.0)


def _run(env_fns, position, yaw, action, steps, scenario=1, goal=(0.0, 0.0, 4.5), key=0, **overrides):
    env, reset_to, rollout = env_fns(scenario, **overrides)
    s0 = reset_to(jax.random.PRNGKey(key), jnp.array(position, jnp.float32), yaw, jnp.array(goal, jnp.float32))
    actions = jnp.tile(jnp.array(action, jnp.float32), (steps, 1))
    _, (obs, rew, done, info) = rollout(s0, actions)
    return s0, obs, rew, done, info


@pytest.mark.parametrize("z", [2.0, -0.6])
def test_hover_holds_altitude_in_air_and_depth_underwater(env_fns, z):
    _, _, _, done, info = _run(env_fns, (0.0, 0.0, z), 0.3, HOVER, 75, wind=False)  # 15 s
    pos = np.asarray(info["position"])
    assert not np.any(np.asarray(done))
    assert np.max(np.abs(pos - np.array([0.0, 0.0, z]))) < 0.02
    assert np.max(np.abs(np.asarray(info["velocity"])[-10:])) < 0.005


@pytest.mark.parametrize("z", [2.0, -0.6])
def test_forward_speed_and_yaw_rate_are_tracked_at_steady_state(env_fns, z):
    # Full forward speed with dpsi = 0: 0.25 m/s along the heading, level flight.
    _, _, _, done, info = _run(env_fns, (-3.0, -1.0, z), 0.4, (1.0, 0.0, 0.0), 40, wind=False)
    v = np.asarray(info["velocity"])[-10:]  # last 2 s
    np.testing.assert_allclose(v.mean(0), [0.25 * np.cos(0.4), 0.25 * np.sin(0.4), 0.0], atol=0.01)
    assert abs(float(info["position"][-1][2]) - z) < 0.03
    # Hovering turn: dpsi = +0.25 is a yaw rate of 0.25 rad/s.
    _, _, _, _, info = _run(env_fns, (0.0, 0.0, z), 0.0, (-1.0, 0.0, 1.0), 30, wind=False)
    yaw = np.unwrap(np.asarray(info["yaw"]))
    rate = (yaw[-1] - yaw[-11]) / (10 * 0.2)
    assert rate == pytest.approx(0.25, abs=0.01)


def test_vertical_speed_is_tracked_in_both_media(env_fns):
    _, _, _, _, info = _run(env_fns, (0.0, 0.0, 0.8), 0.0, (-1.0, 1.0, 0.0), 40, wind=False)   # climb in air
    assert np.asarray(info["velocity"])[-8:, 2].mean() == pytest.approx(0.25, abs=0.01)
    _, _, _, _, info = _run(env_fns, (0.0, 0.0, -0.15), 0.0, (-1.0, -1.0, 0.0), 15, wind=False)  # sink in water
    assert np.all(np.asarray(info["position"])[3:, 2] < 0)
    assert np.asarray(info["velocity"])[-5:, 2].mean() == pytest.approx(-0.25, abs=0.02)


def test_dive_crosses_the_surface_switches_sensor_and_climbs_back(env_fns):
    env, reset_to, rollout = env_fns(1, wind=False)
    s0 = reset_to(jax.random.PRNGKey(0), jnp.array([0.0, 0.0, 0.6]), 0.0, jnp.array([0.0, 0.0, 4.5]))
    actions = jnp.concatenate([jnp.tile(jnp.array([-1.0, -1.0, 0.0]), (22, 1)),
                               jnp.tile(jnp.array([-1.0, 1.0, 0.0]), (30, 1))])
    _, (obs, _, done, info) = rollout(s0, actions)
    z, wet = np.asarray(info["position"])[:, 2], np.asarray(info["underwater"])
    ranges, obs = np.asarray(info["ranges"]), np.asarray(obs)
    assert not np.any(np.asarray(done))
    np.testing.assert_array_equal(wet, z < 0)
    i_in = int(np.argmax(wet))
    assert 0 < i_in < 22 and z[21] < -0.3                       # went under
    i_out = 22 + int(np.argmax(~wet[22:]))
    assert wet[21] and not wet[-1] and z[-1] > 0.3               # came back out
    # Sonar (max 20 m) underwater, LIDAR (max 10 m) in air: the normalisation follows the sensor...
    np.testing.assert_allclose(obs[i_in, :20] * 20.0, ranges[i_in], atol=1e-4)
    np.testing.assert_allclose(obs[i_out, :20] * 10.0, ranges[i_out], atol=1e-4)
    # ...and so does the fan: the LIDAR's +-135 degree side beams see the side walls at 4.9 m,
    # the sonar's +-45 degree beams see the front wall at 4.9 / cos(45 deg).
    assert ranges[i_out, 0] == pytest.approx(4.9 / np.cos(np.deg2rad(45)), abs=0.05)
    assert ranges[i_in, 0] == pytest.approx(4.9 / np.cos(np.deg2rad(45)), abs=0.05)
    assert ranges[i_out, 10] == pytest.approx(4.9 / np.cos(np.deg2rad(270 / 38)), abs=0.05)
    assert ranges[i_in, 10] == pytest.approx(4.9 / np.cos(np.deg2rad(90 / 38)), abs=0.05)


def test_medium_forces_buoyancy_drag_and_free_fall():
    p = make_params(1, wind=False)
    veh = physics.make_vehicle(2.08, np.array([0.0347563, 0.0458929, 0.0806492]), p.rotor_moment_constant)
    eye, zero3, zero4 = jnp.eye(3), jnp.zeros(3), jnp.zeros(4)
    w = lambda frac, vel=zero3, p=p, wind=jnp.zeros(2): physics.medium_wrench(nominal_plant(p), veh, eye, vel, zero3,
                                                                              zero4, wind, frac, 0.01)
    # In air, at rest, rotors off: nothing but gravity acts (free fall at g).
    np.testing.assert_allclose(np.asarray(w(0.0)), 0.0, atol=1e-6)
    # Buoyancy pushes up, only in water, by rho g V (scaled by m / (m + m_A) for the added mass).
    no_volume = make_params(1, wind=False, hull_volume=0.0)
    lift = float(w(1.0)[2] - w(1.0, p=no_volume)[2])
    expected = 1028.0 * 9.81 * 5e-5 * 2.08 / (2.08 + 1.93)
    assert lift == pytest.approx(expected, rel=1e-4) and lift > 0
    assert float(w(0.0)[2] - w(0.0, p=no_volume)[2]) == pytest.approx(0.0, abs=1e-6)
    # Added mass: a body sinking in water at rest accelerates at -(m g - B) / (m + m_A), not -g.
    acc = (float(w(1.0)[2]) - 2.08 * 9.81) / 2.08
    assert acc == pytest.approx(-(2.08 * 9.81 - 1028 * 9.81 * 5e-5) / (2.08 + 1.93), rel=1e-4)
    # Drag opposes motion, is far larger in water, and stays bounded (implicit form) at absurd speeds.
    v = jnp.array([1.0, 0.0, -1.0])
    f_air, f_water = np.asarray(w(0.0, v))[:3], np.asarray(w(1.0, v))[:3] - np.asarray(w(1.0))[:3]
    assert f_air[0] < 0 and f_water[0] < 0 and f_water[2] > 0 and abs(f_water[2]) > 100 * abs(f_air[2])
    fast = np.asarray(w(1.0, jnp.array([0.0, 0.0, -1e4])))[2]
    assert np.isfinite(fast) and fast * 0.01 / 2.08 < 1e4   # cannot reverse the velocity in one step


def test_every_scene_factors_its_mass_matrix_sparse_and_mjx_steps_as_mujoco_does(env_fns):
    """assets/common.xml sets jacobian="sparse" (MJX's element-wise factorisation instead of its dense
    GPU path of batched Cholesky and triangular solves): every scene loads it, and MJX's step of the
    env's own model then follows MuJoCo's C step of the same model (float64): a tumbling body, pushed and
    turned, so that every one of its 6 dofs moves."""
    for scene in ("procedural.xml", "scenario_1.xml", "scenario_2.xml", "scenario_3.xml"):
        model = mujoco.MjModel.from_xml_path(str(resource_dir("assets") / scene))
        assert model.opt.jacobian == mujoco.mjtJacobian.mjJAC_SPARSE, scene
    env, _, _ = env_fns(1)
    m = env.mj_model
    d = mujoco.MjData(m)
    d.qpos[:7] = [0.5, -1.0, 2.0, np.cos(0.4), np.sin(0.4) * 0.6, np.sin(0.4) * 0.8, 0.0]
    d.qvel[:] = [0.3, -0.2, 0.1, 1.5, -1.1, 2.0]
    d.xfrc_applied[env.body_id] = [1.0, 2.0, 17.0, 0.05, -0.03, 0.04]
    mujoco.mj_forward(m, d)
    steps = 60

    def run(data):
        return jax.lax.scan(lambda x, _: (mjx.step(env.mjx_model, x), (x.qpos, x.qvel)), data, None, length=steps)[1]

    qpos, qvel = jax.jit(run)(mjx.put_data(m, d))
    for t in range(steps):
        np.testing.assert_allclose(np.asarray(qpos[t]), d.qpos, atol=2e-5, err_msg=f"qpos, step {t}")
        np.testing.assert_allclose(np.asarray(qvel[t]), d.qvel, atol=1e-4, err_msg=f"qvel, step {t}")
        mujoco.mj_step(m, d)
    assert np.linalg.norm(d.qvel[3:] - [1.5, -1.1, 2.0]) > 0.1   # the applied torque turned it


def test_wind_pushes_only_in_air():
    p = make_params(1, wind=True)
    veh = physics.make_vehicle(2.08, np.array([0.0347563, 0.0458929, 0.0806492]), p.rotor_moment_constant)
    args = lambda frac, wind: (nominal_plant(p), veh, jnp.eye(3), jnp.zeros(3), jnp.zeros(3), jnp.zeros(4), wind, frac, 0.01)
    gust = jnp.array([1.0, -0.5])
    d_air = np.asarray(physics.medium_wrench(*args(0.0, gust)) - physics.medium_wrench(*args(0.0, jnp.zeros(2))))
    d_water = np.asarray(physics.medium_wrench(*args(1.0, gust)) - physics.medium_wrench(*args(1.0, jnp.zeros(2))))
    assert d_air[0] > 0 and d_air[1] < 0          # pushed downwind
    np.testing.assert_allclose(d_water, 0.0, atol=1e-7)


def test_wind_moves_a_hovering_vehicle_in_air_but_not_underwater(env_fns):
    drift = {}
    for z in (2.0, -0.6):   # scenario 2 with its default wind, tank centre (risers are 2.8 m away)
        finals = [np.asarray(_run(env_fns, (0.0, 0.0, z), 0.0, HOVER, 50, scenario=2, key=k)[4]["position"][-1])
                  for k in (1, 2)]
        drift[z] = [np.linalg.norm(f[:2]) for f in finals] + [np.linalg.norm(finals[0] - finals[1])]
    assert min(drift[2.0]) > 0.005          # the wind displaces it, differently per key
    assert max(drift[-0.6]) < 1e-4          # underwater the wind does nothing


def test_collision_with_riser_terminates_with_penalty(env_fns):
    # Scenario 2, riser at (2, 2), radius 0.6: fly straight at it along +y.
    _, _, rew, done, info = _run(env_fns, (2.0, -0.5, 2.0), np.pi / 2, (1.0, 0.0, 0.0), 60, scenario=2)
    i = int(np.argmax(np.asarray(done)))
    assert np.asarray(done)[i] and bool(info["collision"][i]) and bool(info["terminated"][i])
    assert float(rew[i]) == -10.0
    assert float(np.min(np.asarray(info["ranges"])[i])) < 0.5
    assert float(info["position"][i][1]) < 2 - 0.6 - 0.4    # stopped by the range check, before touching


def test_collision_margin_ends_the_episode_further_out(env_fns):
    # The approach above with env.collision_margin 0.3: the range check fires at 0.8 m, not 0.5 m.
    _, _, rew, done, info = _run(env_fns, (2.0, -0.5, 2.0), np.pi / 2, (1.0, 0.0, 0.0), 60, scenario=2,
                                 collision_margin=0.3)
    i = int(np.argmax(np.asarray(done)))
    assert np.asarray(done)[i] and bool(info["collision"][i]) and float(rew[i]) == -10.0
    ranges = np.asarray(info["ranges"]).min(axis=1)
    assert 0.5 < ranges[i] < 0.8 <= ranges[i - 1], ranges[i - 1:i + 1]


def test_an_episode_without_its_training_margins_ends_where_a_test_ends_it(env_fns):
    # The margin above, cleared in the episode's state as the trainer's evaluation lanes clear it: the
    # range check fires under 0.5 m again.
    _, reset_to, rollout = env_fns(2, collision_margin=0.3)
    s0 = reset_to(jax.random.PRNGKey(0), jnp.array((2.0, -0.5, 2.0)), np.pi / 2, jnp.array((0.0, 0.0, 4.5)))
    assert bool(s0.sim.training_margins)
    s0 = s0.replace(sim=s0.sim.replace(training_margins=jnp.zeros((), bool)))
    _, (_, rew, done, info) = rollout(s0, jnp.tile(jnp.array([1.0, 0.0, 0.0]), (60, 1)))
    i = int(np.argmax(np.asarray(done)))
    assert np.asarray(done)[i] and bool(info["collision"][i]) and float(rew[i]) == -10.0
    ranges = np.asarray(info["ranges"]).min(axis=1)
    assert ranges[i] < 0.5 <= ranges[i - 1], ranges[i - 1:i + 1]


def test_hull_touching_a_thin_obstacle_is_caught_without_ranges(env_fns):
    # With the range check off, only the geometric hull test can stop the vehicle at the riser surface.
    _, _, rew, done, info = _run(env_fns, (2.0, -0.2, 2.0), np.pi / 2, (1.0, 0.0, 0.0), 60, scenario=2, wind=False,
                                 collision_distance=0.0)
    i = int(np.argmax(np.asarray(done)))
    assert np.asarray(done)[i] and bool(info["collision"][i]) and float(rew[i]) == -10.0
    y = float(info["position"][i][1])
    assert 2 - 0.6 - 0.235 - 0.06 < y < 2 - 0.6 - 0.235 + 0.06   # the hull's front edge at the surface


def test_hull_margin_ends_the_episode_short_of_obstacles_not_of_walls(env_fns):
    # The approach above with env.hull_margin 0.2: the episode ends with the hull's front edge ~0.2 m
    # short of the riser's surface; flown at a wall, only the touch ends it (starts and goals may lie
    # nearer the walls and the floor than any margin).
    kw = dict(scenario=2, wind=False, collision_distance=0.0, hull_margin=0.2)
    _, _, rew, done, info = _run(env_fns, (2.0, -0.2, 2.0), np.pi / 2, (1.0, 0.0, 0.0), 60, **kw)
    i = int(np.argmax(np.asarray(done)))
    assert np.asarray(done)[i] and bool(info["collision"][i]) and float(rew[i]) == -10.0
    y = float(info["position"][i][1])
    assert 2 - 0.6 - 0.235 - 0.2 - 0.06 < y < 2 - 0.6 - 0.235 - 0.2 + 0.06
    _, _, rew, done, info = _run(env_fns, (4.0, 0.0, 2.0), 0.0, (1.0, 0.0, 0.0), 60, **kw)
    i = int(np.argmax(np.asarray(done)))
    assert np.asarray(done)[i] and bool(info["collision"][i])
    assert 4.9 - 0.235 - 0.06 < float(info["position"][i][0]) < 4.9 - 0.235 + 0.06


def test_floor_collision_and_leaving_the_bounds_terminate(env_fns):
    # Bounds moved below the floor: the hull hits the floor (top -1.3) first.
    _, _, rew, done, info = _run(env_fns, (0.0, 0.0, -0.8), 0.0, (-1.0, -1.0, 0.0), 40, **EVAL_LIKE)
    i = int(np.argmax(np.asarray(done)))
    assert bool(info["collision"][i]) and not bool(info["out_of_bounds"][i]) and float(rew[i]) == -10.0
    assert -1.3 < float(info["position"][i][2]) < -1.3 + 0.045 + 0.12 + 0.06
    # Default bounds: leaving z > -1.1 downward ends the episode as out of bounds.
    _, _, rew, done, info = _run(env_fns, (0.0, 0.0, -0.8), 0.0, (-1.0, -1.0, 0.0), 40, wind=False)
    i = int(np.argmax(np.asarray(done)))
    assert bool(info["out_of_bounds"][i]) and bool(info["terminated"][i]) and float(rew[i]) == -10.0
    assert float(info["position"][i][2]) < -1.1


def test_arrival_rewards_and_resamples_the_goal(env_fns):
    goal = (0.3, 0.0, 2.0)
    _, obs, rew, done, info = _run(env_fns, (0.0, 0.0, 2.0), 0.0, HOVER, 3, goal=goal, wind=False)
    assert bool(info["arrived"][0]) and float(rew[0]) == 100.0 and not bool(done[0])
    new_goal = np.asarray(info["goal"][0])
    assert np.linalg.norm(new_goal - np.array(goal)) > 0.1
    assert np.linalg.norm(new_goal - np.asarray(info["position"][0])) >= 1.0
    assert int(info["goals_reached"][0]) == 1 and not bool(info["arrived"][1])
    # The observation already points at the new goal.
    assert float(obs[0][25]) * 15.2 > 0.9
    # In evaluation mode arrival ends the episode instead.
    _, _, rew, done, info = _run(env_fns, (0.0, 0.0, 2.0), 0.0, HOVER, 2, goal=goal, **EVAL_LIKE)
    assert bool(done[0]) and bool(info["arrived"][0]) and float(rew[0]) == 100.0


def test_step_limit_truncates_with_penalty_and_shaping_is_optional(env_fns):
    # Hovering: the distance does not change, so rewards are the binary ones (shaping adds ~0).
    _, _, rew, done, info = _run(env_fns, (0.0, 0.0, 2.0), 0.0, HOVER, 10, **SHORT_SHAPED)
    assert [bool(d) for d in done] == [False] * 9 + [True]
    assert bool(info["truncated"][9]) and not bool(info["terminated"][9])
    assert float(rew[9]) == pytest.approx(-10.0, abs=1e-4)
    np.testing.assert_allclose(np.asarray(rew[:9]), 0.0, atol=1e-4)
    # Dense progress term: moving towards the goal earns scale * distance gained.
    _, _, rew, _, info = _run(env_fns, (-2.0, 0.0, 2.0), 0.0, (1.0, 0.0, 0.0), 9, goal=(3.0, 0.0, 2.0),
                              **SHORT_SHAPED)
    dist = np.asarray(info["distance"])
    np.testing.assert_allclose(np.asarray(rew[1:]), 2.0 * (dist[:-1] - dist[1:]), atol=1e-4)
    assert float(rew[-1]) > 0.05
