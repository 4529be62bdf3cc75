"""Can a tank be flown? An occupancy grid of the tank and a wavefront distance field over it, in pure JAX
(jit- and vmap-safe: a structured-tank generator checks thousands of levels at once on a GPU, the tank-file
loader a few on the CPU).

  * The grid: cells of `GRID_STEP` = 0.25 m, centres on multiples of the step, symmetric about the tank's
    axis and with a layer on the water surface: x, y in -4.75 .. 4.75 (39 each, inside the walls' inner
    faces at +-4.9 by more than half a cell), z in -4.25 .. 4.75 (37: from above the lowest floor top a
    tank may have, -4.4, up to the episode's top bound 4.8). `GRID_SHAPE` = (39, 39, 37).
  * A free cell (`free_cells`): its centre lies within the episode's vertical bounds and at least
    `clearance(p)` from the walls, the floor and every obstacle. Any 26-neighbour move between two free
    cells then stays at least clearance - step * sqrt(3) / 2 (~0.33 m) from every solid (distances are
    1-Lipschitz), so a route never slips through a solid between cells.
  * Start and goal cells (`region_cells`): a region's points are the cell centres inside a layout's air or
    water region (grown by half a cell, so a point region picks its nearest cells) at least `goal_clearance`
    from the obstacles, as the env draws its starts and goals. Its cells are those points that are free
    cells; a region with none (every point nearer the floor than the clearance: a goal 0.3 m above the
    floor, where the paper puts its underwater goals) takes the free cells within the arrival distance
    (`arrival_distance`, 0.5 m) of its points instead: a goal is reached from them, a start climbs to
    them (the route follower rejoins the free cells within 2 cells on each axis, docrl_jax/envs/guidance.py).
    A region with no cells either way fails both trips. A region with free points keeps exactly those.
  * `distance_field`: route length from every free cell to the nearest seed cell over 26-neighbour moves
    (Bellman-Ford sweeps of shifted copies of a padded grid until nothing changes, as JaxUED's maze check
    floods its grid). In open space the 26-neighbour metric overestimates the straight line by up to
    13 % (8 % in an axis plane; nothing along an axis or a diagonal), so `length / straight` of an
    unobstructed trip lies in 1 .. 1.13 plus the cells' spread.
  * `check`: both trips of a layout, A-W (air region to water region) and W-A, as a `Route`.
  * `route_path`: the polyline of one route, steepest descent down a field (docs, a route-following policy).
  * `blockage`: why a trip is not flyable, for a tank file's refusal: the widest way (`widest_field`, the
    most clearance a way keeps) from a cut-off start cell and where it is narrowest.

What a check costs: `python benchmarks/flyability_cost.py`. Vertically the clearance is conservative (`clearance`):
with the default water band a floor at -0.8 m (the highest a tank file may have) leaves no free water
cell (the top one, z = -0.25, is 0.55 m above it, a float's width short), and the water region takes
the surface layer's cells within the arrival distance of it; at -0.9 m it has one layer of its own.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs import geometry, layouts
from docrl_jax.envs.params import EnvParams

GRID_STEP = 0.25                                              # m
GRID_X = np.arange(-19, 20, dtype=np.float32) * GRID_STEP    # cell centres along x (and y), m
GRID_Z = np.arange(-17, 20, dtype=np.float32) * GRID_STEP    # cell centres along z, m
GRID_SHAPE = (GRID_X.size, GRID_X.size, GRID_Z.size)         # (39, 39, 37)
MAX_SWEEPS = 1000                                            # cap of `distance_field`'s wavefront

_ORIGIN = np.array([GRID_X[0], GRID_X[0], GRID_Z[0]], np.float32)
_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                     if (i, j, k) != (0, 0, 0)], np.int32)                   # (26, 3)
_WEIGHTS = (GRID_STEP * np.sqrt(np.abs(_OFFSETS).sum(-1))).astype(np.float32)  # step, step*sqrt2, step*sqrt3
_NO_WALLS = geometry.Solids(*(np.zeros(shape, np.float32) for shape in
                              ((0, 3), (0, 3, 3), (0, 3), (0, 3), (0, 3), (0,))))


class Route(NamedTuple):
    """Both trips of a layout, [A-W, W-A]; A-W starts in the air region and ends in the water region."""
    flyable: jax.Array      # (2,) bool: both regions have cells and every start cell reaches a goal cell
    length: jax.Array       # (2,) mean route length over the start cells, m (inf unless flyable)
    longest: jax.Array      # (2,) the longest of those routes, m (inf unless flyable)
    straight: jax.Array     # (2,) mean straight-line distance from a start cell to its nearest goal cell, m
    #                         (inf when a region has no cells); length / straight is the detour ratio
    start_cells: jax.Array  # (2,) int32 start-region cells (0: none of the region's points that keep
    #                         goal_clearance from the obstacles lies within the arrival distance of a free cell)


def clearance(p: EnvParams) -> float:
    """The distance (m) a free cell keeps from every solid: the evaluation's fan collision distance plus
    5 cm. The fans are horizontal, so vertically this is conservative: the hull itself reaches ~0.05 m
    above and below its centre, yet a cell under a beam or above the floor needs the full clearance."""
    return p.collision_distance + 0.05


def _centres() -> jax.Array:
    """(X, Y, Z, 3) cell centres, built inside the program from the axes (a 56k-cell constant would be
    embedded in, or on newer JAX passed to, every program that checks a level)."""
    x, z = jnp.asarray(GRID_X), jnp.asarray(GRID_Z)
    return jnp.stack(jnp.meshgrid(x, x, z, indexing="ij"), -1)


def _wall_gap(centres: jax.Array) -> jax.Array:
    """Distance (X, Y, Z) from every cell centre to the nearest tank wall."""
    return geometry.TANK_HALF_WIDTH - jnp.maximum(jnp.abs(centres[..., 0]), jnp.abs(centres[..., 1]))


def _gaps_to(solids: geometry.Solids) -> jax.Array:
    """Signed distance (X, Y, Z) from every cell centre to the nearest of `solids`."""
    points = _centres().reshape(-1, 3)
    return jax.vmap(lambda c: geometry.signed_distance(solids, c))(points).reshape(GRID_SHAPE)


def _solid_gaps(layout: layouts.Layout):
    """Signed distances (X, Y, Z) from every cell centre to the nearest obstacle and to the floor."""
    return _gaps_to(layouts.obstacles(layout)), _gaps_to(layouts.boundary(layout, _NO_WALLS))


def _nearest(*gaps) -> jax.Array:
    """Distance (X, Y, Z) from every cell centre to the nearest of the walls and the solids of `gaps`."""
    return functools.reduce(jnp.minimum, gaps, _wall_gap(_centres()))


def _in_bounds(z_min, p: EnvParams) -> jax.Array:
    z = _centres()[..., 2]
    return (z >= z_min) & (z <= p.bounds[1])


def _free_of(gap: jax.Array, z_min, p: EnvParams) -> jax.Array:
    return _in_bounds(z_min, p) & (gap >= clearance(p))


def _free(layout: layouts.Layout, p: EnvParams, obstacle_gap, floor_gap) -> jax.Array:
    return _free_of(_nearest(obstacle_gap, floor_gap), layout.z_min, p)


def _region(layout: layouts.Layout, p: EnvParams, medium, free, obstacle_gap) -> jax.Array:
    """The region's cells (module doc): its free points, else the free cells within the arrival distance of
    its points. Only where it has no free point: added to every region, the arrival cells would shorten the
    gallery's routes by up to 0.3 m and the structured tanks' by up to 0.7 m, and move the route reward."""
    lo, hi = layout.regions[medium, 0], layout.regions[medium, 1]
    c = _centres()
    inside = jnp.all((c >= lo - GRID_STEP / 2) & (c <= hi + GRID_STEP / 2), -1)
    points = inside & (obstacle_gap >= p.goal_clearance)
    own = free & points
    return jnp.where(jnp.any(own), own, free & _near(points, p.arrival_distance))


def _cells(layout: layouts.Layout, p: EnvParams):
    """(every cell's distance to the nearest solid, the free cells, the air and water regions' cells
    stacked (2, X, Y, Z)) of a layout."""
    obstacle_gap, floor_gap = _solid_gaps(layout)
    gap = _nearest(obstacle_gap, floor_gap)
    free = _free_of(gap, layout.z_min, p)
    return gap, free, jnp.stack([_region(layout, p, m, free, obstacle_gap) for m in (0, 1)])


def cell_centres() -> jax.Array:
    """float32 (X, Y, Z, 3): the grid's cell centres (world frame, m)."""
    return _centres()


def cell_gaps(layout: layouts.Layout) -> jax.Array:
    """float32 (X, Y, Z): distance from every cell centre to the nearest solid: walls, floor, obstacles."""
    return _nearest(*_solid_gaps(layout))


def free_cells(layout: layouts.Layout, p: EnvParams) -> jax.Array:
    """bool (X, Y, Z): cells whose centre lies within the episode's vertical bounds (layout.z_min ..
    p.bounds[1]) and at least `clearance(p)` from the walls, the floor and every obstacle."""
    return _free(layout, p, *_solid_gaps(layout))


def tank_cells(obstacles: geometry.Solids, boundary: geometry.Solids, z_min, p: EnvParams):
    """(free cells, cell gaps) of any tank from its solids, as the env's hull check sees them
    (`HUAUVEnv.solids`: a fixed scenario's MJCF geoms, or a procedural layout's): `free_cells` and
    `cell_gaps` of a layout are these with the layout's obstacles, floor and walls."""
    gap = _nearest(_gaps_to(obstacles), _gaps_to(boundary))
    return _free_of(gap, z_min, p), gap


def region_cells(layout: layouts.Layout, p: EnvParams, medium) -> jax.Array:
    """bool (X, Y, Z): the start or goal cells of `layout.regions[medium]` (0 air, 1 water): free cells
    inside the region grown by half a cell on each side, at least `p.goal_clearance` from the obstacles
    (where the env can put a start or a goal); where none is, the free cells within `p.arrival_distance` of
    such points of the region (module doc)."""
    return _cells(layout, p)[2][medium]


def relax(d: jax.Array, cost, start=None) -> jax.Array:
    """One sweep: every cell takes the best of `start` (default: itself) and its 26 neighbours plus the move's
    length (times the cell's cost)."""
    nx, ny, nz = d.shape
    padded = jnp.pad(d, 1, constant_values=jnp.inf)
    best = d if start is None else start
    for (i, j, k), w in zip(_OFFSETS, _WEIGHTS):
        best = jnp.minimum(best, padded[1 + i:1 + i + nx, 1 + j:1 + j + ny, 1 + k:1 + k + nz] + w * cost)
    return best


def distance_field(free: jax.Array, seeds: jax.Array, cost=None) -> jax.Array:
    """float32 (X, Y, Z): route length (m) from every free cell to the nearest free seed cell over
    26-neighbour moves through free cells (move lengths step, step * sqrt2, step * sqrt3); inf where no
    seed is reachable and on every cell that is not free. `cost` (X, Y, Z), >= 1: each move's length is
    multiplied by the cost of the cell it leaves (a route-follower's dislike of cells near solids); the
    field is then the least route cost. Sweeps until nothing changes (at most `MAX_SWEEPS`; a route needs
    one sweep per move, ~100 in this grid)."""
    free = jnp.asarray(free, bool)
    inf = jnp.float32(jnp.inf)
    d0 = jnp.where(free & seeds, jnp.float32(0.0), inf)
    cost = jnp.float32(1.0) if cost is None else cost

    def sweep(state):
        d, _, n = state
        new = jnp.where(free, relax(d, cost), inf)
        return new, jnp.any(new < d), n + 1

    def more(state):
        return state[1] & (state[2] < MAX_SWEEPS)

    d, _, _ = jax.lax.while_loop(more, sweep, (d0, jnp.asarray(True), jnp.asarray(0, jnp.int32)))
    return d


def window_sq_distance(seeds: jax.Array, reach: int) -> jax.Array:
    """float32 (X, Y, Z): squared distance from every cell centre to the nearest seed cell centre, exact where
    that seed lies within `reach` cells along every axis (so for every distance up to `reach` cells), inf where
    none does. The squared distance separates by axis, so each axis takes the shifts up to `reach` only
    (`_straight_line` takes whole axes)."""
    sq = jnp.where(seeds, jnp.float32(0.0), jnp.float32(jnp.inf))
    for axis in range(3):
        pad = [(0, 0)] * 3
        pad[axis] = (reach, reach)
        padded, n = jnp.pad(sq, pad, constant_values=jnp.inf), sq.shape[axis]
        sq = functools.reduce(jnp.minimum, [jax.lax.slice_in_dim(padded, reach + o, reach + o + n, axis=axis)
                                            + jnp.float32((o * GRID_STEP) ** 2) for o in range(-reach, reach + 1)])
    return sq


def _near(seeds: jax.Array, radius: float) -> jax.Array:
    """bool (X, Y, Z): cells whose centre lies within `radius` of a seed cell's centre (5 cells' window at the
    default arrival distance)."""
    reach = int(np.floor(radius / GRID_STEP + 1e-6))
    return window_sq_distance(seeds, reach) <= jnp.float32(radius) ** 2


def _straight_line(seeds: jax.Array) -> jax.Array:
    """float32 (X, Y, Z): Euclidean distance from every cell centre to the nearest seed cell centre; exact,
    as three 1-D passes of the squared distance (it separates by axis)."""
    sq = jnp.where(seeds, jnp.float32(0.0), jnp.float32(jnp.inf))
    for axis, coords in enumerate((GRID_X, GRID_X, GRID_Z)):
        gap2 = jnp.asarray((coords[:, None] - coords[None, :]) ** 2)          # (to, from)
        moved = jnp.moveaxis(sq, axis, -1)
        sq = jnp.moveaxis(jnp.min(moved[..., None, :] + gap2, -1), -1, axis)
    return jnp.sqrt(sq)


def check(layout: layouts.Layout, p: EnvParams) -> Route:
    """Both trips of `layout` (module doc): a wavefront from the water cells (A-W) and one from the air
    cells (W-A), read at the other region's cells."""
    return check_with_fields(layout, p)[0]


def nearest_cell(point: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(the grid index (..., 3) int32 of the cell nearest each world point (..., 3), clipped to the grid;
    whether the point lies inside the grid)."""
    idx = jnp.round((point - _ORIGIN) / GRID_STEP).astype(jnp.int32)
    inside = jnp.all((idx >= 0) & (idx < jnp.asarray(GRID_SHAPE)), -1)
    return jnp.clip(idx, 0, jnp.asarray(GRID_SHAPE) - 1), inside


def field_at(field: jax.Array, point: jax.Array) -> jax.Array:
    """The value of a field (X, Y, Z) at the cell nearest a world point (3,); inf outside the grid."""
    idx, inside = nearest_cell(point)
    return jnp.where(inside, field[idx[0], idx[1], idx[2]].astype(jnp.float32), jnp.inf)


def goal_seeds(free: jax.Array, goal: jax.Array, radius: float) -> jax.Array:
    """bool (X, Y, Z): the free cells within `radius` of `goal` (an arrival there ends the trip); where
    none is, the free cells nearest the goal (within a cell's diagonal of the nearest)."""
    gap = jnp.where(free, jnp.linalg.norm(cell_centres() - goal, axis=-1), jnp.inf)
    return free & (gap <= jnp.maximum(radius, jnp.min(gap) + GRID_STEP * np.sqrt(3.0)))


def check_with_fields(layout: layouts.Layout, p: EnvParams, straight: bool = True) -> tuple[Route, jax.Array]:
    """(`check`'s Route, the two distance fields (2, X, Y, Z)): route length (m) from every free cell to
    the water region's cells (A-W's goals) and to the air region's (W-A's); the trainer's route reward
    reads them (docrl_jax/envs/curriculum.py). `straight=False` leaves Route.straight NaN: the exact
    straight-line field is most of the program a level pool compiles and it needs none."""
    _, free, (air, water) = _cells(layout, p)
    starts, goals = jnp.stack([air, water]), jnp.stack([water, air])
    fields = jax.vmap(distance_field, (None, 0))(free, goals)
    straight = jax.vmap(_straight_line)(goals) if straight else jnp.full(goals.shape, jnp.nan)

    n_start = jnp.sum(starts, (1, 2, 3))
    has_cells = (n_start > 0) & (jnp.sum(goals, (1, 2, 3)) > 0)
    reach = jnp.where(starts, fields, 0.0)
    flyable = has_cells & jnp.all(jnp.isfinite(reach), (1, 2, 3))
    per_cell = lambda x: jnp.sum(jnp.where(starts, x, 0.0), (1, 2, 3)) / jnp.maximum(n_start, 1)  # noqa: E731
    inf = jnp.float32(jnp.inf)
    return Route(flyable=flyable,
                 length=jnp.where(flyable, per_cell(fields), inf),
                 longest=jnp.where(flyable, jnp.max(reach, (1, 2, 3)), inf),
                 straight=jnp.where(has_cells, per_cell(straight), inf),
                 start_cells=n_start.astype(jnp.int32)), fields


def widest_field(space: jax.Array, gap: jax.Array, seeds: jax.Array) -> jax.Array:
    """float32 (X, Y, Z): for every cell of `space`, the most clearance a way from it to a seed cell of
    `space` can keep: the largest, over 26-neighbour routes through `space`, of the least `gap` of their
    cells (a wavefront as `distance_field`'s, taking max of min for min of sum); -inf where no route is
    and off `space`. A trip that `check` finds blocked keeps less than `clearance` on its widest way."""
    space = jnp.asarray(space, bool)
    low = jnp.float32(-jnp.inf)
    nx, ny, nz = gap.shape

    def sweep(state):
        w, _, n = state
        padded = jnp.pad(w, 1, constant_values=low)
        best = functools.reduce(jnp.maximum, [padded[1 + i:1 + i + nx, 1 + j:1 + j + ny, 1 + k:1 + k + nz]
                                              for i, j, k in _OFFSETS])
        new = jnp.where(space, jnp.maximum(w, jnp.minimum(gap, best)), low)
        return new, jnp.any(new > w), n + 1

    w0 = jnp.where(space & seeds, gap, low)
    w, _, _ = jax.lax.while_loop(lambda state: state[1] & (state[2] < MAX_SWEEPS), sweep,
                                 (w0, jnp.asarray(True), jnp.asarray(0, jnp.int32)))
    return w


class Blockage(NamedTuple):
    """Where one trip of `check` is blocked (`blockage`): for a tank file's refusal."""
    start: jax.Array       # (3,) a start cell cut off from the goal cells: of those whose widest way keeps the
    #                        least clearance, the nearest the start region's centre
    clearance: jax.Array   # () the most clearance (m) a way from there to the goal cells keeps
    narrowest: jax.Array   # (3,) where the shortest of those widest ways keeps only that clearance


def blockage(layout: layouts.Layout, p: EnvParams, trip) -> Blockage:
    """Why `trip` (0 A-W, 1 W-A) of a layout whose regions both have cells is not flyable (`Blockage`). The
    ways run through every cell inside the episode's bounds, solids too (`widest_field`); the narrowest
    place is a cell keeping only that clearance on a shortest way among those keeping at least as much.
    Four wavefronts: for a refusal's message, not for a level pool."""
    gap, free, regions = _cells(layout, p)
    starts, goals = regions[trip], regions[1 - trip]
    space = _in_bounds(layout.z_min, p)
    widest = widest_field(space, gap, goals)
    cut = starts & ~jnp.isfinite(distance_field(free, goals))
    keeps = jnp.min(jnp.where(cut, widest, jnp.inf))
    centres = _centres()
    off_centre = jnp.linalg.norm(centres - layout.regions[trip].mean(0), axis=-1)
    start = jnp.argmin(jnp.where(cut & (widest == keeps), off_centre, jnp.inf))
    wide = space & (gap >= keeps)
    from_start = distance_field(wide, jnp.zeros(gap.size, bool).at[start].set(True).reshape(gap.shape))
    through = jnp.where(gap == keeps, from_start + distance_field(wide, goals), jnp.inf)
    centres = centres.reshape(-1, 3)
    return Blockage(start=centres[start], clearance=keeps, narrowest=centres[jnp.argmin(through)])


def route_path(field, start, max_points: int = 400) -> jax.Array:
    """float32 (max_points, 3): a polyline from the world point `start` down `field` (a `distance_field`)
    to its seeds. Row 0 is `start`; row 1 the cell it enters by (of the 27 cells around its nearest,
    the one with the least field + distance from `start`); then each row the neighbour of steepest descent
    (largest drop per metre: along a shortest route). Once a seed is reached the rows repeat it; a route of
    more than max_points - 2 moves is cut there (its last row's field is then > 0). Where no cell near
    `start` reaches a seed, every row after the first is that nearest cell. Numpy or JAX input; jit-safe."""
    field = jnp.asarray(field, jnp.float32)
    start = jnp.asarray(start, jnp.float32)
    shape = jnp.asarray(GRID_SHAPE)
    offsets, weights = jnp.asarray(_OFFSETS), jnp.asarray(_WEIGHTS)
    centre = lambda idx: jnp.asarray(_ORIGIN) + idx * GRID_STEP  # noqa: E731

    def value(idx):
        inside = jnp.all((idx >= 0) & (idx < shape), -1)
        safe = jnp.clip(idx, 0, shape - 1)
        return jnp.where(inside, field[safe[..., 0], safe[..., 1], safe[..., 2]], jnp.inf)

    nearest = jnp.clip(jnp.round((start - _ORIGIN) / GRID_STEP).astype(jnp.int32), 0, shape - 1)
    around = nearest + jnp.concatenate([jnp.zeros((1, 3), jnp.int32), offsets])
    entry = around[jnp.argmin(value(around) + jnp.linalg.norm(centre(around) - start, axis=-1))]
    entry = jnp.where(jnp.isfinite(value(entry)), entry, nearest)

    def step(idx, _):
        here = value(idx)
        drop = (here - value(idx + offsets)) / weights
        best = jnp.argmax(drop)
        nxt = jnp.where((drop[best] > 0) & jnp.isfinite(here), idx + offsets[best], idx)
        return nxt, centre(nxt)

    _, points = jax.lax.scan(step, entry, None, length=max_points - 2)
    return jnp.concatenate([start[None], centre(entry)[None], points])
