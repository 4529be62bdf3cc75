"""The level pool and curriculum (docrl_jax/envs/curriculum.py) as pure functions, on a generator
stand-in that walls off some of its layouts: what enters the pool is flyable, draws follow the weights,
outcomes are counted per level (repeated levels in one batch too), and a refresh replaces the least
learnable levels. The pool's check is a stand-in that knows the wall (the real check,
docrl_jax/envs/flyability.py, rejects such a wall in tests/envs/test_flyability.py and is what the
trainer's pool runs: tests/train/test_learning.py), so these tests compile in seconds."""

from __future__ import annotations

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.envs import curriculum, flyability, layouts
from docrl_jax.envs.params import make_params

P = make_params(0, layout_boxes=(0, 2), layout_capsules=(0, 1))


def _blocking_wall(layout):
    """The layout with a wall across the whole tank at x = 0, the air region west of it and the water
    region east: no route between them."""
    box = 1 + 12  # the first slot past the random obstacles'
    wall = layout.replace(pos=layout.pos.at[box].set(jnp.array([0.0, 0.0, 0.5])),
                          rot=layout.rot.at[box].set(jnp.eye(3)),
                          size=layout.size.at[box].set(jnp.array([0.2, 5.1, 5.0])))
    regions = wall.regions.at[0, 1, 0].set(-1.5).at[1, 0, 0].set(1.5)
    return wall.replace(regions=regions)


def _generator(blocked_share: float):
    """An env stand-in whose generator walls off a share of its layouts (never flyable)."""
    def draw_layout(key):
        layout = layouts.draw(key, P)
        blocked = jax.random.uniform(jax.random.fold_in(key, 7)) < blocked_share
        wall = _blocking_wall(layout)
        return jax.tree.map(lambda a, b: jnp.where(blocked, a, b), wall, layout)
    return types.SimpleNamespace(params=P, draw_layout=draw_layout)


def _knows_the_wall(layout, p):
    """A flyability check that knows the stand-in's wall; route length: the floor's depth, any number."""
    ok = ~(layout.size[13, 1] > 5.0)
    both = jnp.stack([ok, ok])
    length = jnp.full(2, -layouts.floor_top(layout))
    return flyability.Route(flyable=both, length=length, longest=length, straight=length,
                            start_cells=both.astype(jnp.int32))


@pytest.fixture(scope="module")
def pool_fns():
    out = {}
    for s in curriculum.SAMPLERS:   # compiled once each: eager vmaps of the generator cost far more
        c = curriculum.make_curriculum(_generator(0.3), s, capacity=8, refresh=3, check=_knows_the_wall)
        out[s] = c._replace(init=jax.jit(c.init), refresh=jax.jit(c.refresh),
                            sample=jax.jit(c.sample, static_argnums=2), record=jax.jit(c.record))
    return out


def _walled(levels) -> np.ndarray:
    """Which of the stacked levels carry the stand-in's wall (only walled levels have a box 5 m long)."""
    return np.asarray(levels.size[:, 13, 1]) > 5.0


def test_only_flyable_levels_enter_the_pool(pool_fns):
    c = pool_fns["learnability"]
    pool = c.init(jax.random.PRNGKey(0))
    assert not _walled(pool.levels).any()
    assert 0.3 < float(pool.flyable) < 1.0          # the stand-in walls off about 30 % of the candidates
    assert np.all(np.asarray(pool.route) > 0)
    for i in range(3):
        pool, m = c.refresh(pool, jax.random.PRNGKey(10 + i))
        assert not _walled(pool.levels).any()
        assert set(m) == {"levels_learnability", "levels_success", "levels_route", "levels_flyable"}


def test_outcomes_are_counted_per_level_with_repeats(pool_fns):
    c = pool_fns["uniform"]
    pool = c.init(jax.random.PRNGKey(1))
    idx = jnp.array([2, 2, 5, 5, 5, 0])
    done = jnp.array([True, True, True, False, True, False])
    success = jnp.array([True, False, True, True, False, True])
    pool = c.record(pool, idx, done, success)
    np.testing.assert_array_equal(pool.episodes, [0, 0, 2, 0, 0, 2, 0, 0])
    np.testing.assert_array_equal(pool.successes, [0, 0, 1, 0, 0, 1, 0, 0])


def _with_counts(pool, episodes, successes):
    pool = pool.replace(episodes=jnp.asarray(episodes, jnp.float32), successes=jnp.asarray(successes, jnp.float32))
    return pool


def test_learnability_prefers_levels_solved_sometimes(pool_fns):
    c = pool_fns["learnability"]
    pool = c.init(jax.random.PRNGKey(2))
    # Levels 0-2 mastered (20 of 20), 3-5 never solved (0 of 20), 6 half solved, 7 not flown yet.
    pool = _with_counts(pool, [20] * 6 + [20, 0], [20] * 3 + [0] * 3 + [10, 0])
    pool, _ = c.refresh(pool, jax.random.PRNGKey(3))
    # The refresh replaced the three least learnable (mastered or hopeless), never 6 or 7.
    assert float(pool.episodes[6]) == 20 and float(pool.episodes[7]) == 0
    assert int(np.sum(np.asarray(pool.episodes[:6]) == 0)) == 3
    draws = np.asarray(c.sample(pool, jax.random.PRNGKey(4), 20_000))
    share = np.bincount(draws, minlength=8) / draws.size
    kept = [i for i in range(6) if float(pool.episodes[i]) == 20]
    # Half-solved and fresh levels (learnability 0.25) are drawn far more than mastered ones (0.04).
    assert min(share[6], share[7]) > 3 * max(share[i] for i in kept), share
    assert min(share) > 0.3 / 8 * 0.8          # the uniform share keeps every level in play


def test_uniform_sampler_draws_every_level_alike(pool_fns):
    c = pool_fns["uniform"]
    pool = _with_counts(c.init(jax.random.PRNGKey(5)), [20] * 8, [20] * 4 + [0] * 4)
    pool, _ = c.refresh(pool, jax.random.PRNGKey(6))
    draws = np.asarray(c.sample(pool, jax.random.PRNGKey(7), 40_000))
    share = np.bincount(draws, minlength=8) / draws.size
    np.testing.assert_allclose(share, 1 / 8, atol=0.01)
    assert int(np.sum(np.asarray(pool.episodes) == 0)) == 3   # three slots refreshed


def test_bad_sampler_settings_are_refused_in_one_line():
    with pytest.raises(ValueError, match="valid samplers are uniform, learnability"):
        curriculum.make_curriculum(_generator(0.0), "plr", capacity=8, refresh=2)
    with pytest.raises(ValueError, match=r"refresh=9: must be in \[1, capacity=8\]"):
        curriculum.make_curriculum(_generator(0.0), "uniform", capacity=8, refresh=9)


def test_route_to_the_goal_region_is_read_per_env_from_the_kept_fields(pool_fns):
    c = pool_fns["uniform"]
    pool = c.init(jax.random.PRNGKey(8))
    shape = flyability.GRID_SHAPE
    # Field value = level * 100 + medium * 50 + the cell's x index (exact in float16): every read names its source.
    x_index = jnp.broadcast_to(jnp.arange(shape[0])[:, None, None], shape)
    fields = (jnp.arange(8)[:, None, None, None, None] * 100 + jnp.arange(2)[None, :, None, None, None] * 50
              + x_index[None, None]).astype(jnp.float16)
    pool = pool.replace(fields=fields)
    x0 = float(flyability.GRID_X[0])
    positions = jnp.array([[x0, 0.0, 1.0], [x0 + 0.26, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 40.0]])
    got = c.to_region(pool, jnp.array([3, 5, 7, 1]), jnp.array([True, False, True, True]), positions)
    mid = shape[0] // 2                        # x = 0 is the middle cell
    np.testing.assert_array_equal(got[:3], [300 + 0, 500 + 50 + 1, 700 + mid])
    assert np.isinf(got[3])                    # above the grid
