"""The flyability check (docrl_jax/envs/flyability.py) against independent references: the 26-neighbour
wavefront against a closed form in open space and against a heap Dijkstra of our own on a random
obstacle grid, the widest-way wavefront against thresholded connected components (scipy), free cells
against hand-computed clearances, and whole checks of hand-built tanks (empty, a wall across the tank
with and without an opening, an opening too narrow, a region inside a solid, a goal 0.3 m above the
floor), one at a time and vmapped.

Compiled programs: one jitted check, one vmapped check, one per-layout field program, one blockage,
small fields."""

from __future__ import annotations

import heapq
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import ndimage

from docrl_jax.envs import flyability as fly
from docrl_jax.envs import layouts
from docrl_jax.envs.params import make_params

P = make_params(0)
STEP = fly.GRID_STEP
FLOOR_TOP = -1.3
PARKED = np.array([0.0, 0.0, -50.0], np.float32)
AIR_SIDE = [[-4.3, -4.3, 0.5], [-1.5, 4.3, 4.0]]      # x < 0 of a wall at x = 0
WATER_SIDE = [[1.5, -4.3, -1.0], [4.3, 4.3, -0.4]]    # x > 0
OPENING = (1.7, 3.3)                                   # y range of the 1.6 m opening
NARROW = (1.7, 2.6)                                    # y range of a 0.9 m opening: its best cell, y = 2.25,
NARROW_KEEPS = 2.6 - 2.25                              # keeps 0.35 m from the solids (0.55 from the other side)
PAPER_GOAL = [2.0, 0.0, -1.0]                          # 0.3 m above FLOOR_TOP, on a cell centre


def tank(air, water, boxes=()):
    """A hand-built layout: floor top at FLOOR_TOP, every obstacle parked, then `boxes` ((centre,
    half extents), axis-aligned) in the first box slots; regions given as points or (low, high)."""
    base = layouts.generate(layouts.layout_key(0), P)
    pos = np.tile(PARKED, (base.pos.shape[0], 1))
    rot = np.tile(np.eye(3, dtype=np.float32), (base.pos.shape[0], 1, 1))
    size = np.full((base.pos.shape[0], 3), 0.1, np.float32)
    pos[0], size[0] = (0.0, 0.0, FLOOR_TOP - 0.1), (5.0, 5.0, 0.1)
    for slot, (centre, half) in enumerate(boxes, start=1):
        pos[slot], size[slot] = centre, half
    region = lambda r: np.array(r if np.ndim(r) == 2 else [r, r], np.float32)  # noqa: E731
    return base.replace(pos=jnp.asarray(pos), rot=jnp.asarray(rot), size=jnp.asarray(size),
                        z_min=jnp.float32(FLOOR_TOP + 0.2),
                        regions=jnp.asarray(np.stack([region(air), region(water)])))


def wall(lo_y, hi_y):
    """A box across x = 0 from y = lo_y to hi_y, from inside the floor to above the walls' top (5.4)."""
    bottom, top = FLOOR_TOP - 0.1, 5.5
    return ((0.0, (lo_y + hi_y) / 2, (bottom + top) / 2), (0.15, (hi_y - lo_y) / 2, (top - bottom) / 2))


TANKS = {
    "vertical": tank([0.0, 0.0, 2.0], [0.0, 0.0, -0.5]),
    "diagonal": tank([-2.0, -2.0, 2.5], [1.0, 1.0, -0.5]),
    "oblique": tank([-3.0, 1.0, 3.0], [2.5, -1.0, -0.5]),
    "wall": tank(AIR_SIDE, WATER_SIDE, [wall(-5.0, 5.0)]),
    "opening": tank(AIR_SIDE, WATER_SIDE, [wall(-5.0, OPENING[0]), wall(OPENING[1], 5.0)]),
    "air_in_solid": tank([-3.0, -3.0, 2.0], [2.0, 2.0, -0.5], [((-3.0, -3.0, 2.0), (0.6, 0.6, 0.6))]),
    "narrow": tank(AIR_SIDE, WATER_SIDE, [wall(-5.0, NARROW[0]), wall(NARROW[1], 5.0)]),
    "paper_goal": tank([-2.0, 0.0, 2.0], PAPER_GOAL),
}
NAMES = list(TANKS)


@pytest.fixture(scope="module")
def routes():
    """check() of every tank, one at a time (one compiled program)."""
    one = jax.jit(lambda layout: fly.check(layout, P))
    return {name: jax.tree.map(np.asarray, one(layout)) for name, layout in TANKS.items()}


@jax.jit
def _grids(layout):
    free = fly.free_cells(layout, P)
    air, water = fly.region_cells(layout, P, 0), fly.region_cells(layout, P, 1)
    return free, air, water, fly.distance_field(free, water)


# ---------------------------------------------------------------- the wavefront alone
def _dijkstra(free, seeds):
    """Shortest 26-neighbour route lengths by a heap Dijkstra (our own reference)."""
    dist = np.full(free.shape, np.inf)
    heap = [(0.0, idx) for idx in zip(*np.nonzero(free & seeds))]
    for _, idx in heap:
        dist[idx] = 0.0
    moves = [m for m in itertools.product((-1, 0, 1), repeat=3) if m != (0, 0, 0)]
    while heap:
        d, idx = heapq.heappop(heap)
        if d > dist[idx]:
            continue
        for m in moves:
            nb = tuple(np.add(idx, m))
            if all(0 <= nb[a] < free.shape[a] for a in range(3)) and free[nb]:
                nd = d + STEP * np.sqrt(np.abs(m).sum())
                if nd < dist[nb] - 1e-9:
                    dist[nb] = nd
                    heapq.heappush(heap, (nd, nb))
    return dist


def test_distance_field_open_space_closed_form():
    """No obstacle: the route to one seed is c*sqrt3 + (b-c)*sqrt2 + (a-b) steps for sorted offsets a>=b>=c."""
    shape, seed = (9, 8, 7), (2, 5, 3)
    seeds = np.zeros(shape, bool)
    seeds[seed] = True
    field = np.asarray(fly.distance_field(np.ones(shape, bool), seeds))
    off = np.sort(np.abs(np.indices(shape) - np.array(seed)[:, None, None, None]), axis=0)
    c, b, a = off
    expected = STEP * (c * np.sqrt(3) + (b - c) * np.sqrt(2) + (a - b))
    np.testing.assert_allclose(field, expected, rtol=1e-5)


def test_distance_field_matches_dijkstra_among_obstacles():
    rng = np.random.default_rng(3)
    free = rng.random((10, 9, 8)) > 0.35
    seeds = np.zeros_like(free)
    seeds[0, 0, 0] = seeds[9, 8, 2] = True
    free[0, 0, 0] = free[9, 8, 2] = True
    field = np.asarray(fly.distance_field(free, seeds))
    reference = _dijkstra(free, seeds)
    assert np.isinf(reference).any() and np.isfinite(reference).sum() > 300   # walls cut some cells off
    np.testing.assert_allclose(field, reference, rtol=1e-5)


def test_widest_field_matches_thresholded_components():
    """The widest way from a cell to a seed keeps the largest t at which the cell and a seed share a
    26-connected component of the space's cells with gap >= t (every t tried: scipy labels each)."""
    rng = np.random.default_rng(5)
    gap = rng.normal(0.5, 0.3, (9, 8, 7)).astype(np.float32)
    space = rng.random(gap.shape) > 0.1
    seeds = np.zeros(gap.shape, bool)
    seeds[0, 0, 0] = seeds[8, 7, 3] = space[0, 0, 0] = space[8, 7, 3] = True
    reference = np.full(gap.shape, -np.inf, np.float32)
    for t in np.unique(gap[space]):
        labels, _ = ndimage.label(space & (gap >= t), np.ones((3, 3, 3)))
        joined = np.isin(labels, np.unique(labels[seeds & (gap >= t)])) & (labels > 0)
        reference[joined] = t            # thresholds rise: the last that joins a cell is its widest way
    got = np.asarray(fly.widest_field(space, gap, seeds))
    assert np.isfinite(reference).sum() > 300 and np.isinf(reference[~space]).all()
    np.testing.assert_array_equal(got, reference)


def test_free_cells_hand_computed():
    """Clearance 0.55 m: from the floor top -1.3, the walls at 4.9, the wall box's faces at x = +-0.15."""
    free, *_ = _grids(TANKS["wall"])
    free = np.asarray(free)
    assert fly.clearance(P) == pytest.approx(0.55)
    ix = lambda x: int(np.argmin(np.abs(fly.GRID_X - x)))   # noqa: E731
    iz = lambda z: int(np.argmin(np.abs(fly.GRID_Z - z)))   # noqa: E731
    assert free.shape == fly.GRID_SHAPE == (39, 39, 37)
    assert free[ix(-2.0), ix(0.0), iz(-0.5)] and not free[ix(-2.0), ix(0.0), iz(-1.0)]      # floor
    assert free[ix(4.25), ix(0.0), iz(2.0)] and not free[ix(4.5), ix(0.0), iz(2.0)]         # tank wall
    assert free[ix(-2.0), ix(-4.25), iz(2.0)] and not free[ix(-2.0), ix(4.5), iz(2.0)]
    assert free[ix(0.75), ix(0.0), iz(2.0)] and not free[ix(0.5), ix(0.0), iz(2.0)]         # wall box
    assert free[ix(-2.0), ix(0.0), iz(4.75)]                                                # top bound 4.8
    assert not free[:, :, fly.GRID_Z < FLOOR_TOP + 0.2].any()


# ---------------------------------------------------------------- whole checks of hand-built tanks
@pytest.mark.parametrize("name", ["vertical", "diagonal"])
def test_empty_tank_axis_and_diagonal_route_is_the_straight_line(routes, name):
    r = routes[name]
    lo, hi = np.asarray(TANKS[name].regions[:, 0])
    straight = np.linalg.norm(hi - lo)          # air point to water point
    assert r.flyable.all() and (r.start_cells == 1).all()
    np.testing.assert_allclose(r.length, straight, atol=1e-4)
    np.testing.assert_allclose(r.straight, straight, atol=1e-4)


def test_empty_tank_oblique_route_within_the_metric_bound(routes):
    r = routes["oblique"]
    lo, hi = np.asarray(TANKS["oblique"].regions[:, 0])
    straight = np.linalg.norm(hi - lo)
    assert r.flyable.all()
    assert (np.abs(r.straight - straight) <= STEP * np.sqrt(3)).all()   # point regions snap to cells
    assert (r.length >= r.straight - 1e-4).all() and (r.length <= 1.13 * r.straight + STEP).all()
    assert (r.length > r.straight + STEP).all()      # the 26-neighbour metric's detour off the diagonals


def test_wall_across_the_tank_is_not_flyable(routes):
    r = routes["wall"]
    assert not r.flyable.any() and (r.start_cells > 100).all()
    assert np.isinf(r.length).all() and np.isfinite(r.straight).all()


def test_wall_with_an_opening_is_flown_through_the_opening(routes):
    r = routes["opening"]
    assert r.flyable.all()
    assert (r.length > 1.2 * r.straight).all() and (r.longest >= r.length).all()
    free, air, water, field = (np.asarray(x) for x in _grids(TANKS["opening"]))
    start = np.array([-3.0, -3.0, 2.0], np.float32)
    path = np.asarray(fly.route_path(field, start, max_points=200))
    assert path.shape == (200, 3) and np.allclose(path[0], start)
    end = np.round((path[-1] - fly._ORIGIN) / STEP).astype(int)
    assert water[tuple(end)] and field[tuple(end)] == 0.0                   # it ends on a goal cell
    cross = np.nonzero((path[:-1, 0] < 0) & (path[1:, 0] >= 0))[0]
    assert cross.size == 1
    a, b = path[cross[0]], path[cross[0] + 1]
    y_at_wall = a[1] + (b[1] - a[1]) * (0 - a[0]) / (b[0] - a[0])
    assert OPENING[0] < y_at_wall < OPENING[1]
    moves = np.linalg.norm(np.diff(path[1:], axis=0), axis=1)
    route_length = moves.sum()
    assert route_length == pytest.approx(field[tuple(np.round((path[1] - fly._ORIGIN) / STEP).astype(int))],
                                         abs=1e-3)                          # it follows a shortest route


def test_region_inside_a_solid_has_no_start_cells(routes):
    r = routes["air_in_solid"]
    assert r.start_cells[0] == 0 and r.start_cells[1] > 0
    assert not r.flyable.any() and np.isinf(r.length).all()


def test_a_narrow_opening_is_blocked_where_it_is_narrowest(routes):
    """A 0.9 m opening: not flyable; `blockage` names the best cell in it (x = 0, y = 2.25), keeping 0.35 m."""
    assert not routes["narrow"].flyable.any() and (routes["narrow"].start_cells > 100).all()
    for trip in (0, 1):
        b = jax.tree.map(np.asarray, jax.jit(lambda layout, d: fly.blockage(layout, P, d))(TANKS["narrow"], trip))
        assert b.clearance == pytest.approx(NARROW_KEEPS, abs=1e-5)
        np.testing.assert_allclose(b.narrowest[:2], [0.0, 2.25], atol=1e-6)
        assert (b.start[0] < 0) == (trip == 0)                 # a start cell on the start's side of the wall


def test_a_goal_near_the_floor_takes_the_free_cells_within_the_arrival_distance(routes):
    """The paper's underwater goals lie 0.3 m above the floor, below every free cell (0.55 m up): the water
    region's cells are the free cells within the arrival distance of the goal, and the trips are flown."""
    r = routes["paper_goal"]
    assert r.flyable.all() and r.start_cells[0] == 1
    free, air, water, field = (np.asarray(x) for x in _grids(TANKS["paper_goal"]))
    to_goal = np.linalg.norm(np.asarray(fly.cell_centres()) - np.array(PAPER_GOAL), axis=-1)
    assert not free[to_goal < 1e-6].any()                                  # the goal's own cell is not free
    np.testing.assert_array_equal(water, free & (to_goal <= P.arrival_distance))
    assert r.start_cells[1] == water.sum() > 0
    assert np.isfinite(field[air]).all()


def test_vmapped_batch_matches_one_at_a_time(routes):
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *TANKS.values())
    many = jax.jit(jax.vmap(lambda layout: fly.check(layout, P)))(batch)
    for i, name in enumerate(NAMES):
        for field, one, got in zip(fly.Route._fields, routes[name], many):
            np.testing.assert_allclose(np.asarray(got[i]), one, rtol=1e-6, err_msg=f"{name}: {field}")
