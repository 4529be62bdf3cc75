"""Domain randomisation (docrl_jax/envs/randomization.py) against independent references.

`sample_plant` against its `dr_*` ranges and `nominal_plant` against the parameters it is made of;
each randomised quantity against the motion it must cause (the steady states of the nominal controller
facing the true plant, solved here by hand; a 1-D integration of a fall under saturated rotors; the
first-order motor lag in closed form); latency against the nominal run shifted in time; dropouts
against the true ranges the collision check keeps.

Compiled programs: the physics reads the episode's plant from the state, so one env whose static
switches are on (latency queues, range noise and dropout branches: `DR`) runs every plant, passed to
`reset_to(..., plant=...)`. The reference is `conftest.env_fns(1, wind=False)`, shared with the physics
tests. One more reset program checks that the `dr_*` parameters reach the plant of `reset_to`."""

from __future__ import annotations

import dataclasses
import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax.envs import physics
from docrl_jax.envs.params import EnvParams
from docrl_jax.envs.randomization import nominal_plant, sample_plant

HOVER = (-1.0, 0.0, 0.0)
REFERENCE = dict(wind=False)
DR = dict(wind=False, dr_mass_scale=(0.8, 1.2), dr_action_latency=(0, 2), dr_obs_latency=(0, 1),
          dr_beam_dropout=(0.0, 1.0), dr_range_noise_std=(0.0, 0.1))
WIDE = dict(dr_mass_scale=(0.7, 1.3), dr_hull_volume_scale=(0.5, 4.0), dr_water_drag_scale=(0.5, 2.0),
            dr_air_drag_scale=(0.25, 3.0), dr_added_mass_scale=(0.6, 1.5), dr_thrust_air_scale=(0.8, 1.1),
            dr_thrust_water_scale=(0.7, 1.0), dr_motor_tau_scale=(1.0, 3.0), dr_wind_scale=(0.0001, 2.0),
            dr_current_speed=(0.1, 0.4), dr_range_noise_std=(0.0, 0.2), dr_beam_dropout=(0.0, 0.3),
            dr_action_latency=(0, 3), dr_obs_latency=(1, 2))
OFF = {f.name: f.default for f in dataclasses.fields(EnvParams) if f.name.startswith("dr_")}


@pytest.fixture(scope="module")
def dr(env_fns):
    env, reset_to, rollout = env_fns(1, **DR)
    nominal = nominal_plant(env.params)

    def plant(**fields):
        """The nominal plant with `fields` replaced (same dtypes: one compiled program for all)."""
        return nominal._replace(**{k: jnp.asarray(v, getattr(nominal, k).dtype) for k, v in fields.items()})

    def run(plant, position, yaw, actions, goal=(0.0, 0.0, 4.5), fns=None):
        """(first state, (obs, reward, done, info) over the steps) of a run with `plant`."""
        reset, roll = fns or (reset_to, rollout)
        kw = {} if plant is None else {"plant": plant}
        s0 = reset(jax.random.PRNGKey(0), jnp.array(position, jnp.float32), yaw, jnp.array(goal, jnp.float32), **kw)
        return s0, jax.tree.map(np.asarray, roll(s0, jnp.asarray(np.atleast_2d(actions), jnp.float32))[1])

    reference = env_fns(1, **REFERENCE)
    return env, plant, run, (reference[1], reference[2])


def _hover(n):
    return np.tile(HOVER, (n, 1))


# ---------------------------------------------------------------- the plant
def test_sample_plant_draws_every_quantity_within_its_range():
    p = envs.make_params(1, **WIDE)
    nominal = nominal_plant(p)
    plants = jax.device_get(jax.jit(jax.vmap(lambda k: sample_plant(k, p)))(
        jax.random.split(jax.random.PRNGKey(0), 1024)))
    nom = jax.device_get(nominal)

    def within(values, lo, hi, spread=True):
        values = np.asarray(values)
        assert values.min() >= lo - 1e-5 * abs(lo) - 1e-7 and values.max() <= hi + 1e-5 * abs(hi) + 1e-7
        if spread:   # a uniform draw fills its range
            assert values.min() < lo + 0.05 * (hi - lo) and values.max() > hi - 0.05 * (hi - lo)

    within(plants.mass_scale, *p.dr_mass_scale)
    within(plants.buoyancy / nom.buoyancy, *p.dr_hull_volume_scale)
    for name in ("water_linear_drag", "water_quadratic_drag", "water_angular_drag"):
        ratio = getattr(plants, name) / getattr(nom, name)
        within(ratio, *p.dr_water_drag_scale)
        np.testing.assert_allclose(ratio, ratio[:, :1] * np.ones(3), rtol=1e-5)   # one scale for all axes
        np.testing.assert_allclose(ratio[:, 0], plants.water_linear_drag[:, 0] / nom.water_linear_drag[0],
                                   rtol=1e-5)                                         # and for all terms
    within(plants.air_linear_drag[:, 0] / nom.air_linear_drag[0], *p.dr_air_drag_scale)
    within(plants.air_quadratic_drag / nom.air_quadratic_drag, *p.dr_air_drag_scale)
    within(plants.added_mass / nom.added_mass, *p.dr_added_mass_scale)
    np.testing.assert_allclose(plants.added_mass / nom.added_mass, plants.added_inertia / nom.added_inertia[None],
                               rtol=1e-5)
    within(plants.thrust_air / p.rotor_max_thrust_air, *p.dr_thrust_air_scale)
    within(plants.thrust_water / p.rotor_max_thrust_water, *p.dr_thrust_water_scale)
    within(plants.tau_up / p.rotor_tau_up, *p.dr_motor_tau_scale)
    np.testing.assert_allclose(plants.tau_up / p.rotor_tau_up, plants.tau_down / p.rotor_tau_down, rtol=1e-5)
    within(plants.wind_sigma / p.wind_sigma, *p.dr_wind_scale)
    speed = np.linalg.norm(plants.current - np.asarray(p.water_current), axis=-1)
    within(speed, *p.dr_current_speed)
    direction = (plants.current - np.asarray(p.water_current)) / speed[:, None]
    assert np.all(np.abs(direction.mean(0)) < 0.1)               # no preferred direction in 3-D
    assert np.all(np.abs(direction).max(0) > 0.95)
    within(plants.noise_std - p.sensor_noise_std, *p.dr_range_noise_std)
    within(plants.dropout, *p.dr_beam_dropout)
    for name in ("action_latency", "obs_latency"):
        values = getattr(plants, name)
        assert values.dtype == np.int32
        assert set(np.unique(values)) == set(range(getattr(p, f"dr_{name}")[0], getattr(p, f"dr_{name}")[1] + 1))
    np.testing.assert_array_equal(plants.moment_constant, nom.moment_constant)    # never randomised
    # Each quantity is drawn on its own: mass and buoyancy, say, are uncorrelated.
    assert abs(np.corrcoef(plants.mass_scale, plants.buoyancy)[0, 1]) < 0.1


@pytest.mark.parametrize("scenario", [0, 1, 3])
def test_default_params_sample_exactly_the_nominal_plant_the_params_describe(scenario):
    p = envs.make_params(scenario)
    nominal = jax.device_get(nominal_plant(p))
    for seed in range(3):
        sampled = jax.device_get(sample_plant(jax.random.PRNGKey(seed), p))
        for name, a, b in zip(nominal._fields, sampled, nominal):
            assert np.asarray(a).dtype == np.asarray(b).dtype and np.array_equal(a, b), name
    # The nominal plant, field by field from the parameters themselves.
    f32 = lambda x: np.asarray(x, np.float32)  # noqa: E731
    expected = dict(mass_scale=1.0, buoyancy=f32(p.water_density * p.hull_volume * physics.GRAVITY),
                    added_mass=f32(p.added_mass), added_inertia=f32(p.added_inertia),
                    water_linear_drag=f32(p.water_linear_drag), water_quadratic_drag=f32(p.water_quadratic_drag),
                    water_angular_drag=f32(p.water_angular_drag), air_linear_drag=f32(p.air_linear_drag),
                    air_quadratic_drag=f32(p.air_quadratic_drag), thrust_air=p.rotor_max_thrust_air,
                    thrust_water=p.rotor_max_thrust_water, tau_up=p.rotor_tau_up, tau_down=p.rotor_tau_down,
                    moment_constant=p.rotor_moment_constant, wind_sigma=p.wind_sigma, current=f32(p.water_current),
                    noise_std=p.sensor_noise_std, dropout=0.0, action_latency=0, obs_latency=0)
    for name, value in expected.items():
        np.testing.assert_allclose(getattr(nominal, name), value, rtol=1e-6, err_msg=name)
    # What the controller believes does not depend on the ranges: nominal_plant ignores every dr_*.
    wide = jax.device_get(nominal_plant(envs.make_params(scenario, **WIDE)))
    assert all(np.array_equal(a, b) for a, b in zip(wide, nominal))
    # Spelling the defaults out is the same parameter set (so the same compiled programs and
    # trajectories): (1, 1) scales and (0, 0) offsets, written as floats or as ints.
    for explicit in (OFF, {k: tuple(int(x) for x in v) for k, v in OFF.items()}):
        q = envs.make_params(scenario, **explicit)
        assert q == p and hash(q) == hash(p)


def test_dr_params_reach_the_plant_of_reset_to():
    """The ranges of a built env, end to end: degenerate ranges (a draw that cannot vary) of every kind."""
    fixed = dict(dr_mass_scale=(1.1, 1.1), dr_hull_volume_scale=(4.0, 4.0), dr_water_drag_scale=(2.0, 2.0),
                 dr_thrust_air_scale=(0.1, 0.1), dr_motor_tau_scale=(5.0, 5.0), dr_current_speed=(0.3, 0.3),
                 dr_beam_dropout=(1.0, 1.0), dr_action_latency=(2, 2), dr_obs_latency=(1, 1))
    env = envs.make(1, wind=False, **fixed)
    p, nom = env.params, jax.device_get(nominal_plant(env.params))
    s = jax.device_get(jax.jit(env.reset_to)(jax.random.PRNGKey(4), jnp.array([0.0, 0.0, 2.0]), 0.0,
                                             jnp.array([1.0, 0.0, 2.0])))
    plant = s.sim.plant
    assert float(plant.mass_scale) == pytest.approx(1.1)
    assert float(plant.buoyancy) == pytest.approx(4.0 * p.water_density * p.hull_volume * physics.GRAVITY, rel=1e-6)
    np.testing.assert_allclose(plant.water_quadratic_drag, 2.0 * nom.water_quadratic_drag, rtol=1e-6)
    np.testing.assert_allclose(plant.air_quadratic_drag, nom.air_quadratic_drag, rtol=1e-6)
    assert float(plant.thrust_air) == pytest.approx(0.1 * p.rotor_max_thrust_air, rel=1e-6)
    assert float(plant.thrust_water) == pytest.approx(p.rotor_max_thrust_water, rel=1e-6)
    assert float(plant.tau_up) == pytest.approx(5 * p.rotor_tau_up) and float(plant.tau_down) == pytest.approx(
        5 * p.rotor_tau_down)
    assert float(np.linalg.norm(plant.current)) == pytest.approx(0.3, rel=1e-5)
    assert (int(plant.action_latency), int(plant.obs_latency), float(plant.dropout)) == (2, 1, 1.0)
    # The queues: two hover actions waiting, one observation (the first) waiting.
    np.testing.assert_array_equal(s.sim.actions, np.tile(HOVER, (2, 1)))
    np.testing.assert_array_equal(s.sim.observations, s.obs[None])
    np.testing.assert_array_equal(s.obs[:20], 1.0)   # every beam dropped: every range reads the maximum


def test_controller_reads_the_params_never_the_plant():
    assert "plant" not in inspect.signature(physics.controller).parameters
    nominal, randomised = envs.make_params(1), envs.make_params(1, **WIDE)
    veh = physics.make_vehicle(2.08, np.array([0.0347563, 0.0458929, 0.0806492]), nominal.rotor_moment_constant)
    rng = np.random.default_rng(0)
    for frac in (0.0, 0.5, 1.0):
        q = rng.normal(size=4) * np.array([1.0, 0.2, 0.2, 1.0])
        args = (physics.quat_to_mat(jnp.asarray(q / np.linalg.norm(q), jnp.float32)),
                *(jnp.asarray(rng.normal(size=3) * 0.3, jnp.float32) for _ in range(2)), frac,
                jnp.asarray(rng.normal(size=3) * 0.01, jnp.float32), jnp.array([0.2, -0.1, 0.15]), 0.01)
        a = physics.controller(nominal, veh, *args)
        b = physics.controller(randomised, veh, *args)
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


# ---------------------------------------------------------------- the plant reaches the physics
def test_nominal_plant_in_the_randomising_env_is_the_reference_bit_for_bit(dr):
    """The queues, noise and dropout branches of the randomising env change nothing when its plant is
    the nominal one: the same trajectory, bit for bit, as the env without them, across the surface."""
    env, plant, run, reference = dr
    actions = np.concatenate([np.tile([0.0, -1.0, 0.3], (12, 1)),
                              np.random.default_rng(1).uniform(-1, 1, (28, 3))])
    _, ours = run(plant(), (1.0, -1.0, 0.6), 0.3, actions)
    _, ref = run(None, (1.0, -1.0, 0.6), 0.3, actions, fns=reference)
    assert ours[3]["underwater"].any() and not ours[3]["underwater"].all()
    for a, b in zip(jax.tree.leaves(ours), jax.tree.leaves(ref)):
        np.testing.assert_array_equal(a, b)


def test_hull_volume_lifts_a_hovering_vehicle_at_the_controllers_steady_state(dr):
    """Buoyancy x4 under water: the controller's feed-forward still expects the nominal buoyancy, so
    the vehicle rises at the speed where its P loop and the water's drag take up the excess."""
    env, plant, run, _ = dr
    p, nom = env.params, nominal_plant(env.params)
    _, (_, _, done, info) = run(plant(), (0.0, 0.0, -0.9), 0.0, _hover(20))
    _, (_, _, done4, info4) = run(plant(buoyancy=4 * nom.buoyancy), (0.0, 0.0, -0.9), 0.0, _hover(20))
    assert not done.any() and not done4.any() and info4["underwater"].all()
    assert np.abs(info["position"][:, 2] + 0.9).max() < 0.02
    excess = 3 * float(nom.buoyancy)
    # m_eff kp v + (c1 + c2 v) v = excess   (the controller's effective mass; linear + quadratic drag)
    m_eff = env.vehicle.mass + np.mean(p.added_mass)
    c1, c2 = p.water_linear_drag[2], p.water_quadratic_drag[2]
    b = m_eff * p.vel_p_gain + c1
    v = (-b + np.sqrt(b * b + 4 * c2 * excess)) / (2 * c2)
    assert info4["velocity"][-8:, 2].mean() == pytest.approx(v, rel=0.02)
    assert info4["position"][-1, 2] > -0.9 + 0.3


@pytest.mark.parametrize("scale", [1.1, 0.9])
def test_mass_scale_makes_the_hover_sink_or_climb(dr, scale):
    """A vehicle heavier (lighter) than the controller's model sinks (climbs) in air at the speed where
    the P loop makes up the weight error: m kp v = (1 - s) m g, so v = (1 - s) g / kp."""
    env, plant, run, _ = dr
    z0 = 3.5 if scale > 1 else 1.0
    _, (_, _, done, info) = run(plant(mass_scale=scale), (0.0, 0.0, z0), 0.0, _hover(20))
    assert not done.any()
    v = (1 - scale) * physics.GRAVITY / env.params.vel_p_gain
    assert info["velocity"][-8:, 2].mean() == pytest.approx(v, rel=0.02)
    assert np.sign(info["position"][-1, 2] - z0) == np.sign(v) and abs(info["position"][-1, 2] - z0) > 1.0


@pytest.mark.parametrize("scale", [1.1, 0.9])
def test_rate_limited_integral_takes_up_a_wrong_mass(env_fns, scale):
    """With env.vel_i_rate the integral also accumulates outside its band (at most that rate), so the
    same wrong mass stops drifting: the integral settles where it carries the weight error the
    feed-forward misses, m ki I = (s - 1) m g, so I = (s - 1) g / ki; and the climb or sink on the
    way is bounded, where the default integral (the test above) never engages."""
    rate, z0 = 0.3, (3.5 if scale > 1 else 1.0)
    env, reset_to, rollout = env_fns(1, wind=False, dr_mass_scale=(0.8, 1.2), vel_i_rate=rate)
    nominal = nominal_plant(env.params)
    plant = nominal._replace(mass_scale=jnp.asarray(scale, nominal.mass_scale.dtype))
    s0 = reset_to(jax.random.PRNGKey(0), jnp.array([0.0, 0.0, z0]), 0.0, jnp.array([0.0, 0.0, 4.5]), plant=plant)
    final, (_, _, done, info) = rollout(s0, jnp.asarray(_hover(80), jnp.float32))
    p = env.params
    assert not np.asarray(done).any()
    assert float(final.sim.vel_integral[2]) == pytest.approx((scale - 1) * physics.GRAVITY / p.vel_i_gain, rel=0.02)
    z = np.asarray(info["position"][:, 2])
    assert np.abs(np.asarray(info["velocity"][-10:, 2])).max() < 0.005   # stopped: no steady drift left
    assert np.abs(z - z0).max() < 1.2 and np.sign(z[-1] - z0) == np.sign(1 - scale)


def test_weak_rotors_in_air_fall_as_newton_says(dr):
    """Thrust limit x0.1 in air: every rotor saturates, the vehicle falls; a 1-D integration of the
    saturated rotors (first-order lag from the hover thrust), gravity and the air's vertical drag."""
    env, plant, run, _ = dr
    p = env.params
    limit = 0.1 * p.rotor_max_thrust_air
    s0, (_, _, _, info) = run(plant(thrust_air=limit), (0.0, 0.0, 3.0), 0.0, _hover(3))
    _, (_, _, _, nominal) = run(plant(), (0.0, 0.0, 3.0), 0.0, _hover(3))
    m, dt = env.vehicle.mass, p.physics_dt
    thrust, v, z, zs = float(s0.sim.thrust[0]), 0.0, 3.0, []
    for k in range(3 * p.substeps):
        thrust = limit + (thrust - limit) * np.exp(-dt / p.rotor_tau_down)
        a = (4 * thrust - m * physics.GRAVITY - p.air_quadratic_drag[2] * v * abs(v)) / m
        v += a * dt
        z += v * dt
        if (k + 1) % p.substeps == 0:
            zs.append(z)
    np.testing.assert_allclose(info["position"][:, 2], zs, atol=0.01)
    assert 3.0 - zs[-1] > 0.5 and np.abs(nominal["position"][:, 2] - 3.0).max() < 0.005


def test_current_drifts_a_hovering_vehicle_downstream(dr):
    """A 0.3 m/s current under water: the vehicle drifts with it at the speed where the P loop holds
    the drag of the relative flow, m_eff kp v = (c1 + c2 (c - v)) (c - v), and not across it."""
    env, plant, run, _ = dr
    p = env.params
    c = 0.3
    current = np.array([0.6, -0.8, 0.0]) * c
    yaw = float(np.arctan2(current[1], current[0]))   # body x along the flow: one drag axis
    _, (_, _, done, info) = run(plant(current=current), (0.0, 0.0, -0.7), yaw, _hover(20))
    _, (_, _, _, still) = run(plant(), (0.0, 0.0, -0.7), yaw, _hover(20))
    assert not done.any()
    m_eff = env.vehicle.mass + np.mean(p.added_mass)
    c1, c2 = p.water_linear_drag[0], p.water_quadratic_drag[0]
    # u = c - v solves c2 u^2 + (c1 + m_eff kp) u - m_eff kp c = 0
    b = c1 + m_eff * p.vel_p_gain
    u = (-b + np.sqrt(b * b + 4 * c2 * m_eff * p.vel_p_gain * c)) / (2 * c2)
    drift = info["velocity"][-8:].mean(0)
    assert drift @ current / c == pytest.approx(c - u, rel=0.05)
    assert np.linalg.norm(drift - (drift @ current) * current / c**2) < 0.005     # along the current
    assert np.linalg.norm(still["position"][-1, :2]) < 1e-4


def test_motor_lag_scale_slows_the_thrust_response(dr):
    env, plant, run, _ = dr
    p, nom = env.params, nominal_plant(env.params)
    # The rotor model itself: a constant command is approached as 1 - exp(-t / tau), rising or falling.
    slow = plant(tau_up=10 * nom.tau_up, tau_down=10 * nom.tau_down)
    for pl, scale in ((plant(), 1.0), (slow, 10.0)):
        for start, command, tau in ((2.0, 6.0, p.rotor_tau_up), (6.0, 2.0, p.rotor_tau_down)):
            thrust = jnp.full(4, start)
            for _ in range(5):
                thrust = physics.rotor_response(pl, thrust, jnp.full(4, command), jnp.full(4, 28.9), 0.01)
            expected = command + (start - command) * np.exp(-0.05 / (scale * tau))
            np.testing.assert_allclose(thrust, expected, rtol=1e-5)
    # In the env: a climb command, one step; slow motors leave the vehicle behind.
    climb = [-1.0, 1.0, 0.0]
    _, (_, _, _, fast) = run(plant(), (0.0, 0.0, 2.0), 0.0, climb)
    _, (_, _, _, lagged) = run(slow, (0.0, 0.0, 2.0), 0.0, climb)
    assert 0.05 < fast["velocity"][0, 2] and lagged["velocity"][0, 2] < 0.75 * fast["velocity"][0, 2]


# ---------------------------------------------------------------- latency and dropouts
def test_action_latency_shifts_the_response_by_whole_steps(dr):
    """Two steps of action latency: the run equals the reference run given two hover actions first."""
    env, plant, run, reference = dr
    actions = np.random.default_rng(2).uniform(-1, 1, (24, 3))
    _, late = run(plant(action_latency=2), (0.5, 1.0, 1.5), -0.4, actions)
    _, ref = run(None, (0.5, 1.0, 1.5), -0.4, np.concatenate([_hover(2), actions[:-2]]), fns=reference)
    obs, _, _, info = late
    r_obs, _, _, r_info = ref
    for name in ("position", "velocity", "yaw", "ranges", "distance"):
        np.testing.assert_allclose(info[name], r_info[name], atol=1e-6, err_msg=name)
    np.testing.assert_allclose(obs[:, :20], r_obs[:, :20], atol=1e-6)
    np.testing.assert_allclose(obs[:, 23:], r_obs[:, 23:], atol=1e-6)
    # The observation reports the action the agent sent (not yet acting), and it did move.
    np.testing.assert_allclose(obs[:, 20:23], np.clip(actions, -1, 1), atol=1e-7)
    assert np.linalg.norm(info["position"][-1] - info["position"][0]) > 0.2
    # With the latency drawn as 0 the same env follows the actions at once.
    _, now = run(plant(action_latency=0), (0.5, 1.0, 1.5), -0.4, actions)
    _, ref_now = run(None, (0.5, 1.0, 1.5), -0.4, actions, fns=reference)
    np.testing.assert_allclose(now[3]["position"], ref_now[3]["position"], atol=1e-6)


def test_observation_latency_shows_the_previous_steps_observation(dr):
    env, plant, run, reference = dr
    actions = np.random.default_rng(3).uniform(-1, 1, (20, 3))
    s0, (obs, _, _, info) = run(plant(obs_latency=1), (-1.0, 2.0, -0.4), 1.0, actions)
    r0, (r_obs, _, _, r_info) = run(None, (-1.0, 2.0, -0.4), 1.0, actions, fns=reference)
    np.testing.assert_array_equal(s0.obs, r0.obs)                 # the reset's own observation
    np.testing.assert_allclose(obs[0], r0.obs, atol=1e-6)         # seen again after the first step
    np.testing.assert_allclose(obs[1:], r_obs[:-1], atol=1e-6)    # then one step late throughout
    np.testing.assert_allclose(info["position"], r_info["position"], atol=1e-6)   # the vehicle is not late
    assert np.abs(np.diff(r_obs, axis=0)).max() > 0.01


def test_dropped_beams_read_the_maximum_but_collisions_see_the_true_ranges(dr):
    """Every beam dropped: the observation's ranges all read the maximum, yet a vehicle 0.4 m from a
    wall (the hull clear of it, only a range below 0.5 m tells) is still a collision."""
    env, plant, run, _ = dr
    position, goal = (4.5, 0.0, 2.0), (0.0, 0.0, 2.0)     # facing the east wall at x = 4.9
    _, (obs, rew, done, info) = run(plant(dropout=1.0), position, 0.0, _hover(1), goal=goal)
    _, (k_obs, _, k_done, kept) = run(plant(), position, 0.0, _hover(1), goal=goal)
    np.testing.assert_array_equal(obs[0, :20], 1.0)
    np.testing.assert_array_equal(info["ranges"][0], env.params.lidar_max_range)
    assert kept["ranges"][0].min() == pytest.approx(0.4, abs=0.01) and k_obs[0, :20].min() < 0.05
    assert bool(info["collision"][0]) and bool(done[0]) and float(rew[0]) == env.params.reward_collide
    assert bool(kept["collision"][0]) and bool(k_done[0])
    # A quarter dropped: about a quarter of the beams read the maximum, the others as measured.
    _, (obs, _, _, info) = run(plant(dropout=0.25), (0.0, 0.0, 2.0), 0.0, _hover(40), goal=(0.0, 3.0, 2.0))
    maxed = obs[:, :20] == 1.0
    assert 0.18 < maxed.mean() < 0.32


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize("kwargs, pattern", [
    ({"layout_boxes": (5, 3)}, r"layout_boxes=\(5, 3\): .*low <= high.*\[0, 12\]"),
    ({"layout_capsules": (0, 7)}, r"layout_capsules=\(0, 7\): .*\[0, 6\]"),
    ({"layout_capsules": (1.5, 3)}, r"layout_capsules=\(1.5, 3\): .*whole numbers"),
    ({"layout_boxes": (2.0, 4.0)}, r"layout_boxes=\(2.0, 4.0\): .*whole numbers"),
    ({"layout_floor_top": (-1.0, -0.5)}, r"layout_floor_top=.*\[-4.4, -0.8\]"),
    ({"layout_beam_fraction": 1.5}, r"layout_beam_fraction=1.5: .*\[0, 1\]"),
    ({"dr_mass_scale": (-1.0, 1.0)}, r"dr_mass_scale=\(-1.0, 1.0\): .*\(0, 100\]"),
    ({"dr_hull_volume_scale": (2.0, 1.0)}, r"dr_hull_volume_scale=\(2.0, 1.0\): .*low <= high"),
    ({"dr_motor_tau_scale": (0.0, 1.0)}, r"dr_motor_tau_scale=.*\(0, 100\]"),
    ({"dr_current_speed": (0.3, 0.1)}, r"dr_current_speed=\(0.3, 0.1\): .*\[0, 2\] m/s"),
    ({"dr_range_noise_std": (0.0, 6.0)}, r"dr_range_noise_std=.*\[0, 5\] m"),
    ({"dr_current_speed": (-0.1, 0.2)}, r"dr_current_speed=\(-0.1, 0.2\): .*\[0, 2\] m/s"),
    ({"dr_range_noise_std": (-0.5, 0.0)}, r"dr_range_noise_std=.*\[0, 5\] m"),
    ({"dr_beam_dropout": (0.5, 1.5)}, r"dr_beam_dropout=\(0.5, 1.5\): .*\[0, 1\]"),
    ({"dr_action_latency": (0, 11)}, r"dr_action_latency=\(0, 11\): .*\[0, 10\] control steps"),
    ({"dr_obs_latency": (-1, 0)}, r"dr_obs_latency=\(-1, 0\): .*\[0, 10\]"),
    ({"dr_obs_latency": (1.0, 2.0)}, r"dr_obs_latency=\(1.0, 2.0\): .*whole numbers"),
    ({"dr_wind_scale": (1.0,)}, r"dr_wind_scale=\(1.0,\): must be a sequence of 2 finite numbers"),
    ({"dr_mass_scale": (1.0, float("nan"))}, r"dr_mass_scale=.*finite"),
    ({"scenario": 5}, r"scenario=5: valid scenarios are 0 \(procedural\), 1, 2, 3"),
])
def test_bad_ranges_raise_naming_the_parameter_and_the_valid_range(kwargs, pattern):
    kwargs = dict(kwargs)
    scenario = kwargs.pop("scenario", 0)
    with pytest.raises(ValueError, match="env parameter " + pattern):
        envs.make_params(scenario, **kwargs)


def test_edge_ranges_are_accepted():
    p = envs.make_params(0, layout_boxes=(0, 12), layout_capsules=(6, 6), layout_floor_top=(-4.4, -0.8),
                         dr_action_latency=(10, 10), dr_obs_latency=(0, 10), dr_beam_dropout=(1.0, 1.0),
                         dr_mass_scale=(100.0, 100.0), dr_current_speed=(2.0, 2.0), layout_beam_fraction=0.0)
    assert p.dr_action_latency == (10, 10) and p.bounds[0] == pytest.approx(-4.2)
    # The env's queues are as long as the largest latency the ranges allow, never longer.
    env = envs.make(1, dr_action_latency=(1, 3), dr_obs_latency=(0, 2))
    assert (env._action_queue, env._obs_queue) == (3, 2)
    assert (envs.make(1)._action_queue, envs.make(1)._obs_queue) == (0, 0)
