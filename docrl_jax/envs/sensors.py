"""Range sensors: a 20-beam LIDAR fan in air, a 20-beam sonar fan underwater, cast with `mjx.ray`.

Beams leave the vehicle's centre in the body x-y plane (they tilt with the body) and see the group-1
geoms (walls, floor, obstacles), never the water surface or the vehicle. The medium decides the fan:
the vehicle's centre below z = 0 selects the sonar (orig 3.3, a hard switch). Only the active fan is
cast: 20 rays per control step, the same count in both media, so one vmapped `mjx.ray` serves both.

With `vertical_beams` two more beams of the active sensor point along body +z and -z and see what the
fans see.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs._quiet_import import mjx  # mujoco.mjx, without its notice about the optional Warp backend
from docrl_jax.envs.params import EnvParams

NUM_BEAMS = 20  # per fan; with vertical_beams `cast` returns two more ranges after them
RAY_GEOMGROUP = (0, 1, 0, 0, 0, 0)  # only group 1 (assets/common.xml)
VERTICAL_DIRECTIONS = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], np.float32)  # vertical_beams: body +z, -z


def beam_angles(fov_deg: float) -> np.ndarray:
    """Bearings (rad) from body x, evenly spaced over the fan, ends included (as Gazebo does)."""
    return np.deg2rad(np.linspace(-fov_deg / 2.0, fov_deg / 2.0, NUM_BEAMS)).astype(np.float32)


def beam_directions(p: EnvParams, rot: jnp.ndarray, underwater: jnp.ndarray) -> jnp.ndarray:
    """World-frame unit directions (20, 3) of the active fan, then (with vertical_beams) body +z, -z."""
    angles = jnp.where(underwater, beam_angles(p.sonar_fov_deg), beam_angles(p.lidar_fov_deg))
    local = jnp.stack([jnp.cos(angles), jnp.sin(angles), jnp.zeros_like(angles)], -1)
    if p.vertical_beams:
        local = jnp.concatenate([local, VERTICAL_DIRECTIONS])
    return local @ rot.T


def max_range(p: EnvParams, underwater: jnp.ndarray) -> jnp.ndarray:
    return jnp.where(underwater, p.sonar_max_range, p.lidar_max_range)


def cast(p: EnvParams, model: mjx.Model, data: mjx.Data, vehicle_body: int, position, rot, underwater):
    """Noise-free ranges (20,) in metres, (22,) with vertical_beams (the fan first); a beam that hits
    nothing within range reads the maximum."""
    dirs = beam_directions(p, rot, underwater)
    ray = functools.partial(mjx.ray, model, data, geomgroup=RAY_GEOMGROUP, flg_static=True,
                            bodyexclude=vehicle_body)
    dist, _ = jax.vmap(lambda v: ray(position, v))(dirs)
    limit = max_range(p, underwater)
    return jnp.where(dist < 0.0, limit, jnp.minimum(dist, limit))


def corrupt(p: EnvParams, plant, key: jax.Array, ranges: jnp.ndarray, underwater) -> jnp.ndarray:
    """What the sensor reports: Gaussian range noise of the episode's `plant.noise_std` (kept inside
    [0, max range]) and beam dropouts (a lost return reads the maximum range, probability
    `plant.dropout` per beam and step). Nothing is drawn when the parameters allow neither."""
    limit = max_range(p, underwater)
    if p.sensor_noise_std != 0.0 or p.dr_range_noise_std != (0.0, 0.0):
        noisy = ranges + plant.noise_std * jax.random.normal(key, ranges.shape)
        ranges = jnp.clip(noisy, 0.0, limit)
    if p.dr_beam_dropout != (0.0, 0.0):
        ranges = jnp.where(jax.random.uniform(jax.random.fold_in(key, 1), ranges.shape) < plant.dropout, limit, ranges)
    return ranges
