"""What the vehicle knows, drawn: the own map (docrl_jax/envs/belief.py) of a recorded trial as a top view
beside each frame of the renderer (`python -m docrl_jax.render --guide sensors`).

`replay` runs the own-map planner (`belief.sense_and_plan`, the very function the steered policy ran) over a
trial's records (pose, attitude, ranges, goal), so the drawing is what the policy knew at each step, not a
second model of it. `top_view` draws one step: per column of the grid within `BAND` of the vehicle's depth,
a seen solid dark, cells a beam crossed light, unknown grey, the frontier (free next to unknown) at the vehicle's
depth amber, the
route the planner follows from the vehicle blue, the vehicle red, the goal green.
"""

from __future__ import annotations

import numpy as np

from docrl_jax.envs import belief as own_map
from docrl_jax.envs import flyability

BAND = 0.5           # m above and below the vehicle that the top view flattens (a floor or slab farther off
#                      would hide the walls at its depth)
ROUTE_POINTS = 80    # cells of the planned route drawn from the vehicle

_COLOURS = {"unknown": (150, 150, 150), "free": (235, 235, 235), "occupied": (30, 30, 30),
            "frontier": (240, 170, 40), "route": (40, 90, 230), "vehicle": (220, 30, 30), "goal": (30, 170, 60)}


def replay(params, positions, rots, underwater, ranges, goals) -> dict[str, np.ndarray]:
    """The own map at every step of one trial: {"belief" (T, X, Y, Z) int8, "field" (T, X, Y, Z) float32},
    from the trial's records (T, ...) from its first step on: positions (3,), rots (3, 3), underwater, ranges
    (20 + k,) (the fan, then the beams after it) and goals (3,); step t plans when the policy's did. `params`:
    the env's (its beams' geometry)."""
    import jax
    import jax.numpy as jnp

    from docrl_jax.envs.sensors import NUM_BEAMS

    def step(carry, x):
        info = {"position": x[0], "rot": x[1], "underwater": x[2], "ranges": x[3][:NUM_BEAMS], "vertical_ranges": x[3][NUM_BEAMS:],
                "goal": x[4], "step": x[5]}
        carry, _ = own_map.sense_and_plan(params, carry, info)
        return carry, (carry["belief"], carry["field"])

    steps = jnp.arange(len(positions), dtype=jnp.int32)     # the records start at the trial's first step
    xs = tuple(jnp.asarray(a) for a in (positions, rots, underwater, ranges, goals)) + (steps,)
    _, (beliefs, fields) = jax.jit(lambda xs: jax.lax.scan(step, own_map.own_map(), xs))(xs)
    return {"belief": np.asarray(beliefs), "field": np.asarray(fields)}


def top_view(belief: np.ndarray, field: np.ndarray, position, goal, size: int) -> np.ndarray:
    """uint8 (size, size, 3): the top view of one step (module doc); north (+y) up, east (+x) right."""
    z = flyability.GRID_Z
    band = np.abs(z - float(position[2])) <= BAND
    cells = belief[..., band]
    image = np.empty(belief.shape[:2] + (3,), np.uint8)
    image[...] = _COLOURS["unknown"]
    image[np.any(cells == own_map.FREE, -1)] = _COLOURS["free"]
    layer = int(np.argmin(np.abs(z - float(position[2]))))   # the frontier at the vehicle's own depth
    image[np.asarray(own_map.frontier(belief))[..., layer]] = _COLOURS["frontier"]
    image[np.any(cells == own_map.OCCUPIED, -1)] = _COLOURS["occupied"]
    path = np.asarray(flyability.route_path(field, np.asarray(position, np.float32), ROUTE_POINTS))
    for point, colour in [(p, "route") for p in path[1:]] + [(goal, "goal"), (position, "vehicle")]:
        idx, inside = flyability.nearest_cell(np.asarray(point, np.float32))
        if bool(inside) or colour != "route":
            i, j = np.asarray(idx)[:2]
            image[i, j] = _COLOURS[colour]
    image = np.transpose(image, (1, 0, 2))[::-1]          # rows: +y up; columns: +x right
    scale = max(1, size // image.shape[0])
    image = np.repeat(np.repeat(image, scale, 0), scale, 1)
    out = np.full((size, size, 3), 255, np.uint8)
    top, left = (size - image.shape[0]) // 2, (size - image.shape[1]) // 2
    out[top:top + image.shape[0], left:left + image.shape[1]] = image
    return out


def beside(frames: np.ndarray, params, track, every: int) -> np.ndarray:
    """`frames` (F, H, W, 3) of `track` (an `envs.rendering.Track`, drawn every `every` entries) with the top view
    of the own map at each frame's step to their right (F, H, W + H, 3)."""
    from docrl_jax.envs import physics
    from docrl_jax.envs.render_tracks import frame_steps
    qpos = np.asarray(track.qpos, np.float32)
    rots = np.stack([np.asarray(physics.quat_to_mat(q)) for q in qpos[:, 3:7]])
    ranges = np.concatenate([track.ranges, track.vertical_ranges], -1)
    maps = replay(params, qpos[:, :3], rots, np.asarray(track.underwater), ranges, np.asarray(track.goal))
    size = frames.shape[1]
    views = [top_view(maps["belief"][t], maps["field"][t], qpos[t, :3], track.goal[t], size)
             for t in frame_steps(len(qpos), every)]
    return np.concatenate([frames, np.stack(views)], 2)
