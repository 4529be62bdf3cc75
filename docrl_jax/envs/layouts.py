"""Procedural tanks (scenario 0): an obstacle layout per episode, drawn inside the compiled program.

The scene is `assets/procedural.xml`: the tank's walls, a floor and 24 box and 8 capsule slots. A
`Layout` gives every slot (floor first, then boxes, then capsules) its pose and size, and the regions
where starts and goals are drawn in air and in water; `place` writes
them into the MJX model and data the range sensors cast against, and `solids` gives the same solids to
the hull collision check and to the start/goal sampler, so the sensors, the collisions and the
sampler see one tank. What a layout holds, with the `layout_*` ranges of `EnvParams`:

  * a floor whose top lies in `layout_floor_top` (scenarios 1-2: -1.3 m, 3: -2.0 m); the episode's
    lower bound is the floor + 0.2 m, as in every scenario;
  * `layout_boxes` boxes (in the first 12 box slots), each a post or wall panel standing on the floor (half length 0.15-1.0 m,
    half thickness 0.1-0.3 m, top from 0.6 m under water to above the walls) or, with probability
    `layout_beam_fraction`, a beam (half length 0.8-2.5 m, pitched up to 0.4 rad) at any height;
  * `layout_capsules` capsules (in the first 6 capsule slots), each a riser from the floor (radius 0.2-0.6 m, top from 0.6 m under
    water to above the walls, like scenario 2's) or a bar (radius 0.1-0.25 m, half length 0.8-2.3 m,
    tilted 45-90 degrees from vertical, like scenario 3's) at any height;
  * every centre uniform over the tank (|x|, |y| <= 4.3 m), every yaw uniform;
  * two points kept clear: one in air, one in water (or, for `reset_to`, the given start and goal).
    Every obstacle nearer than `goal_clearance` to them is removed, so an episode always has a free
    start and goal (the sampler's fallback);
  * start and goal regions: the whole tank inside the walls' margin, `air_z_range` in air and the water
    band above the floor in water (a structured layout, docrl_jax/envs/structures.py, or a tank file,
    docrl_jax/envs/tanks.py, narrows them).

The slots past the random obstacles' (12 boxes, 6 capsules) stay parked here; structures and tank files
fill them. The random draws are those of a 12 + 6 slot scene, so layout `i` is the same as before the
scene had more slots.

Layouts are numbered: layout `i` is `generate(layout_key(i), p)`, the same on every machine. Ids
`0 .. HELD_OUT_IDS - 1` are the held-out set (the robustness benchmark's); training draws its ids from
`HELD_OUT_IDS .. 2**31 - 2`, so a held-out layout is never trained on.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct

from docrl_jax.envs import geometry
from docrl_jax.envs.params import BOX_SLOTS, CAPSULE_SLOTS, RANDOM_BOXES, RANDOM_CAPSULES, EnvParams
from docrl_jax.resources import resource_dir

SCENE = "procedural.xml"
HELD_OUT_IDS = 10_000
_ROOT_SEED = 0x6C61796F  # the layouts' own PRNG root ("layo"), apart from every training seed
SLOT_NAMES = (("floor",) + tuple(f"slot_box_{i}" for i in range(BOX_SLOTS))
              + tuple(f"slot_capsule_{i}" for i in range(CAPSULE_SLOTS)))
_FLOOR = slice(0, 1)                       # the floor is a box
_OBSTACLE_BOXES = slice(1, 1 + BOX_SLOTS)
_CAPSULES = slice(1 + BOX_SLOTS, None)
_PARKED = np.array([0.0, 0.0, -50.0], np.float32)  # an unused slot: below the floor, out of every beam's reach
_HALF_SPAN = 4.3                                    # obstacle centres: |x|, |y| <= this


@struct.dataclass
class Layout:
    pos: jax.Array     # (S, 3) slot centres, world frame (S = 1 floor + 12 boxes + 6 capsules)
    rot: jax.Array     # (S, 3, 3) local -> world
    size: jax.Array    # (S, 3) MuJoCo geom_size: box half extents; capsule (radius, half length, 0)
    z_min: jax.Array   # () the episode's lower vertical bound: floor top + 0.2
    clear: jax.Array   # (2, 3) points kept clear of every obstacle: [air, water]
    index: jax.Array   # () int32 layout id (-1: generated from a key that is no id's); a tank set's: its tank
    regions: jax.Array  # (2, 2, 3) where starts and goals are drawn: [air, water] x [low corner, high corner]


def layout_key(index) -> jax.Array:
    """The PRNG key of layout `index` (module doc)."""
    return jax.random.fold_in(jax.random.PRNGKey(_ROOT_SEED), index)


def held_out(index, p: EnvParams) -> Layout:
    """Held-out layout `index` (0 <= index < HELD_OUT_IDS) for the parameters' `layout_*` ranges."""
    return generate(layout_key(index), p).replace(index=jnp.asarray(index, jnp.int32))


def draw(key: jax.Array, p: EnvParams) -> Layout:
    """A layout for a new episode: a random training id, or a random held-out id with
    `p.layout_held_out`."""
    lo, hi = (0, HELD_OUT_IDS) if p.layout_held_out else (HELD_OUT_IDS, 2**31 - 1)
    index = jax.random.randint(key, (), lo, hi)
    return generate(layout_key(index), p).replace(index=index)


def _rot_z(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(angle), jnp.ones_like(angle)
    return jnp.stack([jnp.stack([c, -s, zero], -1), jnp.stack([s, c, zero], -1),
                      jnp.stack([zero, zero, one], -1)], -2)


def _rot_y(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(angle), jnp.ones_like(angle)
    return jnp.stack([jnp.stack([c, zero, s], -1), jnp.stack([zero, one, zero], -1),
                      jnp.stack([-s, zero, c], -1)], -2)


def capsule_frame(axis):
    """A rotation whose local z (a capsule's axis) lies along `axis` (..., 3): yaw about z, then tilt
    about y, as the random bars are posed; the one frame tank files and structures build capsules in."""
    axis = axis / jnp.linalg.norm(axis, axis=-1, keepdims=True)
    return _rot_z(jnp.arctan2(axis[..., 1], axis[..., 0])) @ _rot_y(jnp.arccos(jnp.clip(axis[..., 2], -1.0, 1.0)))


def _slot_draws(key, n: int, p: EnvParams, draws: int):
    """What every slot kind draws alike: `draws` keys, U(lo, hi) over the n slots, centres (n, 2) over
    the tank, and which slots are beams (probability `layout_beam_fraction`)."""
    k = jax.random.split(key, draws)
    u = lambda kk, lo, hi: jax.random.uniform(kk, (n,), minval=lo, maxval=hi)  # noqa: E731
    xy = jax.random.uniform(k[0], (n, 2), minval=-_HALF_SPAN, maxval=_HALF_SPAN)
    return k, u, xy, jax.random.uniform(k[1], (n,)) < p.layout_beam_fraction


def _boxes(key, p: EnvParams, floor_top, z_min):
    """Poses and sizes of every random box slot (used or not): posts/panels on the floor, or beams."""
    k, u, xy, beam = _slot_draws(key, RANDOM_BOXES, p, 9)
    half_thick = u(k[2], 0.1, 0.3)
    # Standing: from inside the floor up to a top between 0.6 m under water and above the walls.
    bottom, top = floor_top - 0.1, u(k[3], -0.6, 5.4)
    standing = jnp.stack([u(k[4], 0.15, 1.0), half_thick, (top - bottom) / 2], -1)
    # Beam: long axis horizontal (local x), pitched a little, at any height above the lower bound.
    beam_size = jnp.stack([u(k[5], 0.8, 2.5), half_thick, u(k[6], 0.1, 0.3)], -1)
    z = jnp.where(beam, u(k[7], z_min + 0.3, 4.4), (top + bottom) / 2)
    pitch = jnp.where(beam, u(k[8], -0.4, 0.4), 0.0)
    rot = _rot_z(u(jax.random.fold_in(key, 1), -jnp.pi, jnp.pi)) @ _rot_y(pitch)
    size = jnp.where(beam[:, None], beam_size, standing)
    return jnp.concatenate([xy, z[:, None]], -1), rot, size


def _capsules(key, p: EnvParams, floor_top, z_min):
    """Poses and sizes of every random capsule slot: risers on the floor, or tilted bars."""
    n = RANDOM_CAPSULES
    k, u, xy, bar = _slot_draws(key, n, p, 8)
    # Riser: vertical segment from just inside the floor to a top between 0.6 m under water and 6 m.
    seg_lo, seg_hi = floor_top - 0.05, u(k[2], -0.6, 6.0)
    riser = jnp.stack([u(k[3], 0.2, 0.6), (seg_hi - seg_lo) / 2, jnp.zeros(n)], -1)
    bar_size = jnp.stack([u(k[4], 0.1, 0.25), u(k[5], 0.8, 2.3), jnp.zeros(n)], -1)
    z = jnp.where(bar, u(k[6], z_min + 0.3, 4.4), (seg_lo + seg_hi) / 2)
    tilt = jnp.where(bar, u(k[7], jnp.pi / 4, jnp.pi / 2), 0.0)   # of the axis (local z) from vertical
    rot = _rot_z(u(jax.random.fold_in(key, 1), -jnp.pi, jnp.pi)) @ _rot_y(tilt)
    size = jnp.where(bar[:, None], bar_size, riser)
    return jnp.concatenate([xy, z[:, None]], -1), rot, size


def _clear_points(key, p: EnvParams, z_min):
    """A point in air and one in water, inside the walls' margin: kept free by `generate`."""
    k_xy, k_air, k_water = jax.random.split(key, 3)
    half = geometry.TANK_HALF_WIDTH - p.wall_margin
    xy = jax.random.uniform(k_xy, (2, 2), minval=-half, maxval=half)
    air = jax.random.uniform(k_air, (), minval=p.air_z_range[0], maxval=p.air_z_range[1])
    lo, hi = p.water_band(z_min)
    water = jax.random.uniform(k_water, (), minval=jnp.maximum(lo, z_min - 0.1), maxval=hi)
    return jnp.concatenate([xy, jnp.stack([air, water])[:, None]], -1)


def generate(key: jax.Array, p: EnvParams, clear=None) -> Layout:
    """A layout drawn from `key` within the `layout_*` ranges of `p` (module doc). `clear` (2, 3):
    points to keep free instead of a drawn air and water point (e.g. a given start and goal)."""
    k_floor, k_boxes, k_caps, k_nb, k_nc, k_clear = jax.random.split(key, 6)
    floor_top = jax.random.uniform(k_floor, (), minval=p.layout_floor_top[0], maxval=p.layout_floor_top[1])
    z_min = floor_top + 0.2
    box_pos, box_rot, box_size = _boxes(k_boxes, p, floor_top, z_min)
    cap_pos, cap_rot, cap_size = _capsules(k_caps, p, floor_top, z_min)
    clear = _clear_points(k_clear, p, z_min) if clear is None else jnp.asarray(clear, jnp.float32)

    used_box = jnp.arange(RANDOM_BOXES) < jax.random.randint(k_nb, (), p.layout_boxes[0], p.layout_boxes[1] + 1)
    used_cap = jnp.arange(RANDOM_CAPSULES) < jax.random.randint(k_nc, (), p.layout_capsules[0],
                                                                 p.layout_capsules[1] + 1)
    candidates = _solids(box_pos, box_rot, box_size, cap_pos, cap_rot, cap_size)
    near = lambda dist: jnp.min(jax.vmap(lambda c: dist(candidates, c))(clear), 0) < p.goal_clearance  # noqa: E731
    used_box &= ~near(geometry.box_distances)
    used_cap &= ~near(geometry.capsule_distances)

    floor = (jnp.array([[0.0, 0.0, 0.0]]).at[0, 2].set(floor_top - 0.1), jnp.eye(3)[None],
             jnp.array([[5.0, 5.0, 0.1]]))
    box_pos = jnp.where(used_box[:, None], box_pos, _PARKED)
    cap_pos = jnp.where(used_cap[:, None], cap_pos, _PARKED)
    box_pos, box_rot, box_size = park_rest(box_pos, box_rot, box_size, BOX_SLOTS)
    cap_pos, cap_rot, cap_size = park_rest(cap_pos, cap_rot, cap_size, CAPSULE_SLOTS)
    return Layout(pos=jnp.concatenate([floor[0], box_pos, cap_pos]).astype(jnp.float32),
                  rot=jnp.concatenate([floor[1], box_rot, cap_rot]).astype(jnp.float32),
                  size=jnp.concatenate([floor[2], box_size, cap_size]).astype(jnp.float32),
                  z_min=z_min, clear=clear, index=jnp.asarray(-1, jnp.int32),
                  regions=default_regions(p, floor_top))


def park_rest(pos, rot, size, slots: int):
    """(pos, rot, size) of n solids padded with parked slots up to `slots`."""
    n = slots - pos.shape[0]
    return (jnp.concatenate([pos, jnp.tile(jnp.asarray(_PARKED), (n, 1))]),
            jnp.concatenate([rot, jnp.tile(jnp.eye(3), (n, 1, 1))]),
            jnp.concatenate([size, jnp.full((n, 3), 0.1)]))


def default_regions(p: EnvParams, floor_top) -> jax.Array:
    """(2, 2, 3) start and goal regions of a tank whose floor top is `floor_top`: the whole tank inside the
    walls' margin, `air_z_range` in air and, in water, the water band above the episode's lower bound
    (never inside the floor)."""
    half = geometry.TANK_HALF_WIDTH - p.wall_margin
    z_min = floor_top + 0.2 if p.z_bounds is None else p.bounds[0]
    w_lo, w_hi = p.water_band(z_min)
    w_lo = jnp.maximum(w_lo, floor_top + 0.1)
    air = jnp.array([[-half, -half, p.air_z_range[0]], [half, half, p.air_z_range[1]]], jnp.float32)
    water = jnp.stack([jnp.array([-half, -half, 0.0]).at[2].set(w_lo),
                       jnp.array([half, half, 0.0]).at[2].set(w_hi)]).astype(jnp.float32)
    return jnp.stack([air, water])


def _solids(box_pos, box_rot, box_size, cap_pos, cap_rot, cap_size) -> geometry.Solids:
    axis = cap_rot[:, :, 2] * cap_size[:, 1:2]
    return geometry.Solids(box_pos=box_pos, box_rot=box_rot, box_half=box_size,
                           cap_a=cap_pos - axis, cap_b=cap_pos + axis, cap_radius=cap_size[:, 0])


def floor_top(layout: Layout) -> jax.Array:
    """Height (m) of the layout's floor top."""
    return layout.pos[0, 2] + layout.size[0, 2]


def obstacles(layout: Layout) -> geometry.Solids:
    """The layout's obstacles (no floor, no walls): what starts and goals keep clear of."""
    b, c = _OBSTACLE_BOXES, _CAPSULES
    return _solids(layout.pos[b], layout.rot[b], layout.size[b], layout.pos[c], layout.rot[c], layout.size[c])


def boundary(layout: Layout, walls: geometry.Solids) -> geometry.Solids:
    """The episode's walls and floor: with `obstacles`, every solid the hull must not touch."""
    b, none = _FLOOR, slice(0, 0)
    return geometry.concat(walls, _solids(layout.pos[b], layout.rot[b], layout.size[b], layout.pos[none],
                                          layout.rot[none], layout.size[none]))


def slot_ids(model: mujoco.MjModel) -> np.ndarray:
    """Geom ids of the slots in `SLOT_NAMES` order."""
    return np.array([model.geom(name).id for name in SLOT_NAMES], np.int32)


def place(mjx_model, data, layout: Layout, ids: np.ndarray):
    """(model, data) with the slots posed and sized as `layout`: what `mjx.ray` reads (geom_size from
    the model; geom_xpos, geom_xmat from the data). MuJoCo's kinematics would put the slots back at
    the MJCF's poses, so this is applied to the copy the sensors cast against, after the physics."""
    model = mjx_model.replace(geom_size=mjx_model.geom_size.at[ids].set(layout.size))
    data = data.replace(geom_xpos=data.geom_xpos.at[ids].set(layout.pos),
                        geom_xmat=data.geom_xmat.at[ids].set(layout.rot))
    return model, data


def mj_model(layout: Layout) -> mujoco.MjModel:
    """A MuJoCo model of the procedural scene (assets/procedural.xml) with one (unbatched) layout compiled in:
    `mujoco.mj_ray` and the renderer then see the tank the env's sensors see (compiled, so MuJoCo's
    own bounding volumes match the new sizes)."""
    spec = mujoco.MjSpec.from_file(str(resource_dir("assets") / SCENE))
    pos, rot, size = (np.asarray(x, np.float64) for x in (layout.pos, layout.rot, layout.size))
    for i, name in enumerate(SLOT_NAMES):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rot[i].reshape(9))
        geom = spec.geom(name)
        geom.pos, geom.quat, geom.size = pos[i], quat, size[i]
    return spec.compile()
