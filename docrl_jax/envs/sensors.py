"""Range sensors: a 20-beam LIDAR fan in air, a 20-beam sonar fan underwater, cast with `mjx.ray`.

Beams leave the vehicle's centre in the body x-y plane (they tilt with the body) and see the group-1
geoms (walls, floor, obstacles), never the water surface or the vehicle. The medium decides the fan:
the vehicle's centre below z = 0 selects the sonar (orig 3.3, a hard switch). Only the active fan is
cast: 20 rays per control step, the same count in both media, so one vmapped `mjx.ray` serves both.

With `vertical_beams` two more beams of the active sensor point along body +z and -z, and with
`slant_beams` two rings of beams slant above and below the body plane; they see what the fans see
(`extra_directions`).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs._quiet_import import mjx  # mujoco.mjx, without its notice about the optional Warp backend
from docrl_jax.envs.params import EnvParams

NUM_BEAMS = 20  # per fan; `cast` returns the `extra_directions` beams after them
RAY_GEOMGROUP = (0, 1, 0, 0, 0, 0)  # only group 1 (assets/common.xml)
VERTICAL_DIRECTIONS = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], np.float32)  # vertical_beams: body +z, -z


def beam_angles(fov_deg: float) -> np.ndarray:
    """Bearings (rad) from body x, evenly spaced over the fan, ends included (as Gazebo does)."""
    return np.deg2rad(np.linspace(-fov_deg / 2.0, fov_deg / 2.0, NUM_BEAMS)).astype(np.float32)


def extra_directions(p: EnvParams) -> np.ndarray:
    """Body-frame unit directions (k, 3) of the beams after the fan: body +z and -z with
    vertical_beams, then the upper and the lower slant_beams ring, each from bearing 0 (body x)
    counter-clockwise."""
    parts = [VERTICAL_DIRECTIONS] if p.vertical_beams else []
    if p.slant_beams:
        bearing = 2.0 * np.pi * np.arange(p.slant_beams) / p.slant_beams
        elev = np.deg2rad(p.slant_elevation_deg)
        for sign in (1.0, -1.0):
            parts.append(np.stack([np.cos(elev) * np.cos(bearing), np.cos(elev) * np.sin(bearing),
                                   np.full_like(bearing, sign * np.sin(elev))], -1))
    return np.concatenate(parts).astype(np.float32) if parts else np.zeros((0, 3), np.float32)


def beam_directions(p: EnvParams, rot: jnp.ndarray, underwater: jnp.ndarray) -> jnp.ndarray:
    """World-frame unit directions (20 + k, 3): the active fan, then `extra_directions`."""
    angles = jnp.where(underwater, beam_angles(p.sonar_fov_deg), beam_angles(p.lidar_fov_deg))
    local = jnp.stack([jnp.cos(angles), jnp.sin(angles), jnp.zeros_like(angles)], -1)
    local = jnp.concatenate([local, extra_directions(p)])
    return local @ rot.T


def max_range(p: EnvParams, underwater: jnp.ndarray) -> jnp.ndarray:
    return jnp.where(underwater, p.sonar_max_range, p.lidar_max_range)


def cast(p: EnvParams, model: mjx.Model, data: mjx.Data, vehicle_body: int, position, rot, underwater):
    """Noise-free ranges (20 + k,) in metres, the fan first, then the k `extra_directions`; a beam that
    hits nothing within range reads the maximum."""
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
