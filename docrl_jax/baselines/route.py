"""A privileged route-follower: the reference that tells whether a trial is flyable by the vehicle itself,
not only by the grid check (docrl_jax/envs/flyability.py). It knows the tank.

Per trial, `plan` builds the follower's params: `gap`, every grid cell's distance to the nearest solid
(walls, floor, obstacles), and `field`, the route cost from every free cell (flyability's: 0.55 m from
every solid) to the cells within the arrival distance of the goal. The cost of a move is its length times
1 + `crowding` x how far the cell lies inside `SAFE_GAP` of a solid (0 at SAFE_GAP, 1 at the free cells'
edge): with `crowding` 0 it is flyability's own `distance_field`, whose shortest routes graze corners at
0.55 m, a few centimetres of drift from the fans' 0.5 m collision reading; with the default the route keeps
to the middle of an opening and rounds corners ~1 m off. In the gallery's and the structured set's trials
(`python benchmarks/route_follower.py [--crowding 0]`, benchmarks/results/cpu/route_follower) the default
arrives in all 900, the shortest routes collide in 37 (all in air, where the LIDAR fan sees 270 degrees).

Each step (`aim`) the follower steers at the farthest of the next `LOOK_AHEAD` cells down the field's
steepest descent (`flyability.route_path` from the vehicle) that it sees, a line of sight keeping
`SIGHT_GAP` from every solid at the sampled cells; it flies straight at the goal once within `DIRECT_RANGE`
or when the goal is in sight; off the free cells (a start 0.3 m above the floor, below the lowest free
layer; a drift out of a thin layer) it rejoins them where route cost + distance is least (`_entry`). The
steering is the scripted `straight_line` policy's (docrl_jax/baselines/scripted.py) with that point as its
goal. It reads the pose and the goal from `info`
and the grids from its params, one pair per trial: run it with a rollout that maps params over trials
(benchmarks/route_follower.py).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.baselines.scripted import straight_line
from docrl_jax.envs import flyability
from docrl_jax.policy import Policy

LOOK_AHEAD = 8            # cells down the route the aim may reach (~2-3 m)
DIRECT_RANGE = 1.0        # m: within this of the goal, fly straight at it
SAFE_GAP = 1.0            # m: cells nearer a solid than this cost more
CROWDING = 2.0            # extra cost per metre at the free cells' edge (0.55 m from a solid)
SIGHT_GAP = 0.8           # m: a line of sight's sampled cells keep this from every solid
SIGHT_STEP = 0.1          # m between the points a line of sight samples
SIGHT_SAMPLES = 160       # points sampled toward the goal (16 m: the tank's diagonal)
REACH_CELLS = 2           # off the free cells: where to rejoin them, within this many cells on each axis

_STRAIGHT = straight_line()
_AROUND = np.stack(np.meshgrid(*[np.arange(-REACH_CELLS, REACH_CELLS + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)


def goal_seeds(free: jax.Array, goal: jax.Array, radius: float) -> jax.Array:
    """bool (X, Y, Z): the free cells within `radius` of `goal` (an arrival there ends the trip); where
    none is, the free cells nearest the goal (within a cell's diagonal of the nearest)."""
    gap = jnp.where(free, jnp.linalg.norm(flyability.cell_centres() - goal, axis=-1), jnp.inf)
    return free & (gap <= jnp.maximum(radius, jnp.min(gap) + flyability.GRID_STEP * np.sqrt(3.0)))


def plan(layout, p, goal: jax.Array, crowding: float = CROWDING) -> dict:
    """The follower's params for one trip to `goal` in `layout` (module doc): {"field", "gap"}."""
    return plan_cells(flyability.free_cells(layout, p), flyability.cell_gaps(layout), p, goal, crowding)


def plan_cells(free: jax.Array, gap: jax.Array, p, goal: jax.Array, crowding: float = CROWDING) -> dict:
    """`plan` from a layout's free cells and `flyability.cell_gaps` (computed once for many trips in one tank)."""
    seeds = goal_seeds(free, goal, p.arrival_distance)
    if crowding == 0:
        return {"field": flyability.distance_field(free, seeds), "gap": gap}
    inside = jnp.clip((SAFE_GAP - gap) / (SAFE_GAP - flyability.clearance(p)), 0.0, 1.0)
    return {"field": flyability.distance_field(free, seeds, 1.0 + crowding * inside), "gap": gap}


def straight_plan(goal: jax.Array) -> dict:
    """Params of the control case: the straight-line distance to `goal` from every cell and no solid
    anywhere, as if the tank were empty (the follower then flies straight at the goal)."""
    field = jnp.linalg.norm(flyability.cell_centres() - goal, axis=-1)
    return {"field": field, "gap": jnp.full(field.shape, jnp.inf, jnp.float32)}


def in_sight(params: dict, a: jax.Array, b: jax.Array, samples: int = SIGHT_SAMPLES) -> jax.Array:
    """bool: every point sampled along a -> b (every `SIGHT_STEP`, up to `samples`) lies in a cell the
    field reaches, at least `SIGHT_GAP` from every solid (so the segment keeps ~0.58 m or more)."""
    n = jnp.clip(jnp.ceil(jnp.linalg.norm(b - a) / SIGHT_STEP), 1, samples)
    points = a + jnp.minimum(jnp.arange(samples + 1, dtype=jnp.float32) / n, 1.0)[:, None] * (b - a)
    ok = lambda q: jnp.isfinite(flyability.field_at(params["field"], q)) & (  # noqa: E731
        flyability.field_at(params["gap"], q) >= SIGHT_GAP)
    return jnp.all(jax.vmap(ok)(points))


def _entry(field: jax.Array, position: jax.Array) -> jax.Array:
    """Off the free cells: the centre of the cell within `REACH_CELLS` on each axis with the least field +
    distance from `position` (a solid between would need 1.1 m of free-cell clearance: more than the reach)."""
    idx, _ = flyability.nearest_cell(position)
    cells = jnp.clip(idx + _AROUND, 0, jnp.asarray(flyability.GRID_SHAPE) - 1)
    centres = flyability.cell_centres()[cells[..., 0], cells[..., 1], cells[..., 2]]
    cost = field[cells[:, 0], cells[:, 1], cells[:, 2]] + jnp.linalg.norm(centres - position, axis=-1)
    return centres[jnp.argmin(cost)]


def aim(params: dict, position: jax.Array, goal: jax.Array) -> jax.Array:
    """The point (3,) to steer at (module doc)."""
    off_route = ~jnp.isfinite(flyability.field_at(params["field"], position))
    start = jnp.where(off_route, _entry(params["field"], position), position)
    path = flyability.route_path(params["field"], start, LOOK_AHEAD + 2)[1:]          # (LOOK_AHEAD + 1, 3)
    reach = int(np.ceil(LOOK_AHEAD * flyability.GRID_STEP * np.sqrt(3.0) / SIGHT_STEP)) + 2
    seen = jax.vmap(lambda q: in_sight(params, position, q, reach))(path).at[0].set(True)
    target = path[jnp.max(jnp.where(seen, jnp.arange(path.shape[0]), 0))]
    direct = (jnp.linalg.norm(goal - position) < DIRECT_RANGE) | in_sight(params, position, goal)
    return jnp.where(direct, goal, target)


def _init_carry():
    return jnp.zeros((), jnp.int32)


def _act(params, carry, obs, info, key):
    position, goal = info["position"], info["goal"]
    target = aim(params, position, goal)
    # straight_line slows within 0.5 m (horizontally) of its goal; a route point is no place to stop, so
    # one nearer than that (and not straight above or below) is pushed out to 0.5 m along the same bearing.
    rel = target - position
    across = jnp.linalg.norm(rel[:2])
    stretch = jnp.where((across > 0.1) & jnp.any(target != goal), jnp.maximum(1.0, 0.5 / across), 1.0)
    target = position + rel * jnp.array([stretch, stretch, 1.0])
    _, action = _STRAIGHT.act(_STRAIGHT.params, carry, obs, {**info, "goal": target}, key)
    return carry + 1, action


def route_follower(params=None) -> Policy:
    """The route-follower with `params` (`plan` or `straight_plan` of one trip, or a stack of them with a
    leading trial axis for a rollout that maps params over trials); None: to be given per trial."""
    return Policy(name="route_follower", params=params, init_carry=_init_carry, act=_act)
