"""A level pool and a level curriculum for procedural tanks: small pure functions beside the env, run
inside the trainer's scanned program (`levels.sampler` of the config; docrl_jax/config/sections.py documents it).

A *level* is a `layouts.Layout` (tank, obstacles, structures, start and goal regions). The pool holds
`capacity` of them, every one checked flyable both ways (`flyability.check`) before it enters, so no
unflyable level is trained on. It lives in the trainer's state:

  * `refresh` (start of every chunk): `refresh` candidate levels drawn by the env's own generator
    (`env.draw_layout`, structures mixed in by `layout_structures`), twice as many as needed so that
    flyable ones are almost always enough; they replace `refresh` pool levels: random ones ('uniform'),
    or the least learnable ones ('learnability'). A slot whose candidate is not flyable keeps its level.
    Then the sampling weights are recomputed (once per chunk: a draw is then a search in their
    cumulative sum, not a pass over the pool per env).
  * `sample` (every iteration): the level each env restarts in if its episode ends now.
  * `record` (every iteration): the training episodes that ended, with whether any goal was reached,
    counted on the level they flew.

Learnability is p(1 - p) with p = (successes + 1) / (episodes + 2), the success rate under a uniform
prior (a level not flown yet scores the most, 0.25, so it is tried before it can be dropped): levels
the policy solves sometimes but not always (Sampling For Learnability). Draws are proportional to
learnability^(1 / temperature), plus a uniform share in place of PLR's staleness term. Not PLR's rank
weights: with thousands of envs restarting per chunk they would send most of them to one level. It needs only episode outcomes,
so it fits an off-policy learner, whose replay data holds no on-policy value estimates for a regret.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from docrl_jax.envs import flyability

SAMPLERS = ("uniform", "learnability")
CHECK_BATCH = 32   # candidate levels checked at once


@struct.dataclass
class LevelPool:
    levels: Any            # layouts.Layout with a leading (capacity,) axis, every level flyable both ways
    route: jax.Array       # (capacity,) mean route length (m) of the level's two directions: its difficulty
    episodes: jax.Array    # (capacity,) training episodes ended on the level since it entered
    successes: jax.Array   # (capacity,) of those, the ones that reached a goal
    cdf: jax.Array         # (capacity,) cumulative sampling weights, fixed between refreshes
    flyable: jax.Array     # () share of the last refresh's candidates that were flyable
    fields: Any = None     # (capacity, 2, X, Y, Z) float16 route lengths to the water and the air region
    #                        (flyability.check_with_fields), kept for the route reward; None without it


class Curriculum(NamedTuple):
    init: Callable      # key -> LevelPool (every slot filled with a flyable level)
    refresh: Callable   # (pool, key) -> (pool, metrics)
    sample: Callable    # (pool, key, n) -> (n,) int32 level indices
    take: Callable      # (pool, indices) -> Layout with a leading (n,) axis
    record: Callable    # (pool, indices, done (n,), success (n,)) -> pool
    to_region: Callable  # (pool, indices (n,), water (n,) bool, positions (n, 3)) -> (n,) route length (m)


def learnability(pool: LevelPool) -> jax.Array:
    """(capacity,) p (1 - p) of each level, p its success rate under a uniform prior."""
    p = (pool.successes + 1.0) / (pool.episodes + 2.0)
    return p * (1.0 - p)


def make_curriculum(env, sampler: str, capacity: int, refresh: int, temperature: float = 0.5,
                    uniform_mix: float = 0.3, check: Callable | None = None,
                    keep_fields: bool = False) -> Curriculum:
    """The pool's pure functions for `env` (an HUAUVEnv of procedural tanks; its `draw_layout` and params).
    `sampler`: 'uniform' or 'learnability' (module doc). `check(level, params) -> flyability.Route`
    decides which candidates may enter (default: flyability's, without the straight-line distances). `keep_fields`: the pool keeps each level's distance fields
    (`flyability.check_with_fields`, then the check) for `to_region`."""
    if sampler not in SAMPLERS:
        raise ValueError(f"sampler={sampler!r}: valid samplers are {', '.join(SAMPLERS)}")
    if not 1 <= refresh <= capacity:
        raise ValueError(f"refresh={refresh}: must be in [1, capacity={capacity}]")
    p = env.params
    if check is None:   # the flyability check without its straight-line distances (the pool needs none)
        check = lambda level, params: flyability.check_with_fields(level, params, straight=False)[0]  # noqa: E731

    def candidates(key, n: int):
        """(n levels drawn by the env's generator, flyable (n,), route (n,)), flyable ones first."""
        keys = jax.random.split(key, 2 * n)
        levels = jax.vmap(env.draw_layout)(keys)
        # Checked CHECK_BATCH levels at a time: a check's grids of hundreds of levels at once take
        # gigabytes, and a smaller program compiles far sooner.
        if keep_fields:
            def one(lv):
                route, fields = flyability.check_with_fields(lv, p, straight=False)
                return route, fields.astype(jnp.float16)
            route, fields = jax.lax.map(one, levels, batch_size=CHECK_BATCH)
            levels = (levels, fields)
        else:
            route = jax.lax.map(lambda lv: check(lv, p), levels, batch_size=CHECK_BATCH)
            levels = (levels, None)
        ok = jnp.all(route.flyable, -1)
        order = jnp.argsort(~ok, stable=True)[:n]
        take = lambda x: x[order]  # noqa: E731
        return jax.tree.map(take, levels), ok[order], jnp.mean(route.length, -1)[order], jnp.mean(ok)

    def weights(pool: LevelPool) -> jax.Array:
        if sampler == "uniform":
            return jnp.ones(capacity) / capacity
        w = learnability(pool) ** (1.0 / temperature)
        return (1.0 - uniform_mix) * w / jnp.sum(w) + uniform_mix / capacity

    def init(key) -> LevelPool:
        # Filled in batches of `refresh` (one refresh's worth of candidates at a time): the check's grids of
        # thousands of levels at once would not fit a GPU's memory.
        batches = -(-capacity // refresh)
        levels, ok, route, share = jax.lax.map(lambda k: candidates(k, refresh), jax.random.split(key, batches))
        first = lambda x: x.reshape((-1,) + x.shape[2:])[:capacity]  # noqa: E731
        levels, ok, route, share = jax.tree.map(first, levels), first(ok), first(route), jnp.mean(share)
        # Almost never needed: a slot whose candidate was not flyable takes a flyable one of the batch.
        first_ok = jnp.where(ok, jnp.arange(capacity), jnp.argmax(ok))
        (levels, fields) = jax.tree.map(lambda x: x[first_ok], levels)
        zeros = jnp.zeros(capacity)
        pool = LevelPool(levels=levels, route=route[first_ok], episodes=zeros, successes=zeros, cdf=zeros,
                         flyable=share, fields=fields)
        return pool.replace(cdf=jnp.cumsum(weights(pool)))

    def refresh_pool(pool: LevelPool, key):
        k_new, k_out = jax.random.split(key)
        if sampler == "uniform":
            out = jax.random.permutation(k_out, capacity)[:refresh]
        else:  # the least learnable; random among equals
            noise = 1e-6 * jax.random.uniform(k_out, (capacity,))
            out = jnp.argsort(learnability(pool) + noise)[:refresh]
        levels, ok, route, share = candidates(k_new, refresh)
        put = lambda old, new: old.at[out].set(jnp.where(_expand(ok, new), new, old[out]))  # noqa: E731
        levels, fields = levels
        fresh = pool.replace(levels=jax.tree.map(put, pool.levels, levels), route=put(pool.route, route),
                             fields=None if fields is None else put(pool.fields, fields),
                             episodes=put(pool.episodes, jnp.zeros(refresh)),
                             successes=put(pool.successes, jnp.zeros(refresh)), flyable=share)
        metrics = {"levels_learnability": jnp.mean(learnability(pool)),
                   "levels_success": jnp.sum(pool.successes) / jnp.maximum(jnp.sum(pool.episodes), 1.0),
                   "levels_route": jnp.mean(pool.route), "levels_flyable": share}
        return fresh.replace(cdf=jnp.cumsum(weights(fresh))), metrics

    def sample(pool: LevelPool, key, n: int):
        u = jax.random.uniform(key, (n,)) * pool.cdf[-1]
        return jnp.minimum(jnp.searchsorted(pool.cdf, u, side="right"), capacity - 1).astype(jnp.int32)

    def take(pool: LevelPool, indices):
        return jax.tree.map(lambda x: x[indices], pool.levels)

    def record(pool: LevelPool, indices, done, success):
        done = done.astype(jnp.float32)
        return pool.replace(episodes=pool.episodes.at[indices].add(done),
                            successes=pool.successes.at[indices].add(done * success.astype(jnp.float32)))

    def to_region(pool: LevelPool, indices, water, positions):
        """Route length (m) from each position to the goal's region (water or air) of its level: one value
        per env read from the kept fields (never a whole field gathered); inf off the route or the grid."""
        cell, inside = flyability.nearest_cell(positions)
        medium = jnp.where(water, 0, 1)   # fields[0]: to the water region (A-W), fields[1]: to the air region
        value = pool.fields[indices, medium, cell[:, 0], cell[:, 1], cell[:, 2]].astype(jnp.float32)
        return jnp.where(inside, value, jnp.inf)

    return Curriculum(init=init, refresh=refresh_pool, sample=sample, take=take, record=record,
                      to_region=to_region)


def _expand(flag, x):
    """flag (n,) broadcast against x (n, ...)."""
    return flag.reshape(flag.shape + (1,) * (x.ndim - 1))
