"""Why a tank file's tank cannot be flown, in words that name its solids (docs/TANKS.md, "The errors"): a
region with no free cell within the arrival distance of it (flyability's region cells), or no route between
the regions, and then where the widest way between them is narrowest (`flyability.blockage`). `tanks.load`
raises them as `TankError`, after its own checks of the file."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs import flyability, geometry, layouts
from docrl_jax.envs.params import EnvParams


def by_distance(layout, names, point) -> list[tuple[float, str]]:
    """(distance m, what) of the floor, the tank's walls and every solid from `point`, nearest first."""
    solids, q = layouts.obstacles(layout), jnp.asarray(point, jnp.float32)
    slots = np.concatenate(jax.device_get([geometry.box_distances(solids, q), geometry.capsule_distances(solids, q)]))
    wall = geometry.TANK_HALF_WIDTH - float(np.abs(point[:2]).max())
    return sorted([(float(d), f"solid {n!r}") for d, n in zip(slots, names) if n is not None]
                  + [(float(point[2] - layouts.floor_top(layout)), "the floor"), (wall, "the tank's wall")])


def _listed(whats) -> str:
    return " and ".join(whats) if len(whats) < 3 else ", ".join(whats[:-1]) + " and " + whats[-1]


def route_refusal(layout: layouts.Layout, route: flyability.Route, names, p: EnvParams) -> str | None:
    """Why a loaded tank's `route` (`flyability.check`) is not flyable, or None when it is: a region with no
    free cell within the arrival distance of its points (flyability's region cells), else the narrowest
    place of the widest way between the regions. `names`: the slots' solid names (None where parked)."""
    clear, reach, step = flyability.clearance(p), p.arrival_distance, flyability.GRID_STEP
    at = lambda point: np.round(np.asarray(point, np.float64), 2).tolist()  # noqa: E731
    for i, medium in enumerate(("air", "water")):
        if route.start_cells[i] == 0:     # trip i starts in region i
            (lo, hi), point = np.asarray(layout.regions[i]), np.asarray(layout.clear[i])
            found = by_distance(layout, names, point)
            lies = _listed([f"{d:.2f} m {'above' if what == 'the floor' else 'from'} {what}"
                            for d, what in [x for x in found[:2] if x[0] < clear + reach] or found[:1]])
            why = (f"at {at(point)} lies {lies}: no free cell within the arrival distance {reach} m of it"
                   if np.array_equal(lo, hi) else f"{at(lo)} .. {at(hi)} has no point within the arrival distance "
                   f"{reach} m of a free cell (its point {at(point)} lies {lies})")
            return (f"the {medium} region {why}; free cells keep {clear:.2f} m from every solid, a start or goal "
                    "joins them within the arrival distance (move the region off the solid)")
    for trip, (start, goal) in enumerate((("air", "water"), ("water", "air"))):
        if route.flyable[trip]:
            continue
        if p not in _BLOCKAGE:
            _BLOCKAGE[p] = jax.jit(lambda lay, d: flyability.blockage(lay, p, d))
        blocked = jax.device_get(_BLOCKAGE[p](layout, trip))
        keeps = float(blocked.clearance)
        near = [what for d, what in by_distance(layout, names, blocked.narrowest) if d <= max(keeps, 0.0) + step]
        if keeps < step * np.sqrt(3) / 2:    # a move between two cells may jump a solid this thin
            why = (f"{_listed(near[:4])} close{'s' if len(near) == 1 else ''} every way from its point "
                   f"{at(blocked.start)} (the widest way crosses at {at(blocked.narrowest)})")
        else:
            why = (f"from its point {at(blocked.start)} the widest way keeps at most {keeps:.2f} m from the solids, "
                   f"at {at(blocked.narrowest)} beside {_listed(near[:4])} (a gap of ~{2 * keeps:.1f}-"
                   f"{2 * keeps + step:.1f} m)")
        return (f"no route from the {start} region to the {goal} region: {why}; a route keeps {clear:.2f} m from "
                f"every solid: a gap must be >= ~{2 * clear:.1f} m wide, {2 * clear + step:.2f} m wherever it lies "
                f"on the {step} m grid")
    return None


_BLOCKAGE: dict = {}   # params -> the compiled `flyability.blockage`, compiled at a tank's first refusal
