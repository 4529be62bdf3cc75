"""Signed distances to the tank's solids, read from the MJCF model (one source of truth).

MJX contacts are off (they would run the constraint solver every substep, 5x slower per
mjx-notes.md), so collisions are decided here, analytically: the hull is covered by a 3 x 3 grid of
spheres, and the hull touches a solid when a sphere's centre is closer to it than the radius.
Exact per sphere, so a thin obstacle that slips between two range beams is still caught.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from docrl_jax.envs.params import HULL_SPHERE_PITCH, HULL_SPHERE_RADIUS

SOLID_GROUP = 1  # walls, floor and obstacles (assets/common.xml)
TANK_HALF_WIDTH = 4.9  # inner wall faces at x, y = +-4.9 (assets/common.xml; orig 1.2)

# Spheres covering the hull box (params.HULL_SPHERE_*): centres on a 3 x 3 grid in the body x-y plane.
_PITCH = (-HULL_SPHERE_PITCH, 0.0, HULL_SPHERE_PITCH)
HULL_SPHERE_CENTRES = np.array([[x, y, 0.0] for x in _PITCH for y in _PITCH], dtype=np.float32)


class Solids(NamedTuple):
    """Boxes and capsules of one scene (arrays with a leading solid axis; may be empty)."""
    box_pos: jnp.ndarray      # (nb, 3)
    box_rot: jnp.ndarray      # (nb, 3, 3) local -> world
    box_half: jnp.ndarray     # (nb, 3)
    cap_a: jnp.ndarray        # (nc, 3) segment end points
    cap_b: jnp.ndarray        # (nc, 3)
    cap_radius: jnp.ndarray   # (nc,)


SOLID_PARTS = ("obstacles", "boundary", "walls")


def solids_from_model(model: mujoco.MjModel, part: str) -> Solids:
    """Collects the group-1 boxes and capsules of one part of the tank: `obstacles` (neither walls nor
    floor), `boundary` (the walls and the floor) or `walls` (the four walls alone: a procedural tank
    places its floor and obstacles per episode). Walls and floor are the geoms named wall_* / floor."""
    if part not in SOLID_PARTS:
        raise ValueError(f"part={part!r}: valid parts are {', '.join(SOLID_PARTS)}")
    keep = {"obstacles": lambda name: not (name.startswith("wall") or name == "floor"),
            "boundary": lambda name: name.startswith("wall") or name == "floor",
            "walls": lambda name: name.startswith("wall")}[part]
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    boxes, caps = [], []
    for g in range(model.ngeom):
        if model.geom_group[g] != SOLID_GROUP or model.geom_bodyid[g] != 0:
            continue
        name = model.geom(g).name
        if not keep(name):
            continue
        pos, rot, size = data.geom_xpos[g].copy(), data.geom_xmat[g].reshape(3, 3).copy(), model.geom_size[g]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            boxes.append((pos, rot, size.copy()))
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = rot[:, 2] * size[1]
            caps.append((pos - axis, pos + axis, size[0]))
        else:
            raise ValueError(f"geom {name!r}: only boxes and capsules are supported as solids "
                             "(mjx.ray misses cylinders)")
    f32 = lambda x, shape: jnp.asarray(np.array(x, dtype=np.float32).reshape(shape))
    return Solids(
        box_pos=f32([b[0] for b in boxes], (-1, 3)), box_rot=f32([b[1] for b in boxes], (-1, 3, 3)),
        box_half=f32([b[2] for b in boxes], (-1, 3)),
        cap_a=f32([c[0] for c in caps], (-1, 3)), cap_b=f32([c[1] for c in caps], (-1, 3)),
        cap_radius=f32([c[2] for c in caps], (-1,)))


def concat(*parts: Solids) -> Solids:
    """One `Solids` holding every solid of `parts`."""
    return Solids(*(jnp.concatenate(leaves) for leaves in zip(*parts)))


def box_distances(solids: Solids, p: jnp.ndarray) -> jnp.ndarray:
    """Signed distance (nb,) from point p (3,) to each box."""
    local = jnp.einsum("nji,nj->ni", solids.box_rot, p[None] - solids.box_pos)
    q = jnp.abs(local) - solids.box_half
    return jnp.linalg.norm(jnp.maximum(q, 0.0), axis=-1) + jnp.minimum(jnp.max(q, axis=-1), 0.0)


def capsule_distances(solids: Solids, p: jnp.ndarray) -> jnp.ndarray:
    """Signed distance (nc,) from point p (3,) to each capsule."""
    ab = solids.cap_b - solids.cap_a
    t = jnp.clip(jnp.sum((p[None] - solids.cap_a) * ab, -1) / jnp.sum(ab * ab, -1), 0.0, 1.0)
    closest = solids.cap_a + t[:, None] * ab
    return jnp.linalg.norm(p[None] - closest, axis=-1) - solids.cap_radius


def signed_distance(solids: Solids, p: jnp.ndarray) -> jnp.ndarray:
    """Smallest signed distance from point p (3,) to any solid; +inf when there is none."""
    d = jnp.inf
    if solids.box_pos.shape[0]:
        d = jnp.minimum(d, jnp.min(box_distances(solids, p)))
    if solids.cap_a.shape[0]:
        d = jnp.minimum(d, jnp.min(capsule_distances(solids, p)))
    return jnp.asarray(d, jnp.float32)


def hull_clearance(solids: Solids, position: jnp.ndarray, rot: jnp.ndarray) -> jnp.ndarray:
    """Gap (m) between the hull (sphere cover) and the nearest solid; negative means touching."""
    centres = position[None] + jnp.asarray(HULL_SPHERE_CENTRES) @ rot.T
    return jnp.min(jax.vmap(lambda c: signed_distance(solids, c))(centres)) - HULL_SPHERE_RADIUS
