"""Range sensors against independent references: mujoco.mj_ray on the same model, and closed-form
distances to the walls of the empty tank."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

import docrl_jax.envs as envs
from docrl_jax.envs import sensors


@pytest.fixture(scope="module")
def casters():
    out = {}
    for sc in (1, 2, 3):
        env = envs.make(sc)
        out[sc] = (env, jax.jit(lambda d, p, r, u, env=env: sensors.cast(env.params, env.mjx_model, d,
                                                                           env.body_id, p, r, u)))
    return out


@pytest.mark.parametrize("scenario", [1, 2, 3])
def test_rays_match_mj_ray(casters, scenario):
    env, cast = casters[scenario]
    m = env.mj_model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(scenario)
    lo, hi = env.params.bounds
    worst = 0.0
    for _ in range(25):
        pos = np.array([rng.uniform(-4.6, 4.6), rng.uniform(-4.6, 4.6), rng.uniform(lo, hi)])
        quat = rng.normal(size=4)
        quat[1:3] *= 0.3  # mostly upright, up to ~35 degrees of tilt
        quat /= np.linalg.norm(quat)
        d.qpos[:3], d.qpos[3:7] = pos, quat
        mujoco.mj_forward(m, d)
        rot = d.xmat[env.body_id].reshape(3, 3)
        underwater = pos[2] < 0.0
        ours = np.asarray(cast(mjx.put_data(m, d), jnp.asarray(pos, jnp.float32), jnp.asarray(rot, jnp.float32),
                               jnp.asarray(underwater)))
        fov, max_range = (90.0, 20.0) if underwater else (270.0, 10.0)
        ref = []
        for a in sensors.beam_angles(fov):
            vec = rot @ np.array([np.cos(a), np.sin(a), 0.0])
            dist = mujoco.mj_ray(m, d, pos, vec, np.array(sensors.RAY_GEOMGROUP, np.uint8), 1, env.body_id,
                                 np.zeros(1, np.int32))
            ref.append(max_range if dist < 0 else min(dist, max_range))
        worst = max(worst, float(np.max(np.abs(ours - np.array(ref)))))
    assert worst < 1e-3, worst


def _wall_distance(p, direction, half=4.9):
    """Distance along a horizontal direction from p to the inner wall faces of the square tank."""
    ts = []
    for axis in (0, 1):
        if abs(direction[axis]) > 1e-9:
            ts.append(((half if direction[axis] > 0 else -half) - p[axis]) / direction[axis])
    return min(ts)


@pytest.mark.parametrize("position, yaw", [((0.0, 0.0, 2.0), 0.0), ((1.5, -2.0, 3.0), 0.7),
                                           ((-3.0, 1.0, -0.5), -2.0), ((2.5, 2.5, -0.9), 2.9)])
def test_ranges_in_empty_tank_are_analytic(env_fns, position, yaw):
    env, reset_to, _ = env_fns(1, wind=False)
    s = reset_to(jax.random.PRNGKey(0), jnp.array(position), yaw, jnp.array([0.0, 0.0, 2.0]))
    underwater = position[2] < 0
    fov, max_range = (90.0, 20.0) if underwater else (270.0, 10.0)
    expected = [min(_wall_distance(position, (np.cos(yaw + a), np.sin(yaw + a))), max_range)
                for a in sensors.beam_angles(fov)]
    np.testing.assert_allclose(np.asarray(s.info["ranges"]), expected, atol=1e-3)
    assert bool(s.info["underwater"]) == underwater
    np.testing.assert_allclose(np.asarray(s.obs[:20]), np.array(expected) / max_range, atol=1e-4)


def test_beams_ignore_the_water_surface_and_the_vehicle(env_fns):
    env, reset_to, _ = env_fns(1, wind=False)
    # Just above and just below the surface, nose pitched 30 degrees towards the surface: the beams must
    # pass through the water surface (and never see the hull) and hit the walls or floor.
    for z, pitch in ((0.2, 0.52), (-0.2, -0.52)):
        m = env.mj_model
        d = mujoco.MjData(m)
        d.qpos[:3] = (0.0, 0.0, z)
        d.qpos[3:7] = (np.cos(pitch / 2), 0.0, np.sin(pitch / 2), 0.0)
        mujoco.mj_forward(m, d)
        rot = d.xmat[env.body_id].reshape(3, 3)
        r = np.asarray(sensors.cast(env.params, env.mjx_model, mjx.put_data(m, d), env.body_id,
                                    jnp.array(d.qpos[:3], jnp.float32), jnp.asarray(rot, jnp.float32),
                                    jnp.asarray(z < 0)))
        assert np.min(r) > 0.4, r  # would be ~0.2 m (surface) or ~0.2 m (own hull) otherwise


def test_sensor_noise_is_gaussian_and_bounded(env_fns):
    env, reset_to, _ = env_fns(1, wind=False, sensor_noise_std=0.1)
    keys = jax.random.split(jax.random.PRNGKey(0), 200)
    batch = jax.vmap(lambda k: reset_to(k, jnp.array([0.0, 0.0, 2.0]), 0.0, jnp.array([1.0, 1.0, 2.0])))(keys)
    clean = _wall_distance((0.0, 0.0), (1.0, 0.0))
    beam = np.asarray(batch.info["ranges"])[:, 10]  # +7.1 degrees
    expected = clean / np.cos(np.deg2rad(270 / 38))
    assert abs(beam.mean() - expected) < 0.03 and 0.07 < beam.std() < 0.13
    assert np.all(np.asarray(batch.info["ranges"]) <= 10.0)


def test_vertical_beams_match_mj_ray(casters):
    """With vertical_beams the fan is unchanged and two beams along body +z / -z read mj_ray's distance."""
    env, fan_only = casters[3]
    params = envs.make_params(3, vertical_beams=True)
    cast = jax.jit(lambda d, p, r, u: sensors.cast(params, env.mjx_model, d, env.body_id, p, r, u))
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    rng = np.random.default_rng(7)
    lo, hi = env.params.bounds
    hits = 0
    for _ in range(30):
        pos = np.array([rng.uniform(-4.6, 4.6), rng.uniform(-4.6, 4.6), rng.uniform(lo, hi)])
        quat = rng.normal(size=4)
        quat[1:3] *= 0.3
        quat /= np.linalg.norm(quat)
        d.qpos[:3], d.qpos[3:7] = pos, quat
        mujoco.mj_forward(m, d)
        rot = d.xmat[env.body_id].reshape(3, 3)
        args = (mjx.put_data(m, d), jnp.asarray(pos, jnp.float32), jnp.asarray(rot, jnp.float32),
                jnp.asarray(pos[2] < 0.0))
        ours, fan = np.asarray(cast(*args)), np.asarray(fan_only(*args))
        assert ours.shape == (sensors.NUM_BEAMS + 2,)
        np.testing.assert_array_equal(ours[:sensors.NUM_BEAMS], fan)
        max_range = 20.0 if pos[2] < 0 else 10.0
        for k, sign in enumerate((1.0, -1.0)):
            hit = mujoco.mj_ray(m, d, pos, sign * rot[:, 2], np.array(sensors.RAY_GEOMGROUP, np.uint8), 1,
                                env.body_id, np.zeros(1, np.int32))
            hits += 0 <= hit < max_range
            assert ours[sensors.NUM_BEAMS + k] == pytest.approx(max_range if hit < 0 else min(hit, max_range),
                                                                abs=1e-3)
    assert hits >= 30, hits   # the floor below, and obstacles above in scenario 3, were hit


def test_vertical_beams_extend_the_observation_not_the_collision_check(env_fns):
    """In the empty tank (floor top -1.3 m, no ceiling): the observation gains the up and down ranges /
    the active maximum, through the water surface as the fans; the fan and the rest keep their places;
    the floor 0.5 m under the vehicle (within the 0.5 m collision distance of the fans) is no collision.
    info["vertical_ranges"] holds the two in metres (empty without the beams), for the renderer."""
    env, reset_to, rollout = env_fns(1, wind=False, vertical_beams=True)
    _, plain_reset_to, _ = env_fns(1, wind=False)
    assert env.observation_size == 28
    key, goal = jax.random.PRNGKey(0), jnp.array([0.0, 0.0, 2.0])
    for position, expected in (((0.0, 0.0, 2.0), (10.0 / 10.0, 3.3 / 10.0)),
                               ((0.0, 0.0, -0.8), (20.0 / 20.0, 0.5 / 20.0))):
        s = reset_to(key, jnp.array(position), 0.4, goal)
        plain = plain_reset_to(key, jnp.array(position), 0.4, goal)
        np.testing.assert_allclose(np.asarray(s.obs[26:]), expected, atol=1e-4)
        np.testing.assert_array_equal(np.asarray(s.obs[:26]), np.asarray(plain.obs))
        limit = 20.0 if position[2] < 0 else 10.0
        np.testing.assert_allclose(np.asarray(s.info["vertical_ranges"]), np.array(expected) * limit, atol=1e-3)
        assert s.info["ranges"].shape == (20,) and plain.info["vertical_ranges"].shape == (0,)
    _, (_, _, done, info) = rollout(s, jnp.tile(jnp.array([-1.0, 0.0, 0.0]), (3, 1)))
    assert not np.any(np.asarray(info["collision"])) and not np.any(np.asarray(done))
