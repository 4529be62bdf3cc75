"""What the vehicle knows of its tank: an occupancy belief built from its own beams, and a route planned
on it (no prior map). Pure JAX over fixed shapes: one env's arrays, vmap for a batch.

The belief lives on flyability's grid (0.25 m cells, (39, 39, 37): the whole tank in 3-D), one int8 per
cell: UNKNOWN (no beam has passed), FREE (a beam passed through) or OCCUPIED (a beam ended there). Each step
`update` marks, along every beam the active sensor cast (its fan, then the beams after it: vertical, slanted),
the cells the beam crossed before its reading as FREE and the cell of its end point as OCCUPIED, unless the
reading is the sensor's maximum (nothing returned). The cells take the larger code: a solid once seen stays
(the tank is static), and a beam never turns a seen solid free.

What 20 beams see: the paper's fan lies in the body's x-y plane, so it maps one horizontal slice at the
vehicle's depth; a ceiling above it, a floor below it or a window's sill are never seen (the cells stay
UNKNOWN). `vertical_beams` (body +z, -z) and `slant_beams` (rings at +-`slant_elevation_deg`) see up and
down; the recipes for tanks a person builds fly with both (`sac_mlp_tanks`).

`plan` turns the belief into the params `guidance.aim` reads ({"field", "gap", "arrival"}), as `guidance.plan`
does from the tank's own solids: `gap` is every cell's distance to the nearest OCCUPIED cell (exact up to
`GAP_REACH`), a cell is passable when it is not OCCUPIED, keeps `flyability.clearance` from the seen solids and
lies below the episode's top bound (an UNKNOWN cell keeps `UNKNOWN_GAP`), UNKNOWN cells are passable at
`UNKNOWN_COST` extra per metre (the
free-space assumption of D* Lite: plan on what is known, assume the unknown is free), and `field` is the
route cost to the goal's arrival cells. The field is warm-started: each plan runs `SWEEPS` relaxation sweeps
from the last plan's field (the first from the straight-line distance to the goal, a lower bound), so a
newly seen wall raises the cells it cuts off within a few plans and the route bends round it, at a fixed
cost per plan.

`sense_and_plan` updates the belief every step and plans every `REPLAN` steps of the episode (`info["step"]`,
the env's step count; an episode's first step, 0, plans): between plans the aim reads the last plan, which the
carry holds. The rollout (docrl_jax/evaluate/rollout.py) gives the policy its own step counter, the same for
every trial, so under vmap the cond chooses one branch for the whole batch and the steps between plans skip
the planning; a per-trial condition (a new goal) would run both branches, so a goal new between plans (an env
that draws one at arrival) waits for the next plan. A caller that gives no step plans every step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs import flyability, guidance, sensors
from docrl_jax.envs.params import EnvParams

UNKNOWN, FREE, OCCUPIED = 0, 1, 2
BEAM_STEP = flyability.GRID_STEP / 2      # m between the points a beam marks (two per cell)
REACH = float(np.hypot(np.hypot(9.5, 9.5), 9.0)) + 1.0   # m: the farthest a beam from inside the grid can cross it
GAP_REACH = 4                              # cells: `gap` is exact up to 1 m (what the guidance and UNKNOWN_GAP read)
UNKNOWN_COST = 0.5                         # extra route cost per metre through UNKNOWN cells
UNKNOWN_GAP = 1.0                          # m: an UNKNOWN cell nearer a seen solid than this is not passable: beams
#                                            leave pockets unseen in a surface they sweep (a slab under a hovering
#                                            vehicle is hit by one beam), and a pocket is no opening
REPLAN = 4                                 # steps between plans when the caller counts them (`sense_and_plan`)
SWEEPS = 8                                 # relaxation sweeps of the field per plan: two a step, the route bends round
#                                            a new wall as fast as with two sweeps every step (4 a plan lost ~5 points
#                                            of gallery success both ways)

_SAMPLES = int(np.ceil(REACH / BEAM_STEP))
_GRID = np.asarray(flyability.GRID_SHAPE)


def empty() -> jax.Array:
    """int8 (X, Y, Z): a belief that knows nothing."""
    return jnp.zeros(flyability.GRID_SHAPE, jnp.int8)


def update(belief: jax.Array, p: EnvParams, position, rot, underwater, ranges) -> jax.Array:
    """The belief after one sensing: `ranges` (20 + k,) as the env reports them (its fan, then the beams
    after it: `info["ranges"]` then `info["vertical_ranges"]`), cast from `position` with the body's
    rotation `rot` (3, 3) in the medium `underwater` selects (module doc)."""
    dirs = sensors.beam_directions(p, rot, underwater)                       # (B, 3)
    limit = sensors.max_range(p, underwater)
    t = (jnp.arange(_SAMPLES, dtype=jnp.float32) + 0.5) * BEAM_STEP           # (S,)
    points = position + dirs[:, None, :] * t[None, :, None]                  # (B, S, 3)
    crossed = t[None, :] < (ranges[:, None] - 0.75 * flyability.GRID_STEP)   # short of the cell it ended in
    idx, inside = flyability.nearest_cell(points)
    codes = jnp.where(crossed & inside, FREE, UNKNOWN)
    hit = ranges < 0.999 * limit
    # An end point beyond the grid (a wall's face lies 0.15 m outside it) marks the grid's edge cell.
    end_idx, _ = flyability.nearest_cell(position + dirs * ranges[:, None])
    cells = jnp.concatenate([idx.reshape(-1, 3), end_idx])
    codes = jnp.concatenate([codes.reshape(-1), jnp.where(hit, OCCUPIED, UNKNOWN)]).astype(jnp.int8)
    return belief.at[cells[:, 0], cells[:, 1], cells[:, 2]].max(codes)


def gaps(belief: jax.Array) -> jax.Array:
    """float32 (X, Y, Z): distance (m) from every cell centre to the nearest OCCUPIED cell centre, exact up to
    GAP_REACH cells and inf where no occupied cell lies within GAP_REACH cells along every axis."""
    return jnp.sqrt(flyability.window_sq_distance(belief == OCCUPIED, GAP_REACH))


def passable(belief: jax.Array, gap: jax.Array, p: EnvParams) -> jax.Array:
    """bool (X, Y, Z): cells a route may use on what is known (module doc)."""
    z = flyability.cell_centres()[..., 2]
    clear = jnp.where(belief == UNKNOWN, gap >= UNKNOWN_GAP, gap >= flyability.clearance(p))
    return (belief != OCCUPIED) & clear & (z <= p.bounds[1])


def initial_field(goal: jax.Array) -> jax.Array:
    """float32 (X, Y, Z): the straight-line distance to `goal`, a lower bound of every route's cost."""
    return jnp.linalg.norm(flyability.cell_centres() - goal, axis=-1)


def relax(field: jax.Array, free: jax.Array, seeds: jax.Array, cost: jax.Array, sweeps: int | None = None) -> jax.Array:
    """`sweeps` (default SWEEPS) Bellman sweeps of the route cost from `field`: a seed cell 0, a blocked cell inf, any other the
    best of its 26 neighbours plus the move's length times its cost. A cell does not keep its own old value,
    so a field that is too low where a route has closed rises to the true cost (by >= a cell a sweep)."""
    inf = jnp.float32(jnp.inf)

    def sweep(d, _):
        best = flyability.relax(d, cost, jnp.full(d.shape, inf))
        return jnp.where(free, jnp.where(seeds, jnp.float32(0.0), best), inf), None

    return jax.lax.scan(sweep, field, None, length=SWEEPS if sweeps is None else sweeps)[0]


def plan(belief: jax.Array, field: jax.Array, goal: jax.Array, p: EnvParams, sweeps: int | None = None) -> dict:
    """`guidance.aim`'s params from the belief (module doc), the field relaxed `sweeps` times from `field`; a
    known cell costs `guidance.route_cost` per metre (its dislike of cells near solids)."""
    gap = gaps(belief)
    free = passable(belief, gap, p)
    seeds = flyability.goal_seeds(free, goal, p.arrival_distance)
    cost = guidance.route_cost(gap, p) + UNKNOWN_COST * (belief == UNKNOWN)
    return {"field": relax(field, free, seeds, cost, sweeps), "gap": gap,
            "arrival": jnp.float32(p.arrival_distance)}


def own_map(inner=None) -> dict:
    """The carry of a policy that maps as it flies (`sense_and_plan`): an empty belief, no plan yet (the last
    plan's field and gaps, made from the goal at the first step), the goal it was made for, and the steered
    policy's own carry `inner`."""
    return {"belief": empty(), "field": jnp.zeros(flyability.GRID_SHAPE, jnp.float32),
            "gap": jnp.full(flyability.GRID_SHAPE, jnp.inf, jnp.float32),
            "goal": jnp.full(3, jnp.nan, jnp.float32), "inner": inner}


def sense_and_plan(p: EnvParams, carry: dict, info: dict) -> tuple[dict, dict]:
    """(the carry after this step's sensing, `guidance.aim`'s params): the belief takes the step's beams
    (`info`: pose, attitude, ranges) every step; a plan (the field restarted from the straight line when the
    goal is not the last plan's, relaxed on the belief, and its gaps) is made when `info["step"]` is a multiple
    of REPLAN, else the carry's last plan is read (module doc); without "step" in `info`, every step plans.
    `p`: the env's params (the beams' geometry, clearances, arrival)."""
    goal = info["goal"]
    ranges = jnp.concatenate([info["ranges"], info["vertical_ranges"]])
    seen = update(carry["belief"], p, info["position"], info["rot"], info["underwater"], ranges)

    def replan(_):
        new_goal = jnp.any(goal != carry["goal"])    # the first plan's too: the empty carry's goal is NaN
        params = plan(seen, jnp.where(new_goal, initial_field(goal), carry["field"]), goal, p)
        return params["field"], params["gap"], goal

    def last(_):
        return carry["field"], carry["gap"], carry["goal"]

    if "step" not in info:
        field, gap, planned_for = replan(None)
    else:
        # The cond's choice must not depend on the goal: the step is the same for every trial of a rollout, the
        # goal each trial's own, and under vmap a cond on a per-trial value runs both branches.
        field, gap, planned_for = jax.lax.cond(info["step"] % REPLAN == 0, replan, last, None)
    params = {"field": field, "gap": gap, "arrival": jnp.float32(p.arrival_distance)}
    return {**carry, "belief": seen, "field": field, "gap": gap, "goal": planned_for}, params


def frontier(belief: jax.Array) -> jax.Array:
    """bool (X, Y, Z): FREE cells with an UNKNOWN face neighbour (where exploring would learn more)."""
    unknown = jnp.pad(belief == UNKNOWN, 1)
    nx, ny, nz = belief.shape
    near = jnp.zeros(belief.shape, bool)
    for axis in range(3):
        for s in (-1, 1):
            start = [1, 1, 1]
            start[axis] += s
            near = near | unknown[start[0]:start[0] + nx, start[1]:start[1] + ny, start[2]:start[2] + nz]
    return (belief == FREE) & near
