"""Domain randomisation: the plant (true vehicle, water, wind, sensors, delays) of one episode.

`sample_plant(key, p)` draws every quantity uniformly from its `dr_*` range of `EnvParams` (scales
multiply the nominal value); a range whose ends are equal is not drawn at all, so with the defaults
the plant is exactly the nominal one and the program carries no extra random numbers. The env draws a
plant at every reset, inside the compiled program; the physics runs it while the controller keeps the
nominal model, so a drawn plant is a model mismatch the policy has to cope with.

`nominal_plant(p)` is the plant of the parameters themselves (what the controller believes).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from docrl_jax.envs.params import EnvParams
from docrl_jax.envs.physics import GRAVITY, Plant


def _uniform(key, bounds):
    """U(bounds) as a float32 scalar; the constant itself when both ends are equal (nothing drawn)."""
    lo, hi = bounds
    if lo == hi:
        return jnp.asarray(lo, jnp.float32)
    return jax.random.uniform(key, (), minval=lo, maxval=hi)


def _integer(key, bounds):
    lo, hi = bounds
    if lo == hi:
        return jnp.asarray(lo, jnp.int32)
    return jax.random.randint(key, (), lo, hi + 1)


def sample_plant(key: jax.Array, p: EnvParams) -> Plant:
    """One episode's plant: the nominal values of `p` with each `dr_*` range drawn (module doc)."""
    keys = iter(jax.random.split(key, 15))
    f32 = lambda x: jnp.asarray(x, jnp.float32)  # noqa: E731
    mass = _uniform(next(keys), p.dr_mass_scale)
    volume = _uniform(next(keys), p.dr_hull_volume_scale)
    water_drag = _uniform(next(keys), p.dr_water_drag_scale)
    air_drag = _uniform(next(keys), p.dr_air_drag_scale)
    added = _uniform(next(keys), p.dr_added_mass_scale)
    tau = _uniform(next(keys), p.dr_motor_tau_scale)
    k_current, k_direction = next(keys), next(keys)
    current = f32(p.water_current)
    if p.dr_current_speed != (0.0, 0.0):
        direction = jax.random.normal(k_direction, (3,))
        direction = direction / jnp.maximum(jnp.linalg.norm(direction), 1e-6)
        current = current + _uniform(k_current, p.dr_current_speed) * direction
    return Plant(
        mass_scale=mass,
        buoyancy=volume * (p.water_density * p.hull_volume * GRAVITY),
        added_mass=added * f32(p.added_mass), added_inertia=added * f32(p.added_inertia),
        water_linear_drag=water_drag * f32(p.water_linear_drag),
        water_quadratic_drag=water_drag * f32(p.water_quadratic_drag),
        water_angular_drag=water_drag * f32(p.water_angular_drag),
        air_linear_drag=air_drag * f32(p.air_linear_drag), air_quadratic_drag=air_drag * f32(p.air_quadratic_drag),
        thrust_air=_uniform(next(keys), p.dr_thrust_air_scale) * p.rotor_max_thrust_air,
        thrust_water=_uniform(next(keys), p.dr_thrust_water_scale) * p.rotor_max_thrust_water,
        tau_up=tau * p.rotor_tau_up, tau_down=tau * p.rotor_tau_down,
        moment_constant=f32(p.rotor_moment_constant),
        wind_sigma=_uniform(next(keys), p.dr_wind_scale) * p.wind_sigma,
        current=current,
        noise_std=p.sensor_noise_std + _uniform(next(keys), p.dr_range_noise_std),
        dropout=_uniform(next(keys), p.dr_beam_dropout),
        action_latency=_integer(next(keys), p.dr_action_latency),
        obs_latency=_integer(next(keys), p.dr_obs_latency))


def nominal_plant(p: EnvParams) -> Plant:
    """The plant the parameters describe, with no randomisation (what the controller assumes)."""
    off = {f.name: f.default for f in dataclasses.fields(EnvParams) if f.name.startswith("dr_")}
    return sample_plant(jax.random.PRNGKey(0), dataclasses.replace(p, **off))
