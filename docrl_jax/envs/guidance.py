"""Route guidance: where to steer in a tank whose solids are known (a tank file, a procedural level).

`plan` gives one trip's params: `gap`, every grid cell's distance to the nearest solid (walls, floor,
obstacles), `arrival`, the env's arrival distance, and `field`, the route cost from every free cell
(flyability's: 0.55 m from every solid) to the cells within the arrival distance of the goal. The cost of
a move is its length times 1 + `crowding` x how far the cell lies inside `SAFE_GAP` of a solid (0 at SAFE_GAP, 1 at the free cells' edge): with
`crowding` 0 it is flyability's own `distance_field`, whose shortest routes graze corners at 0.55 m, a few
centimetres of drift from the fans' 0.5 m collision reading; with the default the route keeps to the
middle of an opening and rounds corners ~1 m off.

Each step `aim` picks the point to steer at: the farthest of the next `LOOK_AHEAD` cells down the field's
steepest descent (`flyability.route_path` from the vehicle) that it sees, a line of sight keeping
`SIGHT_GAP` from every solid at the sampled cells; the goal itself once within `DIRECT_RANGE` or when the
goal's arrival sphere is in sight; off the free cells (a start 0.3 m above the floor, below the lowest free
layer; a drift out of a thin layer) it rejoins them where route cost + distance is least (`_entry`). For a
learned policy (`GUIDED_STEEP_REACH`), under water an aim above steeper than `STEEP_DEG` comes no farther
than 0.75 m: with a climb through an opening 1.5 m or more away and the opening's rim in its upper beams,
the policy held its depth and timed out (W-A under ceilings and pipes: replayed stalled states climb with
the aim 0.3-1 m away, descend with it 2 m or more away, even straight up).

Two steer at the aim (docrl_jax/baselines/route.py): the privileged route-follower (scripted steering),
and a learned policy with `route.guided` (its observation's goal floats point at the aim instead of the
goal: `guide`). A mapless policy pulled straight at its goal stalls where the way round a wall or up
through a ceiling's opening first leads away from it; guided, it follows the route and keeps its own obstacle
avoidance from the ranges. The episode still ends at the real goal.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs import flyability
from docrl_jax.envs.huauv import GOAL_FEATURES, goal_features

LOOK_AHEAD = 8            # cells down the route the aim may reach (~2-3 m)
DIRECT_RANGE = 1.0        # m: within this of the goal, fly straight at it
SAFE_GAP = 1.0            # m: cells nearer a solid than this cost more
CROWDING = 2.0            # extra cost per metre at the free cells' edge (0.55 m from a solid)
SIGHT_GAP = 0.8           # m: a line of sight's sampled cells keep this from every solid (the scripted follower)
GUIDED_SIGHT_GAP = 0.6    # m: the same for a learned policy (`guided`), which keeps its own clearance from its
#                           ranges: its aim reaches further through an opening (gallery W-A +8 points on 3
#                           seeds against 0.8; 0.5 and below read as 0.55, the free cells' own clearance: no better)
SIGHT_STEP = 0.1          # m between the points a line of sight samples
SIGHT_SAMPLES = 160       # points sampled toward the goal (16 m: the tank's diagonal)
REACH_CELLS = 2           # off the free cells: where to rejoin them, within this many cells on each axis
STEEP_DEG = 45.0          # deg: under water, an aim above steeper than this is a climb through an opening
GUIDED_STEEP_REACH = 0.75  # m: `guided` brings such an aim this near: a learned policy holds its depth under a
#                            structure when a steep aim is 1.5 m or more away (W-A time-outs under ceilings)

_AROUND = np.stack(np.meshgrid(*[np.arange(-REACH_CELLS, REACH_CELLS + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)


def plan(layout, p, goal: jax.Array, crowding: float = CROWDING) -> dict:
    """The follower's params for one trip to `goal` in `layout` (module doc): {"field", "gap"}."""
    return plan_cells(flyability.free_cells(layout, p), flyability.cell_gaps(layout), p, goal, crowding)


def plan_cells(free: jax.Array, gap: jax.Array, p, goal: jax.Array, crowding: float = CROWDING) -> dict:
    """`plan` from a layout's free cells and `flyability.cell_gaps` (computed once for many trips in one tank)."""
    seeds = flyability.goal_seeds(free, goal, p.arrival_distance)
    arrival = jnp.float32(p.arrival_distance)
    if crowding == 0:
        return {"field": flyability.distance_field(free, seeds), "gap": gap, "arrival": arrival}
    return {"field": flyability.distance_field(free, seeds, route_cost(gap, p, crowding)), "gap": gap,
            "arrival": arrival}


def route_cost(gap: jax.Array, p, crowding: float = CROWDING) -> jax.Array:
    """Cost per metre of a move leaving each cell (module doc): 1, plus `crowding` x how far the cell lies
    inside SAFE_GAP of a solid (`gap`: its distance to the nearest one)."""
    inside = jnp.clip((SAFE_GAP - gap) / (SAFE_GAP - flyability.clearance(p)), 0.0, 1.0)
    return 1.0 + crowding * inside


_TRIAL_PLANS: dict = {}   # (id(env), crowding, batch) -> (jit of the plans, env): compiled once per env


def trial_plans(env, states, crowding: float = CROWDING, batch: int = 25) -> dict:
    """A plan per trial (leading axis) from the trials' initial `states` in `env`: the tank each state holds
    (its layout, or the fixed scenario's geoms: `HUAUVEnv.solids`) and its goal; `batch` trials at a time
    (each holds a few grids of the tank). A fixed scenario's one tank is gridded once for all its trials."""
    cache_key = (id(env), float(crowding), int(batch))
    if cache_key not in _TRIAL_PLANS:
        def plan_in(cells, goal):
            return plan_cells(*cells, env.params, goal, crowding)

        def plans(layout, goals):
            if layout is None:   # a fixed scenario (traced once per env: the structure is static)
                cells = flyability.tank_cells(*env.solids(), env.params)
                return jax.lax.map(lambda goal: plan_in(cells, goal), goals, batch_size=batch)
            one = lambda a: plan_in(flyability.tank_cells(*env.solids(a[0]), env.params), a[1])  # noqa: E731
            return jax.lax.map(one, (layout, goals), batch_size=batch)
        _TRIAL_PLANS[cache_key] = (jax.jit(plans), env)
    return _TRIAL_PLANS[cache_key][0](states.sim.layout, states.info["goal"])


def in_sight(params: dict, a: jax.Array, b: jax.Array, samples: int = SIGHT_SAMPLES, gap=None) -> jax.Array:
    """bool: every point sampled along a -> b (every `SIGHT_STEP`, up to `samples`) lies in a cell the
    field reaches, at least `gap` (default SIGHT_GAP) from every solid (with 0.8 the segment keeps ~0.58 m
    or more)."""
    gap = SIGHT_GAP if gap is None else gap
    n = jnp.clip(jnp.ceil(jnp.linalg.norm(b - a) / SIGHT_STEP), 1, samples)
    points = a + jnp.minimum(jnp.arange(samples + 1, dtype=jnp.float32) / n, 1.0)[:, None] * (b - a)
    ok = lambda q: jnp.isfinite(flyability.field_at(params["field"], q)) & (  # noqa: E731
        flyability.field_at(params["gap"], q) >= gap)
    return jnp.all(jax.vmap(ok)(points))


def _entry(field: jax.Array, position: jax.Array) -> jax.Array:
    """Off the free cells: the centre of the cell within `REACH_CELLS` on each axis with the least field +
    distance from `position` (a solid between would need 1.1 m of free-cell clearance: more than the reach)."""
    idx, _ = flyability.nearest_cell(position)
    cells = jnp.clip(idx + _AROUND, 0, jnp.asarray(flyability.GRID_SHAPE) - 1)
    centres = flyability.cell_centres()[cells[..., 0], cells[..., 1], cells[..., 2]]
    cost = field[cells[:, 0], cells[:, 1], cells[:, 2]] + jnp.linalg.norm(centres - position, axis=-1)
    return centres[jnp.argmin(cost)]


def aim(params: dict, position: jax.Array, goal: jax.Array, sight_gap=None, steep_reach=None) -> jax.Array:
    """The point (3,) to steer at (module doc); lines of sight keep `sight_gap` (default SIGHT_GAP). With
    `steep_reach`, under water an aim above steeper than STEEP_DEG lies at most that far (same direction)."""
    off_route = ~jnp.isfinite(flyability.field_at(params["field"], position))
    start = jnp.where(off_route, _entry(params["field"], position), position)
    path = flyability.route_path(params["field"], start, LOOK_AHEAD + 2)[1:]          # (LOOK_AHEAD + 1, 3)
    reach = int(np.ceil(LOOK_AHEAD * flyability.GRID_STEP * np.sqrt(3.0) / SIGHT_STEP)) + 2
    seen = jax.vmap(lambda q: in_sight(params, position, q, reach, sight_gap))(path).at[0].set(True)
    target = path[jnp.max(jnp.where(seen, jnp.arange(path.shape[0]), 0))]
    # The goal is in sight when the line to its arrival sphere is (less a cell: the samples read their nearest
    # cell's gap, up to half a cell low): a goal nearer a solid than the sight gap (the paper's A-W goals lie
    # 0.3 m above the floor) is flown at straight, as a mapless policy flies it, once its sphere can be reached.
    distance = jnp.linalg.norm(goal - position)
    short = jnp.minimum(params["arrival"] + flyability.GRID_STEP, distance)
    sphere = goal + (position - goal) * short / jnp.maximum(distance, 1e-6)
    direct = (distance < DIRECT_RANGE) | in_sight(params, position, sphere, gap=sight_gap)
    target = jnp.where(direct, goal, target)
    if steep_reach is None:
        return target
    rel = target - position
    steep = (position[2] < 0.0) & (rel[2] > np.tan(np.radians(STEEP_DEG)) * jnp.linalg.norm(rel[:2]))
    near = position + rel * jnp.minimum(1.0, steep_reach / jnp.maximum(jnp.linalg.norm(rel), 1e-6))
    return jnp.where(steep, near, target)


def guide(obs: jax.Array, position: jax.Array, yaw: jax.Array, target: jax.Array) -> jax.Array:
    """`obs` with its goal floats (`huauv.GOAL_FEATURES`) pointing at `target` from the pose."""
    return obs.at[GOAL_FEATURES].set(goal_features(position, yaw, target).astype(obs.dtype))
