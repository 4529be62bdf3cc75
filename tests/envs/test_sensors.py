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


def _random_poses(env, seed: int, n: int):
    """n random poses in the tank, mostly upright (up to ~35 degrees of tilt): yields the MuJoCo data
    (forwarded), the position, the body rotation and the arguments `sensors.cast` takes after the model."""
    m, d = env.mj_model, mujoco.MjData(env.mj_model)
    rng = np.random.default_rng(seed)
    lo, hi = env.params.bounds
    for _ in range(n):
        pos = np.array([rng.uniform(-4.6, 4.6), rng.uniform(-4.6, 4.6), rng.uniform(lo, hi)])
        quat = rng.normal(size=4)
        quat[1:3] *= 0.3
        quat /= np.linalg.norm(quat)
        d.qpos[:3], d.qpos[3:7] = pos, quat
        mujoco.mj_forward(m, d)
        rot = d.xmat[env.body_id].reshape(3, 3)
        yield d, pos, rot, (mjx.put_data(m, d), jnp.asarray(pos, jnp.float32), jnp.asarray(rot, jnp.float32),
                            jnp.asarray(pos[2] < 0.0))


def _mj_range(env, d, pos, direction, max_range: float) -> float:
    """mujoco.mj_ray's reading along a world direction, as a beam reports it (no hit: the maximum)."""
    dist = mujoco.mj_ray(env.mj_model, d, pos, direction, np.array(sensors.RAY_GEOMGROUP, np.uint8), 1,
                         env.body_id, np.zeros(1, np.int32))
    return max_range if dist < 0 else min(dist, max_range)


@pytest.mark.parametrize("scenario", [1, 2, 3])
def test_rays_match_mj_ray(casters, scenario):
    env, cast = casters[scenario]
    worst = 0.0
    for d, pos, rot, args in _random_poses(env, scenario, 25):
        ours = np.asarray(cast(*args))
        fov, max_range = (90.0, 20.0) if pos[2] < 0.0 else (270.0, 10.0)
        ref = [_mj_range(env, d, pos, rot @ np.array([np.cos(a), np.sin(a), 0.0]), max_range)
               for a in sensors.beam_angles(fov)]
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
    hits = 0
    for d, pos, rot, args in _random_poses(env, 7, 30):
        ours, fan = np.asarray(cast(*args)), np.asarray(fan_only(*args))
        assert ours.shape == (sensors.NUM_BEAMS + 2,)
        np.testing.assert_array_equal(ours[:sensors.NUM_BEAMS], fan)
        max_range = 20.0 if pos[2] < 0 else 10.0
        for k, sign in enumerate((1.0, -1.0)):
            expected = _mj_range(env, d, pos, sign * rot[:, 2], max_range)
            hits += expected < max_range
            assert ours[sensors.NUM_BEAMS + k] == pytest.approx(expected, abs=1e-3)
    assert hits >= 30, hits   # the floor below, and obstacles above in scenario 3, were hit


def test_slanted_beams_match_mj_ray(casters):
    """With vertical_beams and slant_beams=6 at 35 degrees: the fan and the vertical beams unchanged, then
    an upper and a lower ring of 6 beams each, at bearings 0, 60, .. 300 degrees from body x, reading
    mj_ray's distance along directions built here from the angles."""
    env, fan_only = casters[3]
    params = envs.make_params(3, vertical_beams=True, slant_beams=6, slant_elevation_deg=35.0)
    assert params.observation_size == 26 + 2 + 12
    cast = jax.jit(lambda d, p, r, u: sensors.cast(params, env.mjx_model, d, env.body_id, p, r, u))
    e = np.deg2rad(35.0)
    rings = [(np.cos(e) * np.cos(b), np.cos(e) * np.sin(b), sign * np.sin(e))
             for sign in (1.0, -1.0) for b in np.deg2rad(np.arange(0, 360, 60))]
    hits = 0
    for d, pos, rot, args in _random_poses(env, 11, 30):
        ours, fan = np.asarray(cast(*args)), np.asarray(fan_only(*args))
        assert ours.shape == (sensors.NUM_BEAMS + 2 + 12,)
        np.testing.assert_allclose(ours[:sensors.NUM_BEAMS], fan, atol=1e-5)   # another program: float rounding
        max_range = 20.0 if pos[2] < 0 else 10.0
        for k, local in enumerate([(0, 0, 1.0), (0, 0, -1.0)] + rings):
            expected = _mj_range(env, d, pos, rot @ np.array(local), max_range)
            hits += expected < max_range
            assert ours[sensors.NUM_BEAMS + k] == pytest.approx(expected, abs=1e-3)
    assert hits >= 200, hits   # walls, floor and obstacles: most slanted beams hit something in range


def test_slanted_beams_in_the_observation():
    """The empty tank's centre, 0.5 m up (1.8 m above the floor top, -1.3 m), upright, yaw 0.4 rad: the
    upper ring's 4 beams, 30 degrees above the body plane at yaw + k * 90 degrees, meet the walls
    (x, y = +-4.9) at 4.9 / (cos 30 cos 0.4) = 6.14 m; the lower ring meets the floor at 1.8 / sin 30 =
    3.6 m, before the walls. Scaled by the LIDAR's 10 m they follow the fan's 26 floats."""
    env = envs.make(1, slant_beams=4, wind_sigma=0.0)
    assert env.observation_size == 34
    s = jax.jit(env.reset_to)(jax.random.PRNGKey(0), jnp.array([0.0, 0.0, 0.5]), 0.4, jnp.array([0.0, 0.0, 3.0]))
    wall = 4.9 / (np.cos(np.deg2rad(30)) * np.cos(0.4))
    np.testing.assert_allclose(np.asarray(s.obs[26:]), [wall / 10] * 4 + [0.36] * 4, atol=1e-3)
    assert s.info["ranges"].shape == (20,)
    np.testing.assert_allclose(np.asarray(s.info["vertical_ranges"]), [wall] * 4 + [3.6] * 4, atol=1e-2)


def test_slant_beams_are_validated():
    for bad in ({"slant_beams": -1}, {"slant_beams": 2.5}, {"slant_beams": True}, {"slant_elevation_deg": 0.0},
                {"slant_elevation_deg": 90.0}):
        with pytest.raises(ValueError, match="slant_"):
            envs.make_params(2, **bad)


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
