"""The structure families of structured tanks (docrl_jax/envs/structures.py composes them): each draws one
structure a person builds into a tank, in pure JAX with fixed shapes.

Every family draws in a canonical frame where the trip runs along +x: the air region lies on the -x side
(or above) and the water region on the +x side (or below); `structures.generate` then turns the whole part
by a multiple of 90 degrees about z, so every box stays axis-aligned (a box is its low and high corner).
A family returns a `Part`: up to 12 boxes and 2 capsules, the two start and goal regions, and `via`, two
points on either side of the structure's way through (its opening, door, hole, the way around it), free of
the structure's own solids, through which `generate` keeps a route clear of the random obstacles.

Sizes keep what the flyability check needs (docrl_jax/envs/flyability.py): an opening is at least
`MIN_OPENING` = 1.6 m wide and at least 2 `Tank.fly` + 0.3 m high, the space under a ceiling holds a layer of
cells `fly` clear of the floor and `clearance` clear of the slab, and every region keeps `clearance` from
the structure (the env's starts and goals keep goal_clearance from the obstacles). A family may name a
box no random obstacle may reach into (`Part.keep_out`: the water under a ceiling).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from docrl_jax.envs import geometry

T = geometry.TANK_HALF_WIDTH   # inner wall faces at x, y = +-4.9
REACH = 5.0                    # solids reach 0.1 m into the walls: no slit between a structure and a wall
TOP = 5.4                      # the walls' top: a structure "to the top" cannot be flown over (bound 4.8)
MIN_OPENING = 1.6              # m: the narrowest opening a family draws
BOXES, CAPSULES = 12, 2        # per part: the structure slots of the procedural scene
_MIN_SIDE = 0.1                # a box thinner than this (a sliver beside an opening at a wall) is dropped


class Tank(NamedTuple):
    """What the families read of the tank and the parameters."""
    floor: jax.Array     # () floor top, m
    air: jax.Array       # (2,) heights of air starts and goals (p.air_z_range)
    water: jax.Array     # (2,) heights of water starts and goals (the water band above floor + 0.1)
    clearance: float     # p.goal_clearance: regions keep this from the structure
    fly: float           # flyability.clearance(p): what a flyable cell keeps from every solid
    half: float          # 4.9 - p.wall_margin: regions' |x|, |y| limit


class Part(NamedTuple):
    lo: jax.Array        # (12, 3) boxes' low corners
    hi: jax.Array        # (12, 3) high corners
    used: jax.Array      # (12,) bool
    cap_a: jax.Array     # (2, 3) capsule segment ends
    cap_b: jax.Array     # (2, 3)
    cap_r: jax.Array     # (2,) radii
    cap_used: jax.Array  # (2,) bool
    regions: jax.Array   # (2, 2, 3) [air, water] x [low, high corner]
    via: jax.Array       # (2, 3) the way through: the air side's point, then the water side's
    keep_out: jax.Array  # (2, 3) low and high corner of a box no random obstacle may reach into (none: lo > hi)


def _u(x, lo, hi):
    """x (a U(0, 1) sample) mapped onto U(lo, hi). A family draws all its samples in one call: every
    random call is a threefry kernel of its own, and many of them slow the compile by tens of seconds."""
    return lo + (hi - lo) * x


def _kind(x, p0, p1):
    """0, 1 or 2 with probabilities p0, p1 and the rest, from a U(0, 1) sample x."""
    return (x >= p0).astype(jnp.int32) + (x >= p0 + p1).astype(jnp.int32)


def _v(*xs):
    return jnp.stack([jnp.asarray(x, jnp.float32) for x in xs], -1)


def _boxes(boxes, used=None):
    """(lo, hi, used) padded to BOXES from a list of (lo (3,), hi (3,)), or a tuple (lo (n, 3), hi (n, 3));
    clipped to the walls' reach."""
    lo, hi = boxes if isinstance(boxes, tuple) else (jnp.stack([b[i] for b in boxes]) for i in (0, 1))
    lo, hi = (jnp.clip(x, jnp.array([-REACH, -REACH, -10.0]), jnp.array([REACH, REACH, TOP])) for x in (lo, hi))
    ok = jnp.all(hi - lo > _MIN_SIDE, -1) & (True if used is None else used)
    pad = BOXES - lo.shape[0]
    return (jnp.concatenate([lo, jnp.zeros((pad, 3))]), jnp.concatenate([hi, jnp.zeros((pad, 3))]),
            jnp.concatenate([ok, jnp.zeros(pad, bool)]))


def _region(x, y, z):
    """(2, 3) corners of the box x (lo, hi) by y by z."""
    return jnp.stack([_v(x[0], y[0], z[0]), _v(x[1], y[1], z[1])])


def _no_capsules():
    return jnp.zeros((CAPSULES, 3)), jnp.zeros((CAPSULES, 3)), jnp.full(CAPSULES, 0.1), jnp.zeros(CAPSULES, bool)


def _nowhere():
    """A keep-out box holding nothing (lo > hi). Built when called, never at import: the env imports
    this module while tracing, and a module-level jnp array made then would be a tracer of that trace,
    leaked into every later program (JAX then turns all their constants into inputs it never passes)."""
    return jnp.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])


def _part(boxes, regions, via, used=None, capsules=None, keep_out=None):
    keep_out = _nowhere() if keep_out is None else keep_out
    return Part(*_boxes(boxes, used), *(capsules or _no_capsules()), regions=regions, via=via, keep_out=keep_out)


def _sides(tk: Tank, x_air_hi, x_water_lo, y=None):
    """Regions of a structure dividing the tank across x: air at x <= x_air_hi, water at x >= x_water_lo."""
    y = (-tk.half, tk.half) if y is None else y
    return jnp.stack([_region((-tk.half, x_air_hi), y, tk.air), _region((x_water_lo, tk.half), y, tk.water)])


def _min_height(tk: Tank):
    return 2 * tk.fly + 0.3


def wall(key, tk: Tank) -> Part:
    """A wall across the tank at x = x0 with one opening (y centre yo, width w): floor to the top ('full':
    a slot the full height, a door with a lintel, or a window with a sill and a lintel), only in air (a
    curtain from 0-1 m up: the way is under it), or only under water (a weir, top -0.5..1 m: the way is over
    it, or a slot to the floor). Boxes: the panels either side of the opening, the lintel, the sill."""
    k = jax.random.uniform(key, (12,))
    x0, t, w = _u(k[0], -1.5, 1.5), _u(k[1], 0.1, 0.2), _u(k[2], MIN_OPENING, 3.0)
    yo = _u(k[3], -T + w / 2, T - w / 2)
    kind = _kind(k[4], 0.6, 0.2)   # full, curtain, weir
    bottom, hmin = tk.floor - 0.1, _min_height(tk)
    opening = _kind(k[5], 1 / 3, 1 / 3)   # slot, door, window
    door_top = _u(k[6], jnp.maximum(tk.floor + hmin + 0.1, -0.3), 3.5)
    sill = _u(k[7], 0.3, 2.2)
    window_top = jnp.minimum(sill + _u(k[8], hmin, 2.4), 4.6)
    z_lo = jnp.where(opening == 2, sill, bottom)
    z_hi = jnp.select([opening == 0, opening == 1], [jnp.float32(TOP), door_top], window_top)
    wb = jnp.where(kind == 1, _u(k[9], jnp.maximum(0.0, tk.floor + hmin + 0.1), 1.0), bottom)
    wt = jnp.where(kind == 2, _u(k[10], -0.5, 1.0), TOP)
    weir_slot = k[11] < 0.5
    z_lo = jnp.where(kind == 0, z_lo, wb)                      # curtain, weir: closed unless a weir slot
    z_hi = jnp.where(kind == 0, z_hi, jnp.where((kind == 2) & weir_slot, wt, wb))
    zv = jnp.select([kind == 0, kind == 1], [(jnp.maximum(z_lo, tk.floor) + jnp.minimum(z_hi, 4.8)) / 2,
                                             (tk.floor + wb) / 2], wt + 0.9)
    x = (x0 - t, x0 + t)
    boxes = [(_v(x[0], -REACH, wb), _v(x[1], yo - w / 2, wt)), (_v(x[0], yo + w / 2, wb), _v(x[1], REACH, wt)),
             (_v(x[0], yo - w / 2, z_hi), _v(x[1], yo + w / 2, wt)),
             (_v(x[0], yo - w / 2, wb), _v(x[1], yo + w / 2, z_lo))]
    margin = t + tk.clearance + 0.05
    return _part(boxes, _sides(tk, x0 - margin, x0 + margin),
                 jnp.stack([_v(x0 - t - 1.0, yo, zv), _v(x0 + t + 1.0, yo, zv)]))


def ceiling(key, tk: Tank) -> Part:
    """A horizontal slab at height zc, just above the water (0.4-1.2 m) or, where the water is deep enough,
    under it: over the whole tank with one hole (4 boxes around it), or an overhang over x >= xe (the way
    round its edge). Air region above the slab, water region below it."""
    k = jax.random.uniform(key, (12,))
    t = _u(k[0], 0.08, 0.15)
    low = tk.floor + tk.fly + tk.clearance + t + 0.3       # a layer of water cells under the slab
    above_lo = jnp.maximum(0.4, low)
    above = _u(k[1], above_lo, jnp.maximum(above_lo, jnp.minimum(1.2, tk.air[1] - tk.clearance - t - 0.3)))
    under_hi = -t - 0.15
    zc = jnp.where((k[2] < 0.3) & (low < under_hi), _u(k[3], low, under_hi), above)
    overhang = k[4] < 0.4
    wx, wy = _u(k[5], MIN_OPENING, 2.8), _u(k[6], MIN_OPENING, 2.8)
    hx, hy = _u(k[7], -T + wx / 2, T - wx / 2), _u(k[8], -T + wy / 2, T - wy / 2)
    xe = _u(k[9], -2.5, 1.5)
    x0, x1 = jnp.where(overhang, -REACH, hx - wx / 2), jnp.where(overhang, xe, hx + wx / 2)
    y0, y1 = jnp.where(overhang, -REACH, hy - wy / 2), jnp.where(overhang, REACH, hy + wy / 2)
    z = (zc - t, zc + t)
    boxes = [(_v(-REACH, -REACH, z[0]), _v(x0, REACH, z[1])), (_v(x1, -REACH, z[0]), _v(REACH, REACH, z[1])),
             (_v(x0, -REACH, z[0]), _v(x1, y0, z[1])), (_v(x0, y1, z[0]), _v(x1, REACH, z[1]))]
    xr = (jnp.where(overhang, xe + 0.3, -tk.half), tk.half)
    yr = (-tk.half, tk.half)
    margin = t + tk.clearance + 0.05
    regions = jnp.stack([_region(xr, yr, (jnp.maximum(tk.air[0], zc + margin), tk.air[1])),
                         _region(xr, yr, (tk.water[0], jnp.minimum(tk.water[1], zc - margin)))])
    vx = jnp.where(overhang, xe - 1.0, hx)
    vy = jnp.where(overhang, _u(k[10], -tk.half, tk.half), hy)
    via = jnp.stack([_v(vx, vy, zc + t + 0.8), _v(vx, vy, jnp.maximum(zc - t - 0.8, tk.floor + tk.fly))])
    # The water under a slab is a thin layer with a lid: random obstacles standing in it could wall off a
    # pocket of it, so none stays there.
    keep_out = jnp.stack([_v(xr[0], -tk.half, tk.floor), _v(xr[1], tk.half, zc - t)])
    return _part(boxes, regions, via, keep_out=keep_out)


def room(key, tk: Tank) -> Part:
    """A room: interior [x1, x2] x [y1, y2], walls to the top, against the +x wall and/or a y wall or free,
    one door (to the floor, with a lintel or the full height) in its -x wall. One medium's region is inside
    the room (the goal of one trip, the start of the other), the other's in front of the door."""
    k = jax.random.uniform(key, (11,))
    t, x1, depth, wy = _u(k[0], 0.1, 0.2), _u(k[1], -1.5, 0.8), _u(k[2], 3.2, 5.0), _u(k[3], 3.2, 5.0)
    x2 = x1 + depth
    x2 = jnp.where(x2 > T - 1.8 - 2 * t, T, x2)            # no slit behind the room: against the wall
    place = _kind(k[4], 0.3, 0.3)   # against -y, against +y, free
    y_free = _u(k[5], -T + 1.8 + 2 * t, T - 1.8 - 2 * t - wy)
    y1 = jnp.select([place == 0, place == 1], [jnp.float32(-T), T - wy], y_free)
    y2 = y1 + wy
    w = _u(k[6], MIN_OPENING, jnp.minimum(2.4, wy - 0.4))
    yd = _u(k[7], y1 + w / 2, y2 - w / 2)
    zd = jnp.where(k[8] < 0.3, TOP,
                   _u(k[10], jnp.maximum(1.0, tk.floor + _min_height(tk) + 0.1), 3.5))
    bottom = tk.floor - 0.1
    back, low_side, high_side = x2 < T - 0.01, y1 > -T + 0.01, y2 < T - 0.01
    boxes = [(_v(x1 - 2 * t, y1 - 2 * t, bottom), _v(x1, yd - w / 2, TOP)),
             (_v(x1 - 2 * t, yd + w / 2, bottom), _v(x1, y2 + 2 * t, TOP)),
             (_v(x1 - 2 * t, yd - w / 2, zd), _v(x1, yd + w / 2, TOP)),
             (_v(x2, y1 - 2 * t, bottom), _v(x2 + 2 * t, y2 + 2 * t, TOP)),
             (_v(x1 - 2 * t, y1 - 2 * t, bottom), _v(x2 + 2 * t, y1, TOP)),
             (_v(x1 - 2 * t, y2, bottom), _v(x2 + 2 * t, y2 + 2 * t, TOP))]
    used = jnp.array([True, True, True, False, False, False]).at[3:].set(jnp.stack([back, low_side, high_side]))
    m = tk.clearance + 0.05
    inside_xy = ((x1 + m, jnp.where(back, x2 - m, tk.half)),
                 (jnp.where(low_side, y1 + m, -tk.half), jnp.where(high_side, y2 - m, tk.half)))
    outside_xy = ((-tk.half, x1 - 2 * t - m), (-tk.half, tk.half))
    water_inside = k[9] < 0.5
    pick = lambda a, b: tuple(tuple(jnp.where(water_inside, u, v) for u, v in zip(*uv))  # noqa: E731
                              for uv in zip(a, b))
    air_xy, water_xy = pick(outside_xy, inside_xy), pick(inside_xy, outside_xy)
    regions = jnp.stack([_region(*air_xy, tk.air), _region(*water_xy, tk.water)])
    zv = (tk.floor + jnp.minimum(zd, 4.8)) / 2
    out, inside = _v(x1 - 2 * t - 1.0, yd, zv), _v(x1 + 1.0, yd, zv)
    via = jnp.where(water_inside, jnp.stack([out, inside]), jnp.stack([inside, out]))
    return _part(boxes, regions, via, used)


def dead_end(key, tk: Tank) -> Part:
    """A U of walls to the top between the two regions: its back wall at x = xb faces one region, its mouth
    (depth d, inner half width wu, centre y = yc) the other, so a trip from the mouth's side pulled straight
    at its goal flies into the U. The way is round it, past the side with more room."""
    k = jax.random.uniform(key, (6,))
    t, xb, d, wu, yc = (_u(k[0], 0.1, 0.2), _u(k[1], 0.3, 1.8), _u(k[2], 1.8, 3.2), _u(k[3], 0.9, 1.7),
                        _u(k[4], -1.0, 1.0))
    bottom = tk.floor - 0.1
    outer = (yc - wu - 2 * t, yc + wu + 2 * t)
    boxes = [(_v(xb, outer[0], bottom), _v(xb + 2 * t, outer[1], TOP)),
             (_v(xb - d, outer[0], bottom), _v(xb, yc - wu, TOP)),
             (_v(xb - d, yc + wu, bottom), _v(xb, outer[1], TOP))]
    clip = lambda a, b: (jnp.maximum(a, -tk.half), jnp.minimum(b, tk.half))  # noqa: E731
    mouth_xy = ((-tk.half, xb - d - 0.2), clip(yc - wu, yc + wu))
    back_xy = ((xb + 2 * t + tk.clearance + 0.05, tk.half), clip(*outer))
    air_at_mouth = k[5] < 0.5
    sel = lambda a, b: tuple(tuple(jnp.where(air_at_mouth, u, v) for u, v in zip(*uv))  # noqa: E731
                             for uv in zip(a, b))
    regions = jnp.stack([_region(*sel(mouth_xy, back_xy), tk.air), _region(*sel(back_xy, mouth_xy), tk.water)])
    ys = jnp.where(T - outer[1] >= outer[0] + T, (outer[1] + T) / 2, (outer[0] - T) / 2)
    front, behind = _v(xb - d - 1.0, ys, 1.0), _v(xb + 2 * t + 1.0, ys, 1.0)
    via = jnp.where(air_at_mouth, jnp.stack([front, behind]), jnp.stack([behind, front]))
    return _part(boxes, regions, via)


def grove(key, tk: Tank, nx: int = 3, ny: int = 4) -> Part:
    """A grove: nx x ny square posts (half width a) on a jittered lattice (spacing sx along the trip, sy
    across), full height, low (top -0.5..1 m) or hanging (bottom 0-1.5 m up). Where the lattice leaves
    1.9 m beside it on both sides, the way is round it (its gaps may be too narrow to pass); otherwise its
    rows are spread so that the middle gap is passable and the way is through it."""
    k = jax.random.uniform(key, (10 + 2 * nx * ny,))
    post = k[10:].reshape(2, nx * ny)
    sx, sy, a, jit = _u(k[0], 1.2, 2.0), _u(k[1], 1.3, 2.6), _u(k[2], 0.12, 0.3), 0.15
    half_y = lambda s: (ny - 1) / 2 * s + a + jit  # noqa: E731
    around = T - half_y(sy) >= 1.9
    sy = jnp.where(around, sy, jnp.maximum(sy, 2 * a + 2 * jit + 1.7))
    g = jnp.maximum(T - half_y(sy) - 1.9, 0.0)
    gy = jnp.where(around, _u(k[3], -g, g), 0.0)
    half_x = (nx - 1) / 2 * sx + a + jit
    gmax = jnp.maximum(tk.half - 0.6 - half_x - tk.clearance - 0.05, 0.0)
    gx = _u(k[4], -gmax, gmax)
    i, j = jnp.meshgrid(jnp.arange(nx) - (nx - 1) / 2, jnp.arange(ny) - (ny - 1) / 2, indexing="ij")
    cx = gx + i.ravel() * sx + _u(post[0], -jit, jit)
    cy = gy + j.ravel() * sy + _u(post[1], -jit, jit)
    kind = _kind(k[7], 0.6, 0.2)   # full, low, hanging
    zb = jnp.where(kind == 2, _u(k[8], jnp.maximum(0.0, tk.floor + _min_height(tk) + 0.1), 1.5), tk.floor - 0.1)
    zt = jnp.where(kind == 1, _u(k[9], -0.5, 1.0), TOP)
    ones = jnp.ones(nx * ny)
    boxes = (_v(cx - a, cy - a, zb * ones), _v(cx + a, cy + a, zt * ones))
    margin = half_x + tk.clearance + 0.05
    side = jnp.where(gy <= 0, 1.0, -1.0)                  # the side with more room
    ys = jnp.where(around, gy + side * (half_y(sy) + (T - half_y(sy) - side * gy) / 2), gy)
    via = jnp.stack([_v(gx - half_x - 0.9, ys, 1.0), _v(gx + half_x + 0.9, ys, 1.0)])
    return _part(boxes, _sides(tk, gx - margin, gx + margin), via)


def pipes(key, tk: Tank) -> Part:
    """Two horizontal pipes (capsules along y, radius 0.1-0.3 m) at x = xp and xp + 1..2 m, each at the
    water line or at mid-depth, spanning the tank or 4-8 m long; the way is over them."""
    k = jax.random.uniform(key, (9, CAPSULES))
    r = _u(k[0], 0.1, 0.3)
    xp1 = _u(k[1, 0], -1.5, 0.5)
    xp = jnp.stack([xp1, xp1 + _u(k[1, 1], 1.0, 2.0)])
    z = jnp.where(k[2] < 0.5, _u(k[3], -0.2, 0.2), tk.floor / 2 + _u(k[4], -0.15, 0.15))
    hl = jnp.where(k[5] < 0.6, REACH - r, _u(k[6], 2.0, 4.0))
    room = REACH - r - hl
    cy = _u(k[7], -room, room)
    cap_a, cap_b = _v(xp, cy - hl, z), _v(xp, cy + hl, z)
    x_lo, x_hi = jnp.min(xp - r), jnp.max(xp + r)
    yv = _u(k[8, 0], -tk.half, tk.half)
    via = jnp.stack([_v(x_lo - 1.0, yv, 1.5), _v(x_hi + 1.0, yv, 1.5)])
    m = tk.clearance + 0.05
    return _part([(jnp.zeros(3), jnp.zeros(3))], _sides(tk, x_lo - m, x_hi + m), via,
                 capsules=(cap_a, cap_b, r, jnp.ones(CAPSULES, bool)))


FAMILIES = {"wall": wall, "ceiling": ceiling, "room": room, "dead_end": dead_end, "grove": grove, "pipes": pipes}
