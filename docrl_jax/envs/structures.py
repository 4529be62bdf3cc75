"""Structured tanks: what a person builds into a tank (a wall across it with one opening, a ceiling with one
way down, a room with a door, a dead end, a grove of posts, pipes), drawn inside the compiled program (pure
JAX, jit- and vmap-safe, fixed shapes), for training (`draw`, a level pool) and a held-out set
(`held_out_set`). The families themselves are docrl_jax/envs/structure_families.py.

A structured layout (`generate`) is
  * today's random obstacles (`layouts.generate`, with `RANDOM_SHARE` of the `layout_boxes` and
    `layout_capsules` counts) in the first 12 box and 6 capsule slots, and its floor;
  * one primary structure (`FAMILIES`, drawn with `FAMILY_WEIGHTS`) in box slots 12..23 (a grove) or
    12..17 (the others) and, for pipes, capsule slots 6..7, turned by a multiple of 90 degrees about z;
  * perhaps a second one: a small grove (2 x 3 posts, box slots 18..23, probability 0.25 where the primary
    leaves them free) and/or pipes (capsule slots 6..7, probability 0.5 where free, not under a ceiling:
    in the thin water below a slab, pipes cut the layer in two), anywhere in the tank;
  * the start and goal regions of the primary, so that an air-to-water trip (A-W) and the reverse must
    deal with it: either side of a wall, a grove, pipes or a dead end; above and below a ceiling; inside and
    in front of a room;
  * a route kept clear: a clear point in each region (`Layout.clear`, the env's fallback start or goal), the
    two points on either side of the structure's way through (`Part.via`), and the polyline through the
    four. Every random obstacle and second structure's solid nearer than `ROUTE_CLEARANCE` to the route
    (goal_clearance at the clear points) is parked, so the way through stays open, and so is every one
    reaching into the primary's `keep_out` box (the water under a ceiling, where they could wall off a
    pocket).

Ids: structured layout `i` is `generate(structured_key(i), p)`, the same on every machine. Ids
0 .. HELD_OUT_IDS - 1 are held out (`held_out`, `held_out_set`); `draw` takes training ids from
HELD_OUT_IDS .. 2**31 - 2 (held-out ones with p.layout_held_out). A structured layout's `index` is
`-2 - i` (`index_of`), so it never meets a plain layout's (0 .. 2**31 - 2) or -1 (no id);
`structured_id(index)` reads `i` back.

`python -m docrl_jax.envs.structures` prints the share of held-out ids 0..255 flyable both ways
(docrl_jax/envs/flyability.py), the median route length over straight line per family and the cost of
`generate` vmapped over 1,024 keys. On the development CPU (2 shared cores, busy): 256 of 256 flyable; route
/ straight line A-W (W-A) wall 1.22 (1.27), ceiling 1.76 (2.09), room 1.12 (1.18), dead end 1.30 (1.32),
grove 1.10 (1.09), pipes 1.08 (1.09); 1,024 layouts in 171 ms after a 37 s compile (`layouts.generate`
alone: 8 ms): every family is computed for every layout, then one is picked.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs import flyability, geometry, layouts
from docrl_jax.envs import structure_families as fam
from docrl_jax.envs.params import BOX_SLOTS, RANDOM_BOXES, RANDOM_CAPSULES, EnvParams, make_params

STRUCTURED_SALT = 0x73747275   # the structured layouts' own PRNG root ("stru"), apart from layouts'
HELD_OUT_IDS = layouts.HELD_OUT_IDS
INDEX_BASE = -2                 # a structured layout's index is INDEX_BASE - id
FAMILIES = tuple(fam.FAMILIES)
FAMILY_WEIGHTS = (0.25, 0.2, 0.15, 0.15, 0.15, 0.1)   # wall, ceiling, room, dead end, grove, pipes
CEILING, GROVE, PIPES = (FAMILIES.index(name) for name in ("ceiling", "grove", "pipes"))
RANDOM_SHARE = 0.5              # of the random obstacle counts that stay beside a structure
ROUTE_CLEARANCE = 0.9           # m kept free of random obstacles around the route (flyability's cells: 0.55)
_SAMPLES = 16                   # route points per segment (0.6 m apart at most)
_CANDIDATES = 16                # clear-point candidates per region (the farthest from the structure wins)
_SECOND_GROVE, _SECOND_PIPES = 0.25, 0.5


def structured_key(i) -> jax.Array:
    """The PRNG key of structured layout `i`."""
    return jax.random.fold_in(jax.random.PRNGKey(STRUCTURED_SALT), i)


def index_of(i) -> jax.Array:
    """`Layout.index` of structured layout `i` (module doc)."""
    return (INDEX_BASE - jnp.asarray(i)).astype(jnp.int32)


def structured_id(index) -> jax.Array:
    """The structured id of a layout's `index` (meaningful where `is_structured(index)`)."""
    return INDEX_BASE - jnp.asarray(index)


def is_structured(index) -> jax.Array:
    return jnp.asarray(index) <= INDEX_BASE


def held_out(i, p: EnvParams) -> layouts.Layout:
    """Held-out structured layout `i` (0 <= i < HELD_OUT_IDS)."""
    return generate(structured_key(i), p).replace(index=index_of(i))


def draw(key: jax.Array, p: EnvParams) -> layouts.Layout:
    """A layout for a new episode: with probability p.layout_structures a structured layout of a random
    training id (held-out id with p.layout_held_out), else `layouts.draw`."""
    k_pick, k_id, k_plain = jax.random.split(key, 3)
    lo, hi = (0, HELD_OUT_IDS) if p.layout_held_out else (HELD_OUT_IDS, 2**31 - 1)
    i = jax.random.randint(k_id, (), lo, hi)
    structured = jax.random.uniform(k_pick) < p.layout_structures
    return jax.lax.cond(structured, lambda: held_out(i, p), lambda: layouts.draw(k_plain, p))


def family(key: jax.Array) -> jax.Array:
    """int32 () index in FAMILIES of the primary structure `generate(key, ...)` builds."""
    return jax.random.choice(_keys(key)[0], len(FAMILIES), p=jnp.asarray(FAMILY_WEIGHTS)).astype(jnp.int32)


def _keys(key):
    return jax.random.split(key, 7)   # family, turn, primary, second, choice of second, obstacles, clear


def _tank(p: EnvParams, floor_top) -> fam.Tank:
    regions = layouts.default_regions(p, floor_top)
    return fam.Tank(floor=floor_top, air=regions[0, :, 2], water=regions[1, :, 2], clearance=p.goal_clearance,
                    fly=flyability.clearance(p), half=geometry.TANK_HALF_WIDTH - p.wall_margin)


def _turn(part: fam.Part, k) -> fam.Part:
    """`part` turned by k quarter turns about z (exact: the matrices hold 0 and +-1)."""
    c, s = jnp.array([1, 0, -1, 0], jnp.float32)[k], jnp.array([0, 1, 0, -1], jnp.float32)[k]
    r = jnp.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    move = lambda x: x @ r.T  # noqa: E731

    def corners(lo, hi):   # x and y re-sorted, z kept (an empty box stays empty)
        a, b = move(lo), move(hi)
        return (jnp.minimum(a, b).at[..., 2].set(lo[..., 2]), jnp.maximum(a, b).at[..., 2].set(hi[..., 2]))

    lo, hi = corners(part.lo, part.hi)
    reg_lo, reg_hi = corners(part.regions[:, 0], part.regions[:, 1])
    keep_lo, keep_hi = corners(part.keep_out[0], part.keep_out[1])
    return part._replace(lo=lo, hi=hi, cap_a=move(part.cap_a), cap_b=move(part.cap_b),
                         regions=jnp.stack([reg_lo, reg_hi], 1), via=move(part.via),
                         keep_out=jnp.stack([keep_lo, keep_hi]))


def _solids(part: fam.Part) -> geometry.Solids:
    """The part's solids, unused ones included (the caller masks them)."""
    n = part.lo.shape[0]
    return geometry.Solids(box_pos=(part.lo + part.hi) / 2, box_rot=jnp.tile(jnp.eye(3), (n, 1, 1)),
                           box_half=(part.hi - part.lo) / 2, cap_a=part.cap_a, cap_b=part.cap_b,
                           cap_radius=part.cap_r)


def _gap(part: fam.Part, point) -> jax.Array:
    """Distance from `point` to the part's used solids (inf if none)."""
    s = _solids(part)
    return jnp.minimum(jnp.min(jnp.where(part.used, geometry.box_distances(s, point), jnp.inf)),
                       jnp.min(jnp.where(part.cap_used, geometry.capsule_distances(s, point), jnp.inf)))


def _clear_point(key, region, part: fam.Part):
    """Of `_CANDIDATES` uniform points in `region` (2, 3), the one farthest from the part's solids."""
    cand = jax.random.uniform(key, (_CANDIDATES, 3), minval=region[0], maxval=region[1])
    return cand[jnp.argmax(jax.vmap(lambda c: _gap(part, c))(cand))]


def _route(clear, via, p: EnvParams):
    """(points (3 * _SAMPLES, 3), radius each) along clear air -> via -> clear water: goal_clearance at the
    clear points, ROUTE_CLEARANCE elsewhere."""
    corners = jnp.stack([clear[0], via[0], via[1], clear[1]])
    t = jnp.linspace(0.0, 1.0, _SAMPLES)[None, :, None]
    points = (corners[:-1, None] + t * (corners[1:] - corners[:-1])[:, None]).reshape(-1, 3)
    ends = jnp.zeros(points.shape[0], bool).at[jnp.array([0, -1])].set(True)
    return points, jnp.where(ends, max(p.goal_clearance, ROUTE_CLEARANCE), ROUTE_CLEARANCE)


def _near(solids: geometry.Solids, points, radius):
    """(boxes near (nb,), capsules near (nc,)): solids closer than `radius` to any route point."""
    box = jax.vmap(lambda c, r: geometry.box_distances(solids, c) < r)(points, radius)
    cap = jax.vmap(lambda c, r: geometry.capsule_distances(solids, c) < r)(points, radius)
    return jnp.any(box, 0), jnp.any(cap, 0)


def _overlaps(solids: geometry.Solids, box):
    """(boxes (nb,), capsules (nc,)): solids whose axis-aligned bounds overlap the box (2, 3) (low, high)."""
    reach = jnp.einsum("nij,nj->ni", jnp.abs(solids.box_rot), solids.box_half)
    cap_lo = jnp.minimum(solids.cap_a, solids.cap_b) - solids.cap_radius[:, None]
    cap_hi = jnp.maximum(solids.cap_a, solids.cap_b) + solids.cap_radius[:, None]
    hit = lambda lo, hi: jnp.all((lo <= box[1]) & (hi >= box[0]), -1)  # noqa: E731
    return hit(solids.box_pos - reach, solids.box_pos + reach), hit(cap_lo, cap_hi)


def _second(key, tk: fam.Tank, primary, p_grove, p_pipes) -> fam.Part:
    """The second structure's part: a 2 x 3 grove in boxes 6..11 and/or pipes, each with its own turn."""
    k_grove, k_pipes, k_turns, k_use = jax.random.split(key, 4)
    turns = jax.random.randint(k_turns, (2,), 0, 4)
    small = _turn(fam.grove(k_grove, tk, nx=2, ny=3), turns[0])
    pipes = _turn(fam.pipes(k_pipes, tk), turns[1])
    use = jax.random.uniform(k_use, (2,))
    take_grove = (use[0] < p_grove) & (primary != GROVE)
    take_pipes = (use[1] < p_pipes) & (primary != PIPES) & (primary != CEILING)   # no maze under a slab
    shift = lambda x: jnp.roll(x, 6, 0)  # noqa: E731   # the small grove's 6 posts into boxes 6..11
    return small._replace(lo=shift(small.lo), hi=shift(small.hi), used=shift(small.used) & take_grove,
                          cap_a=pipes.cap_a, cap_b=pipes.cap_b, cap_r=pipes.cap_r,
                          cap_used=pipes.cap_used & take_pipes)


def generate(key: jax.Array, p: EnvParams, second_odds=(_SECOND_GROVE, _SECOND_PIPES)) -> layouts.Layout:
    """A structured layout drawn from `key` (module doc); `second_odds`: the probabilities of the second
    structure's small grove and pipes. index -1: `held_out` and `draw` set it."""
    k_family, k_turn, k_primary, k_second, _, k_obstacles, k_clear = _keys(key)
    share = lambda lohi: (int(lohi[0] * RANDOM_SHARE), int(round(lohi[1] * RANDOM_SHARE)))  # noqa: E731
    fewer = dataclasses.replace(p, layout_boxes=share(p.layout_boxes), layout_capsules=share(p.layout_capsules))
    base = layouts.generate(k_obstacles, fewer, clear=jnp.full((2, 3), 100.0))   # nothing removed yet
    floor_top = layouts.floor_top(base)
    tk = _tank(p, floor_top)

    f = family(key)
    parts = [make(k_primary, tk) for make in fam.FAMILIES.values()]
    primary = jax.tree.map(lambda *xs: jnp.stack(xs)[f], *parts)
    primary = _turn(primary, jax.random.randint(k_turn, (), 0, 4))
    second = _second(k_second, tk, f, *second_odds)
    k_air, k_water = jax.random.split(k_clear)
    clear = jnp.stack([_clear_point(k_air, primary.regions[0], primary),
                       _clear_point(k_water, primary.regions[1], primary)])
    points, radius = _route(clear, primary.via, p)

    # Random obstacles and the second structure's solids on the route are parked.
    rb, rc = slice(1, 1 + RANDOM_BOXES), slice(1 + BOX_SLOTS, 1 + BOX_SLOTS + RANDOM_CAPSULES)
    near_box, near_cap = _near(layouts.obstacles(base), points, radius)
    inside_box, inside_cap = _overlaps(layouts.obstacles(base), primary.keep_out)
    near_box, near_cap = near_box | inside_box, near_cap | inside_cap
    keep_box = (base.pos[rb, 2] != -50.0) & ~near_box[:RANDOM_BOXES]
    keep_cap = (base.pos[rc, 2] != -50.0) & ~near_cap[:RANDOM_CAPSULES]
    near_second = tuple(a | b for a, b in zip(_near(_solids(second), points, radius),
                                              _overlaps(_solids(second), primary.keep_out)))
    box_used = jnp.where(jnp.arange(fam.BOXES) < 6, primary.used, primary.used | (second.used & ~near_second[0]))
    cap_used = primary.cap_used | (second.cap_used & ~near_second[1])
    pick = lambda a, b: jnp.where((jnp.arange(fam.BOXES) < 6)[:, None] | primary.used[:, None], a, b)  # noqa: E731
    lo, hi = pick(primary.lo, second.lo), pick(primary.hi, second.hi)
    capsule = lambda a, b: jnp.where(primary.cap_used[:, None], a, b)  # noqa: E731
    cap_a, cap_b = capsule(primary.cap_a, second.cap_a), capsule(primary.cap_b, second.cap_b)
    cap_r = jnp.where(primary.cap_used, primary.cap_r, second.cap_r)

    parked = jnp.asarray(layouts.park_rest(jnp.zeros((0, 3)), jnp.zeros((0, 3, 3)), jnp.zeros((0, 3)), 1)[0])
    box_pos = jnp.where(box_used[:, None], (lo + hi) / 2, parked)
    box_size = jnp.where(box_used[:, None], (hi - lo) / 2, 0.1)
    axis = cap_b - cap_a
    length = jnp.linalg.norm(axis, axis=-1)
    cap_pos = jnp.where(cap_used[:, None], (cap_a + cap_b) / 2, parked)
    unit = jnp.where(cap_used[:, None], axis / jnp.maximum(length, 1e-6)[:, None], jnp.array([0.0, 0.0, 1.0]))
    cap_rot = layouts.capsule_frame(unit)
    cap_size = jnp.where(cap_used[:, None], jnp.stack([cap_r, length / 2, jnp.zeros_like(cap_r)], -1), 0.1)

    pos = base.pos.at[rb].set(jnp.where(keep_box[:, None], base.pos[rb], parked))
    pos = pos.at[rc].set(jnp.where(keep_cap[:, None], base.pos[rc], parked))
    sb = slice(1 + RANDOM_BOXES, 1 + BOX_SLOTS)
    sc = slice(1 + BOX_SLOTS + RANDOM_CAPSULES, None)
    pos = pos.at[sb].set(box_pos).at[sc].set(cap_pos)
    rot = base.rot.at[sb].set(jnp.tile(jnp.eye(3), (fam.BOXES, 1, 1))).at[sc].set(cap_rot)
    size = base.size.at[sb].set(box_size).at[sc].set(cap_size)
    return base.replace(pos=pos, rot=rot, size=size, clear=clear, regions=primary.regions)


class StructuresError(ValueError):
    """A request this module cannot serve (the message names the valid choices)."""


class HeldOutSet(NamedTuple):
    """The held-out structured tanks an evaluation flies, with what tables bin them by."""
    layouts: layouts.Layout   # stacked over the set: (n, ...) every field
    ids: np.ndarray           # (n,) int structured ids (Layout.index = index_of(ids))
    family: np.ndarray        # (n,) int index in FAMILIES of each layout's primary structure
    length: np.ndarray        # (n, 2) mean route length (m) of [A-W, W-A] (flyability.check): the difficulty
    straight: np.ndarray      # (n, 2) mean straight-line distance of the same trips (m)


@functools.lru_cache(maxsize=4)
def _programs(p: EnvParams):
    """Compiled (ids -> held-out layouts, layouts -> flyability routes, ids -> families), vmapped."""
    return (jax.jit(jax.vmap(lambda i: held_out(i, p))), jax.jit(jax.vmap(lambda lay: flyability.check(lay, p))),
            jax.jit(jax.vmap(lambda i: family(structured_key(i)))))


def held_out_set(n: int, p: EnvParams, batch: int = 64) -> HeldOutSet:
    """The first `n` held-out ids (0, 1, ...) whose layout `flyability.check` finds flyable both ways, checked
    `batch` ids at a time: the same set on every machine for the same parameters (a layout whose route is
    a float rounding from the check's thresholds could differ between a CPU and a GPU)."""
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= HELD_OUT_IDS:
        raise StructuresError(f"n={n!r}: a held-out set holds 1 .. {HELD_OUT_IDS} layouts")
    make, check, families = _programs(p)
    chunks, count, start = [], 0, 0
    while count < n and start < HELD_OUT_IDS:
        ids = jnp.arange(start, min(start + batch, HELD_OUT_IDS))
        lay = make(ids)
        route, fams = jax.device_get((check(lay), families(ids)))
        ok = np.all(route.flyable, -1)
        chunks.append(jax.tree.map(lambda x: np.asarray(x)[ok], (lay, np.asarray(ids), fams, route)))
        count, start = count + int(ok.sum()), start + batch
    if count < n:
        raise StructuresError(f"n={n}: only {count} of the {HELD_OUT_IDS} held-out ids are flyable")
    lay, ids, fams, route = jax.tree.map(lambda *x: np.concatenate(x)[:n], *chunks)
    return HeldOutSet(layouts=lay, ids=ids, family=fams, length=route.length, straight=route.straight)


def _summary(n: int = 256, keys: int = 1024, repeats: int = 5) -> None:
    """Prints the share of held-out ids 0 .. n - 1 flyable both ways, the median route / straight line per
    family, and the time of `generate` vmapped over `keys` keys (compiled)."""
    import time

    p = make_params(0)
    make, check, families = _programs(p)
    ids = jnp.arange(n)
    route = jax.device_get(check(make(ids)))
    fams, ok = np.asarray(families(ids)), np.all(route.flyable, -1)
    print(f"held-out ids 0..{n - 1}: flyable both ways {ok.mean():.3f} (A-W {route.flyable[:, 0].mean():.3f}, "
          f"W-A {route.flyable[:, 1].mean():.3f})")
    for f, name in enumerate(FAMILIES):
        m = (fams == f) & ok
        ratio = np.median(route.length[m] / route.straight[m], 0) if m.any() else (np.nan, np.nan)
        print(f"  {name:9s} {np.sum(fams == f):4d} ids, flyable {ok[fams == f].mean():.2f}, route / straight "
              f"median A-W {ratio[0]:.2f} W-A {ratio[1]:.2f}, route median {np.median(route.length[m]):.1f} m")
    gen = jax.jit(jax.vmap(lambda k: generate(k, p)))
    batch = jax.random.split(jax.random.PRNGKey(0), keys)
    t0 = time.perf_counter()
    jax.block_until_ready(gen(batch))
    compiled, times = time.perf_counter() - t0, []
    for r in range(repeats):
        batch = jax.random.split(jax.random.PRNGKey(r + 1), keys)
        t0 = time.perf_counter()
        jax.block_until_ready(gen(batch))
        times.append(time.perf_counter() - t0)
    print(f"generate vmapped over {keys} keys: compile+first {compiled:.1f} s, then median "
          f"{np.median(times) * 1e3:.1f} ms (min {min(times) * 1e3:.1f}) on {jax.devices()[0].device_kind}")


if __name__ == "__main__":
    _summary()
